"""A pipeline :class:`~esail_opt.optimisation.pipeline.Run` as the fields of its
:class:`~esail_opt.app.solution.Solution`: the file's units (au, km/s, km, m/s, days,
degrees), the problem's parts as kind and fields, dates ISO 8601 (TDB).  Nothing here
solves or flies: every number is the run's own, converted."""

import dataclasses
import math

import numpy as np

from esail_opt.app import schema
from esail_opt.app.solution_parts import (Bounds, ClassLooked, DepartureBody, NearestFeasible,
                                          Part, Polish, Samples, Schedule, Segment, Settings,
                                          Stage, State, TargetBody, VerificationRecord)
from esail_opt.bodies import dates, lookup
from esail_opt.optimisation.pipeline import Outcome
from esail_opt.optimisation.nodes import node_cartesian
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_columns
from esail_opt.physics.thrust import canonical_attitude


def _polar(x):
    """Polar state(s) (4 or 4 x M), canonical -> boundary units, with osculating a and e:
    the fields of a :class:`State` (floats) or of :class:`Samples` (lists)."""
    x = np.asarray(x, float)
    cols = x.reshape(4, -1)
    a, e = classical_columns(cols)
    out = {"r_au": cols[0], "theta_deg": np.degrees(cols[1]),
           "vr_km_s": units.speed_to_km_s(cols[2]), "vtheta_km_s": units.speed_to_km_s(cols[3]),
           "a_au": a, "e": e}
    if x.ndim == 1:
        return {k: float(v[0]) for k, v in out.items()}
    return out


def state(x, cartesian=None):
    """A polar state (4,) as a :class:`State`; in 3-D with its Cartesian state (6,)."""
    three_d = None if cartesian is None else schema.state_fields(np.asarray(cartesian,
                                                                            float)[:6])
    return State(**_polar(x), cartesian=three_d)


def samples(xs, cartesian=None):
    """A flight's samples (5 x M) as :class:`Samples`; a 3-D flight's Cartesian samples
    (7 x M, canonical) add the state in ``schema.STATE_KEYS`` and the osculating
    inclination and node, deg."""
    three_d = None
    if cartesian is not None:
        three_d = schema.state_fields(cartesian[:6])
        h = np.cross(cartesian[:3].T, cartesian[3:6].T).T
        three_d["inclination_deg"] = np.degrees(np.arctan2(np.hypot(h[0], h[1]), h[2]))
        three_d["node_deg"] = np.degrees(np.arctan2(h[0], -h[1]))
    return Samples(**_polar(xs[:4]), t_days=units.time_to_days(np.asarray(xs[4])),
                   three_d=three_d)


def _angle_deg(radians):
    """An angle the NLP leaves unbounded, reported in [-180, 180) deg."""
    return (math.degrees(radians) + 180) % 360 - 180


def _attitudes_deg(problem, result):
    """Each segment's (pitch, clock) in deg, the clock in [-180, 180) (None in the plane);
    with the clock free and the pitch bounded symmetrically, each attitude by its canonical
    name (:func:`~esail_opt.physics.thrust.canonical_attitude`), which both bounds admit."""
    if result.delta is None:
        return [(math.degrees(a), None) for a in result.alpha]
    lo, hi = problem.alpha_bounds()
    canonical = problem.clock_free() and lo == -hi
    pairs = zip(result.alpha, result.delta)
    if canonical:
        pairs = (canonical_attitude(a, d) for a, d in pairs)
    return [(math.degrees(a), _angle_deg(d)) for a, d in pairs]


def schedule(problem, result, local_errors=None):
    """The :class:`Schedule` of an NLP result for ``problem``: each row with its throttle
    for a throttled problem, and its ``local_errors`` entry (km, one per segment) if given."""
    n = result.alpha.size
    throttled = problem.throttled()
    starts_t = np.r_[0.0, np.cumsum(result.durations)[:-1]]
    starts_th = np.r_[result.x_start[1], result.nodes[1, :-1]]
    kappa = result.throttle if throttled else [None] * n
    errors = [None] * n if local_errors is None else local_errors
    rows = tuple(
        Segment(t_days=units.time_to_days(t), theta_deg=math.degrees(th),
                alpha_deg=al, duration_days=units.time_to_days(dt),
                dtheta_deg=math.degrees(ln), clock_deg=c, throttle=k, local_error_km=err)
        for t, th, (al, c), dt, ln, k, err in zip(
            starts_t, starts_th, _attitudes_deg(problem, result), result.durations,
            result.lengths, kappa, errors))
    return Schedule(rows=rows, throttled=bool(throttled),
                    local_errors=local_errors is not None)


