"""Error control: the closed-form optimum refined until its flight on Eqs. 1-2 meets the
problem's tolerance.

Each round: (1) fly the schedule on Eqs. 1-2 and judge it (``verify``); met, stop.  (2) Fly
every segment from its own start node on Eqs. 1-2 and on the closed form: the difference is
its *defect*, whose position part is the reported local error.  (3) Where a segment breaks
:data:`STRAIN_CAP` (a correction there has wrong derivatives), or the miss stalls, add
sub-arcs.  (4) Re-solve warm with every segment's end shifted by its defect, so that at a
fixed point the closed-form chain lands where Eqs. 1-2 do.  A correction that finds no point
ends the rounds with the last that found one; rounds all short of the tolerance answer with
the closest one.  Why: a warm defect correction cuts the miss by orders of magnitude, where
refining the mesh alone gains (m'/m)^2 for a cold solve of a larger NLP.
"""

import dataclasses
import functools
import math
import time
from dataclasses import dataclass
from typing import Optional

import casadi as ca
import numpy as np

from esail_opt.optimisation.ipopt import (build_solver, ipopt_options, primal_warm_options,
                                          solve_problem, solve_transcription)
from esail_opt.optimisation.goals import cartesian_miss, state_miss
from esail_opt.optimisation.segment_methods import ClosedForm
from esail_opt.optimisation.nodes import node_cartesian, start_node
from esail_opt.optimisation.seed import split_guess
from esail_opt.optimisation.transcription import transcribe
from esail_opt.optimisation.verify import verify
from esail_opt.physics import constants as units
from esail_opt.physics import rotation
from esail_opt.physics.elements import polar3d_from_cartesian
from esail_opt.propagation.simulate import (VERIFY_TOLERANCE, SimulationError, fly_segments,
                                            fly_segments3d)

#: Largest a~_c dtheta of one closed-form sub-arc (an arc's error grows as its square or,
#: second order, its cube; THEORY.md §3.8).  Kept by adding sub-arcs, never as an NLP
#: constraint, which made feasible problems infeasible: it bounds accuracy, not the answer.
STRAIN_CAP = 0.05


def strain(problem, r_starts, lengths, throttle=None):
    """a~_c dtheta of each segment's sub-arcs as a fraction of :data:`STRAIN_CAP`
    (a~_c = kappa ac r0 with r_E = 1 au; numpy arrays of the segments' start radii,
    angles and throttles)."""
    kappa = 1.0 if throttle is None else np.asarray(throttle, float)
    return (problem.sail.ac * kappa * np.asarray(r_starts, float) * np.asarray(lengths, float)
            / problem.segments.sub_arcs / STRAIN_CAP)


def sub_arcs_within_cap(problem, guess, most):
    """The problem with enough sub-arcs (at most ``most``) that ``guess`` keeps
    :data:`STRAIN_CAP`."""
    r_starts = np.r_[problem.x0()[0], guess.nodes[0, :-1]]
    worst = float(np.max(strain(problem, r_starts, guess.lengths, guess.throttle)))
    if worst <= 1:
        return problem
    sub = min(most, math.ceil(problem.segments.sub_arcs * worst))
    return dataclasses.replace(problem, segments=dataclasses.replace(problem.segments,
                                                                     sub_arcs=sub))


#: Rounds of defect correction after the first solve.
MAX_ROUNDS = 8
#: The sub-arcs never grow past this (the NLP's cost grows with them).
MAX_SUB_ARCS = 24
#: A round that does not bring the flown miss below this fraction of the last one
#: doubles the sub-arcs: the correction is converging too slowly on this mesh.
STALL = 0.5


@dataclass(frozen=True)
class Round:
    """One round of the error control, in boundary units (solution.json's
    ``refinement.rounds`` rows): the mesh, Ipopt's record and the flight's misses of the
    round's result (None where the flight failed or there is no target), and the seconds
    since the error control started."""

    round: int
    segments: int
    sub_arcs: int
    status: str
    iterations: int
    objective: float
    tof_days: float
    target_miss_r_km: Optional[float]
    target_miss_v_m_s: Optional[float]
    miss_r_km: Optional[float]
    miss_v_m_s: Optional[float]
    max_local_error_km: Optional[float]
    seconds: float


