"""Error control: the closed-form optimum refined until its flight on Eqs. 1-2 meets the
problem's tolerance.

The closed form is approximate, and an optimum found on it alone misses once flown, by
far more where the optimiser stretched single arcs past their validity.  Each round
here:

1. **Judge.** Fly the schedule on Eqs. 1-2 (``verify``) and hold the flight to the
   tolerance (``verify.judge``).  Met: stop, verified.
2. **Local errors.** From every segment's own start node, fly the segment on Eqs. 1-2
   (CVODES in theta, no sensitivities: N short integrations) and on the closed form.
   Their difference is the segment's *defect*; its position part is the local error
   the solution reports per segment.
3. **Re-mesh where the closed form is strained.** If a segment breaks the cap on
   a~_c dtheta per sub-arc (:data:`STRAIN_CAP`), every segment gets enough
   sub-arcs to keep it; if the last round did not at least halve the flown miss, the
   sub-arcs double (the segment Function is mapped over all segments, so they share one
   count).  The cap is kept by adding sub-arcs, never by shortening segments: it bounds
   the closed form's error, not the trajectory.
4. **Defect correction.** Re-solve with every segment's end shifted by its defect, a
   constant of the NLP (``transcribe``'s parameter), warm from the last optimum.  At a
   fixed point the shifted closed-form chain lands exactly where Eqs. 1-2 do, so the
   flown miss falls towards the verifier's own error; the closed form still supplies the
   derivatives, so the optimum moves only by the difference of its gradients from the
   true ones.  A correction that ends with no point (a restoration failure) ends the
   rounds, and the last round that found one is the answer, judged as flown.  Rounds
   that all end short of the tolerance answer with the closest converged one.

Why this algorithm: a round of defect correction is a warm re-solve of the same NLP
and cuts the flown miss by orders of magnitude, where refining the mesh alone gains
only a factor (m'/m)^2 in m sub-arcs per round at the price of a cold solve of a larger
NLP.  Sub-arcs are still added where the closed form is strained, because a defect
correction built on an arc far outside its regime has wrong derivatives and converges
slowly or not at all.
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

#: Largest a~_c dtheta of one closed-form sub-arc: an arc's error grows with a~_c dtheta
#: (as its square for first-order arcs, its cube for the NLP's second-order ones;
#: THEORY.md §3.8), and an optimiser left free stretches single arcs far past where the
#: closed form means anything (a 0.1 au spiral swung one arc out to 4 au).  It is kept
#: by adding sub-arcs -- to the seed before the first solve (:func:`sub_arcs_within_cap`),
#: and to any optimum that breaks it (step 3 above) -- never as a constraint of the NLP:
#: as one it made a 4-segment hop to 1.3 au infeasible, deciding the answer instead of
#: the accuracy.
STRAIN_CAP = 0.05


def strain(problem, r_starts, lengths, throttle=None):
    """a~_c dtheta of each segment's sub-arcs as a fraction of :data:`STRAIN_CAP`
    (a~_c = kappa ac r0 with r_E = 1 au; numpy arrays of the segments' start radii,
    angles and throttles)."""
    kappa = 1.0 if throttle is None else np.asarray(throttle, float)
    return (problem.sail.ac * kappa * np.asarray(r_starts, float) * np.asarray(lengths, float)
            / problem.segments.sub_arcs / STRAIN_CAP)


def sub_arcs_within_cap(problem, guess, most):
    """The problem with enough sub-arcs (at most ``most``) that ``guess`` keeps the cap
    on a~_c dtheta per sub-arc: the cap is kept by adding sub-arcs, not by shortening
    the segments the seed chose."""
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
    """The outcome of :func:`control_error`; the caller judges its final flight.

    Attributes
    ----------
    problem : Problem
        The problem as last solved (its ``segments.sub_arcs`` may have grown).
    result : NLPResult
        The last optimum: the last round's, unless that round's correction found no
        point after an earlier one had (then that earlier round's, and the rounds after
        it are in ``history`` only), or no round met the tolerance (then the converged
        round that flew closest).
    transcription : Transcription
    history : list of Round
        One per round, in order.
    local_error_km : numpy.ndarray
        Per segment, the closed form's position error against Eqs. 1-2 over that
        segment from its own start node, km (NaN where a segment could not be flown).
    check : Verification
        The last round's verification of ``result``.
    defects : numpy.ndarray or None
        The defects the final ``result`` was solved with (None: none).
    """

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
    takes ref's normal to y's, and its theta is on ref's branch.  A node's plane frame
    is free up to a turn about the normal (traded against theta); this picks the one
    next to ``ref``, so that ``node_near(y, ref) - ref`` is a small defect.  ``y`` and
    ``ref`` may also be [7 x N] and [9 x N], column by column (one call for a whole
    schedule: the verification converts every segment's end)."""
    y, ref = np.asarray(y, float), np.asarray(ref, float)
    if y.ndim == 1:
        return np.array(_node_near()(y, ref), float).ravel()
    return np.array(_node_near().map(y.shape[1])(y, ref), float)