def departure_state(problem, result):
    """The state the verification flies from; in three dimensions the exact polar state
    inside the departure's plane and its Cartesian ecliptic state."""
    if not problem.three_d():
        return state(problem.start_state(result))
    plane = problem.departure.plane_state_at(result.epoch, result.vinf_angle)
    return state(plane[:4], problem.start_state(result))


def _final_state(result):
    """The NLP's final state; a 3-D node adds its Cartesian state."""
    nodes = result.nodes
    return state(nodes[:4, -1], None if result.delta is None else node_cartesian(nodes[:, -1]))


def _tof_days(result):
    return units.time_to_days(float(np.sum(result.durations)))


def _flight(check):
    """The :class:`VerificationRecord` of a verification (closed form and polish alike)."""
    named = {f.name for f in dataclasses.fields(VerificationRecord)}
    flown = {}
    if check.error is None:
        cart = getattr(check, "cartesian", None)
        flown = {"cvodes_final_state": state(check.cvodes[:4, -1],
                                             None if cart is None else cart[:, -1]),
                 "cvodes_tof_days": units.time_to_days(float(check.cvodes[4, -1]))}
    misses = check.misses
    return VerificationRecord(**{k: v for k, v in misses.items() if k in named}, **flown,
                              extra={k: v for k, v in misses.items() if k not in named},
                              error=check.error)


def _part(obj):
    """A problem part as a :class:`Part`: its kind and fields, a body by its description."""
    fields = {k: getattr(obj, k) for k in obj.__dataclass_fields__}
    if "body" in fields:
        fields["body"] = lookup.describe(fields["body"])
    return Part(kind=type(obj).__name__, fields=fields)


def _settings(problem, result, sub_arcs_requested):
    """The problem as solved (``Solution.problem``)."""
    seg, sail = problem.segments, problem.sail
    return Settings(
        name=problem.name, description=problem.description, ac_mm_s2=sail.ac_mm_s2,
        coefficients=list(sail.coefficients),
        alpha_bounds_deg=[sail.alpha_min_deg, sail.alpha_max_deg],
        segments=int(result.alpha.size), segments_per_revolution=seg.per_revolution,
        sub_arcs=seg.sub_arcs, sub_arcs_requested=sub_arcs_requested,
        equal_segments=seg.equal, objective=type(problem.objective).__name__,
        target=None if problem.target is None else _part(problem.target),
        departure=_part(problem.departure),
        # For a body, the state of its ephemeris, not the NLP's smooth track of it.
        departure_state=departure_state(problem, result),
        r_min_au=problem.path.r_min_au, q3_margin=problem.path.q3_margin,
        throttle_bounds=list(problem.throttle_bounds()) if problem.throttled() else None)


def _target_body(target, check):
    """The target body as the flight met it (None unless the target is a body)."""
    if target is None or getattr(target, "body", None) is None:
        return None
    m = check.misses
    return TargetBody(name=lookup.name(target.body), source=lookup.source(target.body),
                      kind=type(target).__name__, out_of_plane_km=m.get("out_of_plane_km"),
                      relative_speed_km_s=m.get("relative_speed_km_s"),
                      normal_miss_km=m.get("normal_miss_km"))


def calendar(problem, result, check):
    """The dated fields of a flight (dates, the bodies with their sources and distances from
    the ecliptic) and the a_c a MinAcceleration found, as keyword arguments of
    :class:`Solution` and :class:`Polish` alike; empty for an undated problem sizing no sail."""
    out = {}
    if problem.objective.free_acceleration:
        out["ac_mm_s2_required"] = problem.sail.ac_mm_s2 * result.ac_scale
    if not problem.dated():
        return out
    dep = problem.departure
    start_jd = dates.jd_from_tu(result.epoch)
    z0 = lookup.polar_state(dep.body, start_jd)[1]
    out.update(departure_date=dates.iso_from_jd(start_jd),
               departure_epoch_days=units.time_to_days(float(result.epoch)),
               arrival_date=dates.iso_from_jd(dates.jd_from_tu(
                   result.epoch + float(np.sum(result.durations)))),
               time_scale=dates.TIME_SCALE,
               departure_body=DepartureBody(
                   name=lookup.name(dep.body), source=lookup.source(dep.body),
                   out_of_plane_km=units.length_to_km(abs(z0)), vinf_km_s=dep.vinf_km_s,
                   vinf_angle_deg=_angle_deg(result.vinf_angle)),
               target_body=_target_body(problem.target, check))
    return out