@dataclass
class ErrorControl:
    """The outcome of :func:`control_error`, whose final flight the caller judges: ``problem``
    as last solved (``segments.sub_arcs`` may have grown); ``result`` the kept optimum (see
    the module docstring), with its ``transcription``, ``check`` (its Verification) and
    ``defects`` (5 x N, or None); ``history`` one :class:`Round` per round; ``local_error_km``
    per segment, the closed form's position error against Eqs. 1-2 from its own start node
    (NaN where it could not be flown)."""

    problem: object
    result: object
    transcription: object
    history: list
    local_error_km: np.ndarray
    check: object = None
    defects: np.ndarray = None


def start_nodes(result):
    """Each segment's start state [5 x N] with time (9 rows in three dimensions): the
    departure, then the nodes."""
    return np.column_stack([start_node(result.x_start), result.nodes[:, :-1]])


@functools.lru_cache(maxsize=None)
def _node_near():
    """``(y[7], ref[9]) -> node[9]``, :func:`node_near`'s map, as one SX function."""
    y, ref = ca.SX.sym("y", 7), ca.SX.sym("ref", 9)
    quat_ref = ref[5:9] / ca.norm_2(ref[5:9])
    turn = rotation.matrix(quat_ref)
    x, quat = polar3d_from_cartesian(ca.vertcat(ca.mtimes(turn.T, y[:3]),
                                                ca.mtimes(turn.T, y[3:6])))
    # The turn of theta nearest ref's: x - ref wrapped into [-pi, pi).
    off = x[1] - ref[1] + ca.pi
    theta = ref[1] + off - 2 * ca.pi * ca.floor(off / (2 * ca.pi)) - ca.pi
    return ca.Function("node_near", [y, ref], [ca.vertcat(
        x[0], theta, x[2], x[3], y[6], rotation.multiply(quat_ref, quat))])


def node_near(y, ref):
    """The Cartesian state ``y`` (7 rows, with t) as a 3-D node (9 rows) in the gauge of
    the node ``ref``: its plane's frame is ref's turned by the smallest rotation that
    takes ref's normal to y's, and its theta is on ref's branch, so that
    ``node_near(y, ref) - ref`` is a small defect (a node's frame is free up to a turn
    about the normal).  ``y`` and ``ref`` may also be [7 x N] and [9 x N]."""
    y, ref = np.asarray(y, float), np.asarray(ref, float)
    if y.ndim == 1:
        return np.array(_node_near()(y, ref), float).ravel()
    return np.array(_node_near().map(y.shape[1])(y, ref), float)


def _exact_ends3d(problem, starts, ac, alpha, delta, lengths, model_ends, tol):
    """Every 3-D segment flown by CVODES from its start node (``simulate.fly_segments3d``),
    as nodes next to the model's ends (:func:`node_near`)."""
    y0 = np.vstack([np.column_stack([node_cartesian(c) for c in starts.T]), starts[4]])
    ends = fly_segments3d(y0, ac, alpha, delta, lengths, "theta", problem.sail.coefficients,
                          tol)
    return node_near(ends[:, :starts.shape[1]], model_ends)


def segment_ends(problem, result, method=None, tol=VERIFY_TOLERANCE):
    """(exact, model) ends [5 x N] of every segment flown from its own start node: by CVODES
    on Eqs. 1-2 at ``tol``, and by the NLP's segment ``method`` (default
    ``segment_methods.ClosedForm``), whose lengths are angles or, for a method in time,
    durations.  Raises SimulationError if CVODES cannot fly a segment (an escaping arc)."""
    method = ClosedForm() if method is None else method
    segment, length_in = method.function(problem), method.length_in
    lengths = result.lengths if length_in == "theta" else result.durations
    args = (start_nodes(result), problem.sail.ac * result.ac_scale * result.throttle[None, :],
            result.alpha[None, :], lengths[None, :])
    if getattr(result, "delta", None) is not None:
        args = args[:3] + (result.delta[None, :], args[3])
        model = np.array(segment.map(result.alpha.size)(*args)[0])
        return _exact_ends3d(problem, *args, model, tol), model
    model = np.array(segment.map(result.alpha.size)(*args)[0])
    exact = fly_segments(*args, length_in, problem.sail.coefficients, tol)
    return exact, model


def _node_miss_km(a, b):
    """Position difference of two nodes, km (in three dimensions, in space)."""
    if a.size > 5:
        return cartesian_miss(node_cartesian(a), node_cartesian(b))[0]
    return state_miss(a, b)[0]


