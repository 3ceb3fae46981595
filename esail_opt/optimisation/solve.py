"""The solve: Ipopt (MUMPS) on a :class:`~.transcription.Transcription`, status checked.

CasADi's ``success`` flag is also true for "Solved_To_Acceptable_Level", so the outcome is
read from ``stats()['return_status']`` instead: only "Solve_Succeeded" counts as converged.
"""

import dataclasses
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from esail_opt.optimisation.transcription import Guess, initial_guess, transcribe

CONVERGED = ("Solve_Succeeded",)
ACCEPTABLE = ("Solved_To_Acceptable_Level",)
INFEASIBLE = ("Infeasible_Problem_Detected", "Restoration_Failed",
              "Search_Direction_Becomes_Too_Small", "Not_Enough_Degrees_Of_Freedom")


def ipopt_options(max_iter=3000, hessian="exact", print_level=0):
    """Ipopt options: MUMPS, quiet, and no ``ipopt.opt`` read from the working directory.

    Ipopt reads ``option_file_name`` (default "ipopt.opt") from the current directory if
    it exists; an empty name makes it read nothing, so a stray file cannot change a run.
    """
    opts = {
        "ipopt.linear_solver": "mumps",
        "ipopt.option_file_name": "",
        "ipopt.print_level": print_level,
        "ipopt.sb": "yes",
        "ipopt.max_iter": max_iter,
        "ipopt.tol": 1e-9,
        "ipopt.constr_viol_tol": 1e-10,
        "print_time": False,
    }
    if hessian != "exact":
        opts["ipopt.hessian_approximation"] = "limited-memory"
    return opts


@dataclass
class NLPResult:
    """What Ipopt returned, in canonical units, plus its bookkeeping.

    ``outcome`` is one of "converged", "acceptable" (Solved_To_Acceptable_Level: not
    reported as converged), "infeasible" or "failed".
    """

    status: str
    outcome: str
    objective: float
    iterations: int
    solve_seconds: float
    alpha: np.ndarray
    lengths: np.ndarray
    nodes: np.ndarray
    durations: np.ndarray
    x_start: np.ndarray
    q3: np.ndarray
    constraint_violation: float
    nu0: float
    stages: list = None  # [(status, iterations)] of a staged solve, first stage first
    throttle: np.ndarray = None  # kappa per segment (all 1 without a throttle)

    @property
    def converged(self):
        return self.outcome == "converged"


def outcome_of(status):
    if status in CONVERGED:
        return "converged"
    if status in ACCEPTABLE:
        return "acceptable"
    if status in INFEASIBLE:
        return "infeasible"
    return "failed"


def solve_transcription(tr, options=None):
    """Run Ipopt on a transcription from its initial guess and unpack the result."""
    opts = ipopt_options() if options is None else options
    solver = ca.nlpsol("esail", "ipopt", tr.nlp, opts)
    start = time.perf_counter()
    sol = solver(x0=tr.x0, lbx=tr.lbx, ubx=tr.ubx, lbg=tr.lbg, ubg=tr.ubg)
    seconds = time.perf_counter() - start
    stats = solver.stats()
    status = stats.get("return_status", "unknown")
    # Ipopt may leave a variable past its bound by its bound_relax_factor (1e-8): clip,
    # so that a pitch bound of 90 deg is never reported as 90.0000001.
    w = np.clip(np.array(sol["x"]).ravel(), tr.lbx, tr.ubx)
    g = np.array(tr.nlp_g(w)).ravel()
    violation = float(np.max(np.r_[0.0, tr.lbg - g, g - tr.ubg]))
    parts = [np.array(v) for v in tr.unpack(w)]
    return NLPResult(
        status=status, outcome=outcome_of(status), objective=float(sol["f"]),
        iterations=int(stats.get("iter_count", -1)), solve_seconds=seconds,
        alpha=parts[0].ravel(), lengths=parts[1].ravel(), nodes=parts[2],
        durations=parts[3].ravel(), x_start=parts[4].ravel(), q3=parts[5].ravel(),
        constraint_violation=violation, nu0=float(parts[6].ravel()[0]),
        stages=[(status, int(stats.get("iter_count", -1)))], throttle=parts[7].ravel(),
    )


def solve_problem(problem, segment=None, options=None, guess=None, theta_window=None):
    """Transcribe and solve ``problem``; returns (NLPResult, Transcription).

    ``guess`` replaces the constant-pitch seed of :func:`initial_guess`, and
    ``theta_window`` (rad) boxes the final polar angle (``transcribe``); the global
    search (``optimisation.multistart``) uses both.

    Free segment lengths are solved in two stages: first with equal lengths (a smaller,
    better-conditioned NLP that converges in tens of iterations), then with the lengths
    free, warm-started from it.  From the constant-pitch guess directly, the free NLP
    of Earth-Mars (60 segments) took 70 to 578 iterations and ended anywhere in
    578.03-578.34 d depending on the guess pitch; staged, it took 58-67 iterations and
    578.04 d from guesses of 25, 45 and 65 deg.  The result's iterations and seconds
    are the sums over both stages; ``stages`` lists each stage's status.
    """
    seg = problem.segments
    first = None
    # The seed fixes N (a per-revolution count is resolved by its propagation) and does
    # not depend on whether the lengths are free, so both stages share it.
    guess = initial_guess(problem) if guess is None else guess
    if not seg.equal and guess.alpha.size > 1:
        equal = dataclasses.replace(problem, segments=dataclasses.replace(seg, equal=True))
        tr1 = transcribe(equal, segment, guess, theta_window=theta_window)
        first = solve_transcription(tr1, options)
        if first.outcome in ("converged", "acceptable"):
            nodes = np.vstack([first.nodes, np.cumsum(first.durations)])
            guess = Guess(first.alpha, first.lengths, nodes, first.nu0,
                          tr1.guess.revolutions_k, first.throttle)
    tr = transcribe(problem, segment, guess, theta_window=theta_window)
    result = solve_transcription(tr, options)
    if first is not None:
        result.iterations += first.iterations
        result.solve_seconds += first.solve_seconds
        result.stages = first.stages + result.stages
    return result, tr