def _polish(problem, polished):
    """``Solution.polish`` of the run's PolishRun."""
    if not polished.ran:
        return Polish(status=None, converged=False, verified=False, note=polished.note)
    exact, bounds = polished.result, polished.tolerance
    return Polish(
        status=exact.status, converged=exact.converged, outcome=exact.outcome,
        iterations=exact.iterations, seconds=exact.solve_seconds,
        constraint_violation=exact.constraint_violation, objective=exact.objective,
        tof_days=_tof_days(exact),
        bounds=Bounds(position_km=bounds.position_km, velocity_m_s=bounds.velocity_m_s),
        within_bounds_vs_nlp=polished.within_nlp,
        within_bounds_vs_target=polished.within_target,
        verified=polished.verified, note=polished.note,
        schedule=schedule(problem, exact),
        final_state=_final_state(exact), verification=_flight(polished.check),
        # A polish may move the departure and the a_c: it is flown from its own start.
        departure_state=departure_state(problem, exact),
        **calendar(problem, exact, polished.check))


def _polish_fields(run, drawn):
    """The Solution's fields of the polish (none without one), its flight ``drawn``."""
    polished = run.polish
    if polished is None:
        return {}
    out = {"polish": _polish(run.problem, polished)}
    if polished.ran:
        exact = polished.result
        out.update(objective_closed_form=polished.closed_form_objective,
                   objective_exact=exact.objective, tof_days_exact=_tof_days(exact),
                   trajectory_polished=_trajectory(drawn))
    return out


def _trajectory(drawn):
    """The CVODES samples of a ``verify.Sampled`` (None when CVODES failed)."""
    return None if drawn.cvodes is None else samples(drawn.cvodes, drawn.cartesian)


def _class_looked(problem, c):
    """A ClassTried of the run in the file's units (``Solution.classes``)."""
    acc = problem.objective.free_acceleration and c.ac_scale is not None
    return ClassLooked(
        revolutions_k=c.revolutions_k, label=c.label, status=c.status,
        iterations=c.iterations, objective=c.objective,
        tof_days=None if c.tof is None else units.time_to_days(c.tof),
        ac_mm_s2_required=problem.sail.ac_mm_s2 * c.ac_scale if acc else None,
        constraint_violation=c.constraint_violation, verified=c.verified, chosen=c.chosen,
        projected=c.projected)


def _nearest_feasible(near):
    """The shortest feasible flight the walk found, dated as any flight is."""
    if near is None:
        return None
    flown = near.flight
    dated = calendar(flown.problem, flown.result, flown.check)
    return NearestFeasible(
        departure_date=dated.get("departure_date"), tof_days=near.tof_days,
        ac_mm_s2_required=dated.get("ac_mm_s2_required", flown.problem.sail.ac_mm_s2),
        verified=flown.verified, note=flown.note,
        infeasible_tof_days=near.infeasible_tof_days, iterations=near.iterations)


def _closed_form_fields(run, drawn):
    """The Solution's fields of the closed-form solve, its flight (``drawn``) and its
    record."""
    problem, result, check = run.problem, run.result, run.check
    controlled = run.error_control
    return dict(
        problem=_settings(problem, result, run.sub_arcs_requested),
        status=result.status, converged=result.converged,
        acceptable=result.outcome is Outcome.ACCEPTABLE, outcome=result.outcome,
        flight_verified=run.verified, verification_note=run.note,
        tolerance=Bounds(position_km=problem.tolerance.position_km,
                         velocity_m_s=problem.tolerance.velocity_m_s),
        objective=result.objective, objective_meaning=problem.objective.meaning,
        tof_days=_tof_days(result), iterations=result.iterations,
        stages=tuple(Stage(status=s, iterations=i) for s, i in result.stages),
        solve_seconds=result.solve_seconds, constraint_violation=result.constraint_violation,
        min_q3=float(np.min(result.q3)),
        schedule=schedule(problem, result,
                          None if controlled is None else controlled.local_error_km),
        final_state=_final_state(result), verification=_flight(check),
        rounds=() if controlled is None else tuple(controlled.history),
        starts=tuple(run.starts),
        trajectory_closed_form=samples(drawn.closed_form),
        trajectory_cvodes=_trajectory(drawn),
        **calendar(problem, result, check))


def solution_fields(run, drawn, drawn_polish=None):
    """The keyword arguments of a pipeline Run's Solution, but its schema version:
    ``drawn`` is its schedule drawn for the files and figures (``verify.sampled``),
    ``drawn_polish`` the polished one's."""
    return dict(**_closed_form_fields(run, drawn), **_polish_fields(run, drawn_polish),
                classes=tuple(_class_looked(run.problem, c) for c in run.classes),
                classes_skipped=run.classes_skipped,
                nearest_feasible=_nearest_feasible(run.nearest_feasible))