def _row(rnd, problem, result, check, local_km, seconds):
    m = check.misses
    return Round(round=rnd, segments=int(result.alpha.size),
                 sub_arcs=problem.segments.sub_arcs, status=result.status,
                 iterations=result.iterations, objective=result.objective,
                 tof_days=units.time_to_days(float(np.sum(result.durations))),
                 target_miss_r_km=m.get("target_miss_r_km"),
                 target_miss_v_m_s=m.get("target_miss_v_m_s"),
                 miss_r_km=m.get("miss_r_km"), miss_v_m_s=m.get("miss_v_m_s"),
                 max_local_error_km=None if local_km is None else float(np.max(local_km)),
                 seconds=seconds)


def _flown_miss(problem, check):
    """The miss the tolerance is judged on, km (target, or NLP's end without one)."""
    m = check.misses
    value = m.get("target_miss_r_km") if problem.target is not None else m.get("miss_r_km")
    return np.inf if value is None else value


#: How far below its asked density a ``Segments(per_revolution=K)`` mesh may fall on
#: the turns its optimum flies before that optimum is solved again on a finer mesh.
DENSITY_SLACK = 1.25


def per_revolution_mesh(problem, result, tr, say):
    """A ``Segments(per_revolution=K)`` optimum solved again from itself, each segment cut
    into as many as the turns it flies need (the count is set on the seed's angle, and an
    optimum may fly far more turns): (NLPResult, Transcription).  The first optimum stands
    where the finer mesh finds no point, or where it was not found itself."""
    seg, n = problem.segments, result.alpha.size
    wanted = seg.count_for(float(np.sum(result.lengths))) if result.outcome.found else n
    if seg.per_revolution is None or wanted <= DENSITY_SLACK * n:
        return result, tr
    parts = math.ceil(wanted / n)
    say(f"{problem.name}: the optimum flies {np.sum(result.lengths) / (2 * math.pi):.3g} "
        f"turns on {n} segments; solving it again on {n * parts} "
        f"({seg.per_revolution} a turn asked)")
    guess = split_guess(problem, result.as_guess(), result.x_start, parts)
    finer, finer_tr = solve_problem(problem, guess=guess, progress=say, staged=False,
                                    options=primal_warm_options(ipopt_options()))
    finer.iterations += result.iterations
    finer.solve_seconds += result.solve_seconds
    if not finer.outcome.found:
        say(f"{problem.name}: the finer mesh found no point; keeping {n} segments")
        result.iterations, result.solve_seconds = finer.iterations, finer.solve_seconds
        return result, tr
    return finer, finer_tr


def control_error(problem, result, tr=None, progress=None, max_rounds=MAX_ROUNDS, solver=None,
                  defects=None):
    """Correct and re-mesh the closed-form optimum ``result``, keeping its revolution class,
    until its flight meets ``problem.tolerance`` or ``max_rounds`` rounds have run: an
    :class:`ErrorControl`.  ``tr``: its NLP (without it one is built and the first correction
    starts cold); ``solver``: ``ipopt.build_solver(tr, warm=True)``'s pair if already built (a
    scan reuses one); ``defects``: the 5 x N defects ``result`` was solved with, if any;
    ``progress(text)`` gets a line per round and Ipopt's iteration lines."""
    say, fresh = progress or (lambda text: None), tr is None
    if fresh:  # a new NLP scales its variables anew
        tr, solver = transcribe(problem, guess=result.as_guess()), None
    history, last_miss, applied, found, converged = [], None, defects, None, []
    local_km = np.full(result.alpha.size, np.nan)  # until a round flies every segment
    started = time.perf_counter()
    for rnd in range(max_rounds + 1):
        check, exact, plain, local_km = _judge(problem, result, local_km, say)
        history.append(_row(rnd, problem, result, check, local_km, time.perf_counter() - started))
        miss = _said_miss(rnd, problem, check, say)
        if not result.outcome.found and found is not None:
            return _kept(found, history, say)
        if result.outcome.found:
            found = ErrorControl(problem, result, tr, None, local_km, check, applied)
            converged += [(miss, rnd, found)] if result.converged else []
        if (rnd == max_rounds or exact is None or not result.outcome.found
                or (check.judge(problem)[0] and result.converged)):
            break
        grown = _grown(problem, result, miss, last_miss)
        last_miss = miss
        if grown is not None:
            problem, tr, plain = _remeshed(problem, result, grown, say)
        applied = exact - plain
        cold = fresh or grown is not None
        result, solver = _correct(tr, applied, result, None if cold else solver, cold, progress)
        if cold:
            last_miss, fresh = None, False
    # Every way out of the loop is a break after flying the final result.
    return _closest(ErrorControl(problem, result, tr, history, local_km, check, applied),
                    converged, say)


