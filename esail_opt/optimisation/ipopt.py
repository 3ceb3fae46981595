"""The solve: Ipopt (MUMPS) on a :class:`~.transcription.Transcription`, status checked.

Every result carries Ipopt's ``return_status`` and its :class:`~.outcome.Outcome`;
CasADi's ``success`` flag is never read (``optimisation.outcome`` says why).
"""

import contextvars
import dataclasses
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from esail_opt.runtime.signals import SignalsHeld
from esail_opt.optimisation.outcome import Outcome
from esail_opt.optimisation.problem import CLOCK_ROOM
from esail_opt.optimisation.seed import Guess, initial_guess
from esail_opt.optimisation.transcription import transcribe


def ipopt_options(max_iter=3000, hessian="exact", print_level=0):
    """Ipopt options: MUMPS, quiet, and an empty ``option_file_name`` so that a stray
    ``ipopt.opt`` in the working directory cannot change a run."""
    opts = {
        "ipopt.linear_solver": "mumps",
        "ipopt.option_file_name": "",
        "ipopt.print_level": print_level,
        "ipopt.sb": "yes",
        "ipopt.max_iter": max_iter,
        "ipopt.tol": 1e-9,
        "ipopt.constr_viol_tol": 1e-10,
        "print_time": False,
        # Trial steps into the closed form's invalid region give NaN, which Ipopt
        # rejects and backs off from; CasADi's warning for each is only noise.
        "show_eval_warnings": False,
    }
    # Exact by default: limited-memory did not converge on the closed-form NLPs.
    if hessian != "exact":
        opts["ipopt.hessian_approximation"] = "limited-memory"
    return opts


@dataclass
class NLPResult:
    """What Ipopt returned, in canonical units, plus its bookkeeping.

    ``nodes`` are the states at the segments' ends, 5 x N [r, theta, v_r, v_theta, t] (9 rows in
    three dimensions), as in a :class:`Guess`; the revolution class (``revolutions_k``,
    ``theta_window``) is the NLP's own, so that an NLP started here (:meth:`as_guess`) stays in it.
    """

    status: str
    outcome: Outcome
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
    # Ipopt's primal and dual point in the NLP's own layout, for a warm re-solve.
    w: np.ndarray = None
    lam_x: np.ndarray = None
    lam_g: np.ndarray = None
    revolutions_k: int = 0
    theta_window: tuple = None
    epoch: float = 0.0  # departure, TU since J2000 (dated problems)
    ac_scale: float = 1.0  # a_c over the sail's (MinAcceleration)
    vinf_angle: float = 0.0  # excess velocity's direction, rad
    delta: np.ndarray = None  # clock per segment, rad, in three dimensions (None: planar)

    @property
    def converged(self):
        return self.outcome.converged

    def after(self, *earlier, stages=True):
        """A new result that also covers the solves ``earlier``, run before it in that order: their
        iterations and seconds added, with ``stages`` their stages first; none of them changes."""
        more = {"stages": [s for r in (*earlier, self) for s in (r.stages or [])]} \
            if stages else {}
        return dataclasses.replace(
            self, iterations=self.iterations + sum(r.iterations for r in earlier),
            solve_seconds=self.solve_seconds + sum(r.solve_seconds for r in earlier),
            **more)

    def as_guess(self, durations=False):
        """A start for another NLP (any mesh or segment kind) at this optimum; with
        ``durations`` its lengths are the segment durations (an NLP in time)."""
        lengths = self.durations if durations else self.lengths
        return Guess(self.alpha, lengths, self.nodes, self.nu0, self.revolutions_k,
                     self.throttle, self.theta_window, self.epoch, self.ac_scale,
                     self.vinf_angle, self.delta)

    def accelerations(self, problem):
        """Each segment's characteristic acceleration as flown, canonical: the sail's
        a_c times the result's a_c scale and throttle."""
        kappa = np.ones(self.alpha.size) if self.throttle is None else self.throttle
        return problem.sail.ac * self.ac_scale * np.asarray(kappa, float)


def wrap_pitch(alpha):
    """Pitch (rad) in [-pi/2, pi/2): the thrust depends on 2 alpha only, so this is the
    same attitude as an unwrapped NLP variable."""
    return (np.asarray(alpha, float) + np.pi / 2) % np.pi - np.pi / 2


def wrap_clock(delta):
    """Clock angles (rad) in [-pi, pi]: one outside is wrapped into [-pi, pi), the same
    attitude; one inside is kept, so that a bound the sail sets at 180 deg stays met."""
    d = np.asarray(delta, float)
    return np.where(np.abs(d) > np.pi, (d + np.pi) % (2 * np.pi) - np.pi, d)


def _clock_slice(tr):
    """Where the clocks sit in ``tr``'s variables (the last N), or None when they are
    not free over the full circle (planar, or bounded by the sail)."""
    n = tr.segments
    if tr.rows != 9 or tr.ubx[-n] != CLOCK_ROOM:
        return None
    return slice(tr.ubx.size - n, tr.ubx.size)


