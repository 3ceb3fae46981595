"""The polish: the closed-form optimum re-solved on Eqs. 1-2.

The closed form's optimum misses by hundreds to thousands of km on the full dynamics
(THEORY.md §3.8, §5.2).  The polish keeps the problem and the NLP builder
(:func:`~.transcription.transcribe`) and swaps each closed-form arc for an RK4 arc in time
(the durations become the length variables) whose truncation error is removed by defect
correction against the verifier's CVODES flights (:func:`polish`): it lands where it is
judged, while Ipopt differentiates a small SX graph instead of CVODES's sensitivities, some
40 times cheaper an iteration.
"""

import dataclasses
import time

import numpy as np

from esail_opt.optimisation.goals import cartesian_miss, state_miss
from esail_opt.optimisation.ipopt import build_solver, ipopt_options, solve_transcription
from esail_opt.optimisation.problem import Tolerance
from esail_opt.optimisation.error_control import node_near, segment_ends, start_nodes
from esail_opt.optimisation.segment_methods import CVODES, RK4
from esail_opt.optimisation.nodes import node_cartesian, start_node
from esail_opt.optimisation.transcription import body_corrections, transcribe
from esail_opt.propagation.simulate import (VERIFY_TOLERANCE, SimulationError, fly_segments3d,
                                            simulate, simulate3d)

#: Ipopt's bound on the constraint violation (canonical): continuity defects add up along the
#: chain (at 1e-12 au a 30-segment flight ended 1.67 m from its final node, over the 1 m bound).
CONSTRAINT_TOLERANCE = 1e-13
#: What an exact schedule must meet: 1 m and 1 mm/s, against the target and against the
#: polished NLP's own final node.
TOLERANCE = Tolerance(position_km=1e-3, velocity_m_s=1e-3)
#: RK4 steps per segment of the polish's NLP: the fewest of these whose largest defect at
#: the warm start (exact arc less RK4 arc, from one node) is under STEP_DEFECT, since
#: the defect correction converges only while the RK4 arcs respond as the exact ones do.
RK4_STEPS = (4, 8, 16, 32)
#: 1e-6 au is about 150 km.
STEP_DEFECT = 1e-6
#: Defect corrections at most, and when to stop: the verifier's own flight of the schedule from
#: the departure (CVODES at ``VERIFY_TOLERANCE``) ends within LANDING_* of the NLP's final node, a
#: tenth of the polish's bound (settled defects alone can leave the flight metres off).
MAX_ROUNDS = 8
LANDING_KM, LANDING_M_S = 1e-4, 1e-4
#: Ipopt's first barrier parameter in the polish: its start is already near the exact optimum,
#: and the default (0.1) first pushes it back into the interior, at several times the iterations.
START_MU = 1e-6


def polish_options(max_iter=200):
    """Ipopt options of the polish: the solve's, with a tighter constraint tolerance and a
    small iteration budget (a polish that needs more has a problem to show, not wait for)."""
    opts = ipopt_options(max_iter=max_iter)
    opts["ipopt.constr_viol_tol"] = CONSTRAINT_TOLERANCE
    return opts


def _controls(guess):
    """The controls a segment takes after its a_c: pitch, and the clock in 3-D (rows of one)."""
    rows = [guess.alpha[None, :]]
    if getattr(guess, "delta", None) is not None:
        rows.append(np.asarray(guess.delta, float)[None, :])
    return rows


def _flown_nodes3d(problem, x_start, guess):
    """The schedule ``guess`` flown by CVODES from the 3-D start ``x_start``, as nodes
    next to ``guess``'s own (``error_control.node_near``)."""
    flown = simulate3d(node_cartesian(start_node(x_start)), guess.alpha, guess.delta,
                       guess.lengths, problem.sail.ac * guess.ac_scale,
                       throttles=guess.throttle, length_in="time",
                       coefficients=problem.sail.coefficients)
    n = guess.alpha.size
    return node_near(flown[:, 1:n + 1], guess.nodes[:, :n])


def exact_guess(problem, x_start, guess):
    """A start for the exact (in-time) NLP from the schedule ``guess`` (pitch, clock in 3-D,
    durations in TU, throttle, revolution class): its nodes become the schedule's CVODES flight from
    ``x_start``, so that every continuity constraint holds; ``guess`` if that flight fails."""
    try:
        if problem.three_d():
            return dataclasses.replace(guess, nodes=_flown_nodes3d(problem, x_start, guess))
        flown = simulate(x_start, guess.alpha, guess.lengths, problem.sail.ac * guess.ac_scale,
                         throttles=guess.throttle, samples=1, length_in="time",
                         coefficients=problem.sail.coefficients)
    except SimulationError:
        return guess
    return dataclasses.replace(guess, nodes=flown[:, 1:])