def _closest(final, converged, say):
    """``final``, unless it is short of its tolerance: then the closest of the
    ``converged`` rounds (each its miss, its number and its ErrorControl), when that
    flew closer: a later round's correction can fly worse."""
    if (final.check.judge(final.problem)[0] and final.result.converged) or not converged:
        return final
    miss, rnd, kept = min(converged, key=lambda c: c[0])
    if kept.result is final.result or not miss < _flown_miss(final.problem, final.check):
        return final
    say(f"error control: keeping round {rnd}'s flight, the closest (flown miss {miss:.4g} km)")
    return dataclasses.replace(kept, history=final.history)


def _kept(found, history, say):
    """``found``, the last round that found a point, with the whole ``history``."""
    say(f"error control: round {len(history) - 1} found no point "
        f"({history[-1].status}); keeping round {len(history) - 2}'s")
    return dataclasses.replace(found, history=history)


def _said_miss(rnd, problem, check, say):
    """The flown miss of round ``rnd`` (:func:`_flown_miss`), said in its line."""
    miss = _flown_miss(problem, check)
    say(f"error-control round {rnd}: {problem.segments.sub_arcs} sub-arcs, flown miss "
        f"{miss:.4g} km (tolerance {problem.tolerance.position_km:g} km)")
    return miss


def _judge(problem, result, local_km, say):
    """One round's flights of ``result``: (check, exact ends, model ends, local errors
    in km); the ends are None, and the local errors the last round's, when a segment
    cannot be flown on Eqs. 1-2."""
    check = verify(problem, result)
    try:
        exact, plain = segment_ends(problem, result)
    except SimulationError as err:
        say(f"error control: a segment cannot be flown on Eqs. 1-2 ({err}); stopping")
        return check, None, None, local_km
    local_km = np.array([_node_miss_km(a, b) for a, b in zip(exact.T, plain.T)])
    return check, exact, plain, local_km


def _grown(problem, result, miss, last_miss):
    """``(sub_arcs, strained)`` for the next round, or None to keep the mesh: enough to
    keep the strain cap, else double where the last round did not cut the flown miss by
    :data:`STALL`, never past :data:`MAX_SUB_ARCS`."""
    sub = problem.segments.sub_arcs
    worst = float(np.max(strain(problem, start_nodes(result)[0], result.lengths,
                                result.accelerations(problem) / problem.sail.ac)))
    strained = worst > 1
    stalled = last_miss is not None and miss > STALL * last_miss
    if not (strained or stalled) or sub >= MAX_SUB_ARCS:
        return None
    return min(math.ceil(sub * worst) if strained else 2 * sub, MAX_SUB_ARCS), strained


def _correct(tr, defects, result, solver, cold, progress):
    """The optimum of ``tr`` with ``defects``: cold (a new NLP, or a new mesh, scales
    its variables anew), or warm from ``result`` on ``solver`` (built here if None).
    Returns it and the solver to warm the next round on (None after a cold solve)."""
    if cold:
        return solve_transcription(tr, defects=defects, progress=progress), None
    if solver is None:
        solver = build_solver(tr, warm=True, progress=progress)
    return solve_transcription(tr, defects=defects, warm=result, solver=solver,
                               progress=progress), solver


def _remeshed(problem, result, grown, say):
    """``problem`` on the grown mesh (``grown``: sub-arcs and whether the strain cap
    asked for them), its NLP at ``result``, and the model's segment ends on it."""
    sub_arcs, strained = grown
    problem = dataclasses.replace(problem, segments=dataclasses.replace(
        problem.segments, sub_arcs=sub_arcs))
    tr = transcribe(problem, guess=result.as_guess())
    plain = segment_ends(problem, result)[1]
    say(f"error control: {'strained' if strained else 'slow'} closed form; "
        f"{problem.segments.sub_arcs} sub-arcs per segment")
    return problem, tr, plain