def _off_the_box(tr, result):
    """``result``'s point with its clocks wrapped (:func:`wrap_clock`): the same optimum,
    everything being periodic in them, less the box's pull; None if it is no optimum or
    no clock has reached its box (``problem.CLOCK_ROOM``)."""
    at = _clock_slice(tr)
    if not result.outcome.found:
        return None
    # Ipopt's barrier holds a clock pressed on the box some 1e-6 rad inside it.
    if at is None or np.all(np.abs(result.w[at]) < CLOCK_ROOM - 1e-3):
        return None
    w = result.w.copy()
    w[at] = wrap_clock(w[at])
    return w


#: Ipopt's status when a checkpoint (:func:`build_solver`) stopped it.
STOPPED = "User_Requested_Stop"
#: Ipopt's status at its iteration cap (``max_iter``): a probe ending so has not decided its class.
AT_CAP = "Maximum_Iterations_Exceeded"

#: A ``threading.Event`` that stops the Ipopt runs of this context (a thread's own) at
#: their next iteration, as ``classes.ClassSearch`` calls off a probe; None: only a signal.
STOP = contextvars.ContextVar("esail_opt_ipopt_stop", default=None)

#: Times a solve whose clocks reached their box is taken on from them wrapped
#: (:func:`solve_transcription`).
CLOCK_RESTARTS = 3
#: Seconds between two progress lines of one Ipopt solve.
PROGRESS_SECONDS = 2.0