def _states(problem, nodes):
    """What a defect is measured on: the polar state [r, theta, v_r, v_theta], or the
    Cartesian state in three dimensions (a node's quaternion and theta trade a turn)."""
    if problem.three_d():
        return np.column_stack([node_cartesian(n) for n in np.asarray(nodes).T])
    return np.asarray(nodes)[:4]


def rk4_polish_method(problem, x_start, start, steps=RK4_STEPS):
    """``segment_methods.RK4`` in time at the first of ``steps`` whose largest defect at ``start``
    (:func:`exact_guess`'s flown start: a segment's next node less the RK4 arc from its node) is
    under :data:`STEP_DEFECT`, else the last.  The first NLP is solved without these defects: with
    them, a 0.1 mm/s^2 spiral ran out of iterations."""
    nodes_from = np.column_stack([start_node(x_start), start.nodes[:, :-1]])
    args = (nodes_from, problem.sail.ac * start.ac_scale * start.throttle[None, :],
            *_controls(start), start.lengths[None, :])
    for count in steps:
        # Only the count chosen is compiled, by the NLP that flies it.
        ends = np.array(RK4(count, in_time=True, native=False).function(problem)
                        .map(start.alpha.size)(*args)[0])
        if np.max(np.abs(_states(problem, start.nodes) - _states(problem, ends))) < STEP_DEFECT:
            break
    return RK4(count, in_time=True)


def _final_miss(problem, result):
    """(km, m/s) between the schedule flown by the verifier's CVODES from the departure
    and the NLP's final node (raises SimulationError if it cannot fly)."""
    ac, coefficients = problem.sail.ac * result.ac_scale, problem.sail.coefficients
    if problem.three_d():
        flown = simulate3d(problem.start_state(result), result.alpha, result.delta,
                           result.durations, ac, throttles=result.throttle,
                           coefficients=coefficients, tol=VERIFY_TOLERANCE)
        return cartesian_miss(flown[:6, -1], node_cartesian(result.nodes[:, -1]))
    flown = simulate(problem.start_state(result), result.alpha, result.durations, ac,
                     throttles=result.throttle, coefficients=coefficients,
                     tol=VERIFY_TOLERANCE)
    return state_miss(flown[:4, -1], result.nodes[:4, -1])[:2]


def _lands(problem, result):
    """Whether :func:`_final_miss` is within :data:`LANDING_KM` and :data:`LANDING_M_S`."""
    r_km, v_m_s = _final_miss(problem, result)
    return r_km <= LANDING_KM and v_m_s <= LANDING_M_S


def _on_bodies(problem, result):
    """Whether the NLP's departure and final states are within LANDING_* of the bodies'
    ephemeris (unprojected in 3-D) at its own dates, which a round's move of the dates can
    spoil (True off the calendar and for a target that is not a real body)."""
    if not problem.dated():
        return True
    tof = float(np.sum(result.durations))
    if problem.three_d():
        r_km, v_m_s = cartesian_miss(node_cartesian(start_node(result.x_start)),
                                     problem.start_state(result))
    else:
        r_km, v_m_s, _ = state_miss(result.x_start, problem.start_state(result))
    if r_km > LANDING_KM or v_m_s > LANDING_M_S:
        return False
    if getattr(problem.target, "body", None) is None:
        return True
    if problem.three_d():
        miss = problem.target.miss3d(node_cartesian(result.nodes[:, -1]), tof, result.epoch)
    else:
        miss = problem.target.miss(result.nodes[:4, -1], tof, result.epoch)
    v_m_s = miss["target_miss_v_m_s"]
    return miss["target_miss_r_km"] <= LANDING_KM and (v_m_s is None or v_m_s <= LANDING_M_S)


def _on_ephemeris(tr, problem, result):
    """``tr`` holding its bodies to their ephemeris (or elements) at ``result``'s dates rather than
    to their smooth tracks (``transcription.body_corrections``), whose tens of metres, grown along
    the flight, exceed the polish's 1 m.  Renewed every round, as the dates move."""
    return dataclasses.replace(tr, corrections=body_corrections(problem, result))