def _exact_ends3d(problem, starts, ac, alpha, delta, lengths, model_ends, tol):
    """Every 3-D segment flown by CVODES from its start node, in the angle swept (``simulate.fly_segments3d``), as nodes next to the model's ends
    (:func:`node_near`)."""
    y0 = np.vstack([np.column_stack([node_cartesian(c) for c in starts.T]), starts[4]])
    ends = fly_segments3d(y0, ac, alpha, delta, lengths, "theta", problem.sail.coefficients,
                          tol)
    return node_near(ends[:, :starts.shape[1]], model_ends)


def segment_ends(problem, result, method=None, tol=VERIFY_TOLERANCE):
    """(exact, model) ends [5 x N] of every segment flown from its own start node: by
    CVODES on Eqs. 1-2 at ``tol``, and by the NLP's segment ``method`` (default
    ``segment_methods.ClosedForm``), whose lengths are angles or, for a method in
    time, durations.  Their difference is each segment's defect.

    Raises
    ------
    SimulationError
        If CVODES cannot fly a segment (an escaping arc).
    """
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
    """A ``Segments(per_revolution=K)`` optimum solved again from itself, each segment
    cut into as many as the turns it flies need: (NLPResult, Transcription).

    The count is set on the seed's angle, and an optimum may fly far more turns than
    its seed (an Earth-Laurel minimum time asked for 10 segments a turn flew 2.49 turns
    on 10, where its best turn count found no point).  The first optimum stands where
    the finer mesh finds none, or where it was not found itself."""
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
    """Correct and re-mesh a closed-form optimum until its flight meets
    ``problem.tolerance`` (the rounds of this module's docstring): an
    :class:`ErrorControl`.

    Parameters
    ----------
    problem : Problem
    result : NLPResult
        The closed-form optimum (``ipopt.solve_problem``); every round keeps its
        revolution class.
    tr : Transcription, optional
        Its NLP; without it a new one is built at ``result`` (and the first correction
        starts cold, since a new NLP scales its variables differently).
    progress : callable, optional
        ``progress(text)``: a line per round and Ipopt's iteration lines.
    max_rounds : int
        Rounds of correction at most.
    solver : tuple, optional
        ``ipopt.build_solver(tr, warm=True)``'s pair, already built for ``tr``: a scan
        error-controls many cells on one NLP and builds its solver once.
    defects : numpy.ndarray, optional
        The 5 x N defects ``result`` was solved with (a scan carries a neighbour's), so
        that :attr:`ErrorControl.defects` says what the final result was solved with.
    """
    say, fresh = progress or (lambda text: None), tr is None
    if fresh:  # a new NLP scales its variables anew: the first correction starts cold
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
    flew closer.  Why: a later round's correction can fly worse (Earth-Mars at a 1 m tolerance flew
    27.0 m at round 6 and 105.9 m at round 8, its last)."""
    if (final.check.judge(final.problem)[0] and final.result.converged) or not converged:
        return final
    miss, rnd, kept = min(converged, key=lambda c: c[0])
    if kept.result is final.result or not miss < _flown_miss(final.problem, final.check):
        return final
    say(f"error control: keeping round {rnd}'s flight, the closest (flown miss {miss:.4g} km)")
    return dataclasses.replace(kept, history=final.history)


def _kept(found, history, say):
    """``found``, the last round that found a point, with the whole ``history``: a
    correction after it that lost the point (a restoration failure near a degenerate
    optimum, say) makes no answer of the rounds before it."""
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
    """One round's flights of ``result``: its verification (``verify``) and every
    segment flown from its own start node.  Returns
    (check, exact ends, model ends, local errors in km); the ends are None, and the
    local errors those of the last round, when a segment cannot be flown on Eqs. 1-2."""
    check = verify(problem, result)
    try:
        exact, plain = segment_ends(problem, result)
    except SimulationError as err:
        say(f"error control: a segment cannot be flown on Eqs. 1-2 ({err}); stopping")
        return check, None, None, local_km
    local_km = np.array([_node_miss_km(a, b) for a, b in zip(exact.T, plain.T)])
    return check, exact, plain, local_km


def _grown(problem, result, miss, last_miss):
    """The sub-arcs the next round needs, or None to keep the mesh: more where a
    segment breaks the strain cap (enough to keep it), double where the last round did
    not cut the flown miss by :data:`STALL`, never past :data:`MAX_SUB_ARCS`.

    A fresh start (no NLP given) is no reason to keep a strained mesh either: a defect
    correction on arcs far past the cap moved the 2-3 revolution Earth-Mars optimum
    (one 3.2 rad segment from 0.58 au, 3.6e6 km local error) out to escape."""
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