class _Monitor(ca.Callback):
    """Ipopt's iteration callback: a progress line every few seconds, and a clean stop.

    KeyboardInterrupt cannot reach Ipopt's C++, so the signal is held (``SignalsHeld``), the
    callback stops Ipopt, and leaving ``with monitor`` raises KeyboardInterrupt (or Terminated).
    """

    def __init__(self, tr, progress, checkpoint=None):
        ca.Callback.__init__(self)
        self.ng = tr.lbg.size
        self.lbg, self.ubg = tr.lbg, tr.ubg
        self.scale, self.unit = tr.objective_unit
        self.progress = progress
        self.checkpoint = checkpoint
        self.iteration = 0
        self.last = time.monotonic()
        self.held = SignalsHeld()
        self.stop = STOP.get()
        self.construct("monitor", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "stop"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.dense(1)
        if name == "g":
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def _violation(self, args):
        g = np.array(args[2]).ravel()
        return float(np.max(np.r_[0.0, self.lbg - g, g - self.ubg]))

    def eval(self, args):
        self.iteration += 1
        now = time.monotonic()
        if self.progress is not None and now - self.last >= PROGRESS_SECONDS:
            self.last = now
            self.progress(f"Ipopt iteration {self.iteration}: objective "
                          f"{float(args[1]) * self.scale:.6g}{self.unit}, "
                          f"constraint violation {self._violation(args):.2g}")
        give_up = False
        if self.checkpoint is not None and self.iteration == self.checkpoint[0]:
            give_up = bool(self.checkpoint[1](float(args[1]), self._violation(args)))
        called_off = self.stop is not None and self.stop.is_set()
        return [1 if self.held.interrupted or give_up or called_off else 0]

    def __enter__(self):
        self.held.__enter__()
        return self

    def __exit__(self, *exc):
        return self.held.__exit__(*exc)


def warm_options(options):
    """Ipopt options for a re-solve from a nearby optimum's primal and dual point, with a
    small barrier parameter so that Ipopt does not first walk back into the interior."""
    opts = dict(options)
    opts.update({"ipopt.warm_start_init_point": "yes", "ipopt.mu_init": 1e-7,
                 "ipopt.warm_start_bound_push": 1e-9, "ipopt.warm_start_mult_bound_push": 1e-9,
                 "ipopt.warm_start_slack_bound_push": 1e-9})
    return opts


def primal_warm_options(options):
    """Ipopt options for a start at a nearby problem's optimum whose multipliers do not
    fit (a free date from its best fixed date): a small barrier, the start barely pushed
    off its bounds so that Ipopt descends from it, and bound multipliers at mu / slack, not
    1, so that a far bound (the clocks' box, ``problem.CLOCK_ROOM``) pulls at nothing."""
    opts = dict(options)
    opts.update({"ipopt.mu_init": 1e-6, "ipopt.bound_push": 1e-8, "ipopt.bound_frac": 1e-8,
                 "ipopt.bound_mult_init_method": "mu-based"})
    return opts


def build_solver(tr, options=None, warm=False, progress=None, checkpoint=None):
    """(solver, :class:`_Monitor`) for ``tr``, built once to be re-solved (building is the costly
    part of a warm re-solve).  ``warm`` chooses :func:`warm_options`; ``progress(text)`` gets the
    iteration lines; ``checkpoint``, a pair (iteration, test), stops Ipopt (:data:`STOPPED`) at that
    iteration if ``test(objective, largest constraint violation)`` is true."""
    opts = dict(ipopt_options() if options is None else options)
    if warm:
        opts = warm_options(opts)
    monitor = _Monitor(tr, progress, checkpoint)
    opts["iteration_callback"] = monitor
    solver = ca.nlpsol("esail", "ipopt", tr.nlp, opts)
    return solver, monitor


def solve_transcription(tr, options=None, defects=None, warm=None, solver=None,
                        progress=None, checkpoint=None):
    """Run Ipopt on ``tr``; the :class:`NLPResult`.  ``defects``: the rows x N defects of the defect
    correction; ``warm``, an NLPResult of the same layout, the start (:func:`warm_options`) instead
    of ``tr.x0``; ``options``, ``progress`` and ``checkpoint`` as for :func:`build_solver`, whose
    pair ``solver``, if given, is built for ``tr`` (with its own ``checkpoint``).  Raises
    KeyboardInterrupt (or :class:`~esail_opt.errors.Terminated`) on a signal."""
    if solver is None:
        solver = build_solver(tr, options, warm is not None, progress, checkpoint)
    solver, monitor = solver
    monitor.progress = progress
    p = tr.parameters(defects)
    start = time.perf_counter()
    bounds = {"p": p, "lbx": tr.lbx, "ubx": tr.ubx, "lbg": tr.lbg, "ubg": tr.ubg}
    with monitor:
        if warm is None:
            sol = solver(x0=tr.x0, **bounds)
        else:
            sol = solver(x0=warm.w, lam_x0=warm.lam_x, lam_g0=warm.lam_g, **bounds)
    result = _result(tr, sol, solver.stats(), p, time.perf_counter() - start)
    for _ in range(CLOCK_RESTARTS):
        w = _off_the_box(tr, result)
        if w is None:
            break
        lam_x = result.lam_x.copy()
        lam_x[_clock_slice(tr)] = 0.0
        with monitor:
            sol = solver(x0=w, lam_x0=lam_x, lam_g0=result.lam_g, **bounds)
        again = _result(tr, sol, solver.stats(), p, time.perf_counter() - start)
        result = dataclasses.replace(again, iterations=result.iterations + again.iterations,
                                     stages=result.stages + again.stages)
    return result


def _result(tr, sol, stats, p, seconds):
    """The :class:`NLPResult` of Ipopt's ``sol`` on ``tr`` with parameters ``p``."""
    status = stats.get("return_status", "unknown")
    # Ipopt may leave a variable past its bound by its bound_relax_factor (1e-8): clip,
    # so that a pitch bound of 90 deg is never reported as 90.0000001.
    w = np.clip(np.array(sol["x"]).ravel(), tr.lbx, tr.ubx)
    g = np.array(tr.nlp_g(w, p)).ravel()
    violation = float(np.max(np.r_[0.0, tr.lbg - g, g - tr.ubg]))
    parts = [np.array(v) for v in tr.unpack(w, p)]
    return NLPResult(
        status=status, outcome=Outcome.of(status), objective=float(sol["f"]),
        iterations=int(stats.get("iter_count", -1)), solve_seconds=seconds,
        alpha=wrap_pitch(parts[0].ravel()), lengths=parts[1].ravel(), nodes=parts[2],
        durations=parts[3].ravel(), x_start=parts[4].ravel(), q3=parts[5].ravel(),
        constraint_violation=violation, nu0=float(parts[6].ravel()[0]),
        stages=[(status, int(stats.get("iter_count", -1)))], throttle=parts[7].ravel(),
        w=w, lam_x=np.array(sol["lam_x"]).ravel(), lam_g=np.array(sol["lam_g"]).ravel(),
        revolutions_k=tr.guess.revolutions_k, theta_window=tr.guess.theta_window,
        epoch=parts[8].item(), ac_scale=parts[9].item(), vinf_angle=parts[10].item(),
        delta=wrap_clock(parts[11].ravel()) if parts[11].size else None,
    )


def solve_problem(problem, method=None, options=None, guess=None, progress=None,
                  staged=True, checkpoint=None):
    """Transcribe and solve ``problem`` with the segment ``method`` (default: the closed form);
    returns (NLPResult, Transcription).  ``guess`` replaces :func:`initial_guess`'s seed, with its
    revolution class.  Free lengths are solved equal first (smaller, better conditioned), then free
    from there: from the seed, the free NLP took many more iterations and its optimum depended on
    the seed's pitch (``staged=False`` skips the first stage).  Iterations, seconds and ``stages``
    cover both; a stage ``checkpoint`` stopped ends the solve with its result."""
    seg = problem.segments
    first = None
    # The seed (which fixes N) does not depend on free lengths: both stages share it.
    guess = initial_guess(problem) if guess is None else guess
    if staged and not seg.equal and guess.alpha.size > 1:
        equal = dataclasses.replace(problem, segments=dataclasses.replace(seg, equal=True))
        equal_tr = transcribe(equal, method, guess, threads=1)
        first = solve_transcription(equal_tr, options, progress=progress,
                                    checkpoint=checkpoint)
        if first.status == STOPPED:
            return first, equal_tr
        if first.outcome.found:
            guess = first.as_guess()
    tr = transcribe(problem, method, guess)
    result = solve_transcription(tr, options, progress=progress, checkpoint=checkpoint)
    return (result if first is None else result.after(first)), tr