def _defects(problem, result, method):
    """Each segment's end flown by CVODES at the verifier's tolerance from its own start node, less
    the segment ``method``'s end from the same node (raises SimulationError)."""
    if not problem.three_d():
        flown, model = segment_ends(problem, result, method, VERIFY_TOLERANCE)
        return flown - model
    starts = start_nodes(result)
    ac = result.accelerations(problem)[None, :]
    args = (ac, *_controls(result), result.durations[None, :])
    model = np.array(method.function(problem).map(result.alpha.size)(starts, *args)[0])
    y0 = np.vstack([np.column_stack([node_cartesian(c) for c in starts.T]), starts[4]])
    ends = fly_segments3d(y0, *args, "time", problem.sail.coefficients, VERIFY_TOLERANCE)
    return node_near(ends, model) - model


def _corrected(problem, tr, method, exact, opts, max_rounds):
    """Rounds of defect correction from the first solve ``exact`` until the flight lands on the
    NLP's final node and the bodies (at most ``max_rounds``): (result, transcription, landed), the
    result's stages and iterations covering every round."""
    rounds, solver, landed = [], None, False
    for round_ in range(max_rounds + 1):
        if not exact.outcome.found:
            break
        try:
            landed = _lands(problem, exact) and _on_bodies(problem, exact)
            if landed or round_ == max_rounds:
                break
            defects = _defects(problem, exact, method)
        except SimulationError:
            break  # an arc CVODES cannot fly: the fallback tries other arcs
        tr = _on_ephemeris(tr, problem, exact)
        solver = solver or build_solver(tr, opts, warm=True)
        rounds.append(exact)
        exact = solve_transcription(tr, defects=defects, warm=exact, solver=solver)
    # The seconds summed here give way to the polish's own wall time (polish).
    return exact.after(*rounds), tr, landed


def _first_solve(problem, result, start, schedule, steps, opts):
    """The polish's first solve from ``start``, on RK4 arcs of the steps
    :func:`rk4_polish_method` picks (the fewest if CVODES could not fly the start):
    (result, transcription, segment method)."""
    if start is schedule:  # CVODES could not fly it: no defects to choose the steps by
        method = RK4(steps[0], in_time=True)
    else:
        method = rk4_polish_method(problem, result.x_start, start, steps)
    tr = _on_ephemeris(transcribe(problem, method, start), problem, result)
    return solve_transcription(tr, opts), tr, method


def _fallback(problem, result, start, opts, steps, max_rounds):
    """The polish again when the RK4 NLP did not land: on CVODES arcs in the plane
    (slower but steadier), on RK4 arcs of the most steps in three dimensions."""
    if problem.three_d():
        method = RK4(steps[-1], in_time=True)
        tr = _on_ephemeris(transcribe(problem, method, start), problem, result)
        return _corrected(problem, tr, method, solve_transcription(tr, opts), opts,
                          max_rounds)[:2]
    tr = _on_ephemeris(transcribe(problem, CVODES(in_time=True), start), problem, result)
    return solve_transcription(tr, opts), tr


def polish(problem, result, options=None, steps=RK4_STEPS, max_rounds=MAX_ROUNDS):
    """Re-solve ``problem`` on the exact equations in time, warm-started from ``result`` (every node
    from a CVODES flight of its schedule, :func:`exact_guess`).  Rounds of defect correction
    (:func:`_corrected`) follow until the flight lands on the NLP's final node, the optimum then
    being the exact one; else :func:`_fallback`.

    ``result`` is the closed-form optimum (``ipopt.solve_problem``), whose revolution class is kept
    (without its final-angle box a window optimum would slide into another); ``options`` default to
    :func:`polish_options`, from :data:`START_MU` unless they set ``ipopt.mu_init``; ``steps``, the
    RK4 step counts (:func:`rk4_polish_method`); ``max_rounds``, the most defect corrections.

    Returns (NLPResult, Transcription): ``durations`` are the polished segment times, ``lengths``
    the angles they sweep, ``q3`` empty; ``iterations`` and ``solve_seconds`` cover every round
    (solver builds and CVODES flights included), ``stages`` lists each round's status.
    """
    started = time.perf_counter()
    schedule = result.as_guess(durations=True)
    start = exact_guess(problem, result.x_start, schedule)
    opts = {"ipopt.mu_init": START_MU, **(polish_options() if options is None else options)}
    first, tr, method = _first_solve(problem, result, start, schedule, steps, opts)
    exact, tr, landed = _corrected(problem, tr, method, first, opts, max_rounds)
    if not landed:
        # The RK4 NLP can wander off where the exact one would not.
        again, tr = _fallback(problem, result, start, opts, steps, max_rounds)
        exact = again.after(exact)
    return dataclasses.replace(exact, solve_seconds=time.perf_counter() - started), tr
