"""Verification of an optimised schedule on the full Eqs. 1-2 with CVODES (in three dimensions in
the turning plane, checked on the Cartesian equations, :func:`verify3d`).

The schedule is flown from the exact departure for the NLP's own segment durations, its final state
held to the NLP's final node (the closed form's drift) and to the target.  :func:`judge` counts a
bound as met only when the miss plus the verifier's own error, the gap between flights at
``VERIFY_TOLERANCE`` and ``CHECK_TOLERANCE``, is below it.
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from esail_opt.bodies import dates
from esail_opt.optimisation.goals import cartesian_miss, state_miss
from esail_opt.optimisation.segment_methods import arc_model
from esail_opt.optimisation.nodes import node_cartesian, start_node
from esail_opt.propagation.rectified import propagate
from esail_opt.propagation.rectified3d import propagate3d
from esail_opt.propagation.simulate import (CHECK_TOLERANCE, VERIFY_TOLERANCE, simulate,
                                            simulate3d)

#: Flight samples per segment of the files and figures.
SAMPLES = 16


def target_miss(target, x, t, t0=0.0):
    """Miss of polar state ``x`` at time ``t`` (TU) after a departure at epoch ``t0``
    from ``target`` (its ``miss``), with Nones when there is no target."""
    if target is None:
        return {"target_miss_r_km": None, "target_miss_v_m_s": None}
    return target.miss(x, t, t0)


@dataclass
class Verification:
    """The CVODES flight a verdict is made on, and its misses (boundary units in the dict).

    ``cvodes`` holds [r, theta, v_r, v_theta, t] at the departure and each segment's end; in 3-D it
    is a view of ``cartesian``, the flight's [x, y, z, vx, vy, vz, t] at those instants (ecliptic of
    J2000, canonical).  Both are NaN placeholders when CVODES failed (``error`` says why)."""

    cvodes: np.ndarray
    misses: dict
    error: Optional[str] = None
    cartesian: Optional[np.ndarray] = None

    def judge(self, problem, tolerance=None, against_nlp=False):
        """:func:`judge` of this flight's misses."""
        return judge(problem, self.misses, self.error,
                     problem.tolerance if tolerance is None else tolerance, against_nlp)


def _exceeded(r, v, r_err, v_err, tolerance):
    """The bounds a miss (km, m/s or None) plus the verifier's error exceeds, as text."""
    out = []
    if not r + r_err <= tolerance.position_km:
        out.append(f"{r:.4g} km (+ {r_err:.2g} km verifier error), bound "
                   f"{tolerance.position_km:g} km")
    if v is not None and not v + v_err <= tolerance.velocity_m_s:
        out.append(f"{v:.4g} m/s (+ {v_err:.2g} m/s verifier error), bound "
                   f"{tolerance.velocity_m_s:g} m/s")
    return out


def within(misses, tolerance, against="target"):
    """Whether the flight, its verifier's error included, is within ``tolerance`` of the
    target (``against="target"``) or of the NLP's final state (``"nlp"``)."""
    prefix = "target_" if against == "target" else ""
    r, v = misses.get(prefix + "miss_r_km"), misses.get(prefix + "miss_v_m_s")
    if r is None or misses.get("verifier_error_r_km") is None or _outside(misses):
        return False
    return not _exceeded(r, v, misses["verifier_error_r_km"], misses["verifier_error_v_m_s"],
                         tolerance)


#: How far (days) a flight may arrive outside its target's arrival window and still be
#: in it: about a second.  The NLP holds the window as a constraint, far closer than this.
WINDOW_SLACK_DAYS = 1e-5


def window_miss(target, epoch, tof):
    """Days by which an arrival at ``epoch + tof`` (TU since J2000 TDB) falls outside
    ``target``'s arrival window (0 inside it), or None for a target without one."""
    window = getattr(target, "arrival_jd", None)
    if window is None:
        return None
    arrival = dates.jd_from_tu(float(epoch) + float(tof))
    return max(window[0] - arrival, arrival - window[1], 0.0)


def _outside(misses):
    late = misses.get("arrival_outside_window_days")
    return late is not None and late > WINDOW_SLACK_DAYS


def judge(problem, misses, error, tolerance, against_nlp=False):
    """``(met, line)``: whether a flight with :func:`verify`'s ``misses`` (km, m/s) and failure
    ``error`` (or None) meets ``tolerance``, and a line naming each missed bound with the miss, the
    verifier's error and the bound.  ``against_nlp`` holds the flight to the NLP's final state as
    well as to the target (the polish's nodes are its answer), as is always done without one."""
    if error is not None:
        return False, f"NOT verified: {error}"
    r_err, v_err = misses["verifier_error_r_km"], misses["verifier_error_v_m_s"]
    checks = []
    if problem.target is not None:
        checks.append(("the target", misses["target_miss_r_km"], misses["target_miss_v_m_s"]))
    if against_nlp or problem.target is None:
        checks.append(("the NLP's final state", misses["miss_r_km"], misses["miss_v_m_s"]))
    failed = []
    for what, r, v in checks:
        failed += [f"misses {what} by {text}" for text in _exceeded(r, v, r_err, v_err, tolerance)]
    if _outside(misses):
        first, last = problem.target.arrival_window
        failed.append(f"arrives {misses['arrival_outside_window_days']:.4g} d outside the "
                      f"arrival window {first} to {last}")
    flight = f"the flight on {problem.equations()}"
    if failed:
        speeds = any(v is not None for _, _, v in checks)
        # No flight, however good, passes: say so, or a user tries again in vain.
        blind = (r_err >= tolerance.position_km
                 or (speeds and v_err >= tolerance.velocity_m_s))
        return False, (f"NOT verified: {flight} " + "; ".join(failed)
                       + ("; the verifier's own error alone reaches the bound, so no flight "
                          "can be shown to meet it on these equations" if blind else ""))
    if all(v is not None for _, _, v in checks):
        return True, (f"verified: {flight} is within {tolerance.position_km:g} "
                      f"km and {tolerance.velocity_m_s:g} m/s of "
                      + " and ".join(c[0] for c in checks))
    # An intercept is held to a position only: the line must not claim a speed bound.
    held = [f"{tolerance.position_km:g} km" + ("" if v is None else
                                                f" and {tolerance.velocity_m_s:g} m/s")
            + f" of {what}" for what, _, v in checks]
    return True, f"verified: {flight} is within " + ", and within ".join(held)


def closed_form_curve(problem, result, samples=SAMPLES, defects=None):
    """The closed form the NLP solved, sampled: 5 x (1 + N S m) states, S sub-arcs and
    m = max(1, samples // S) samples per sub-arc, so that column k S m is node k.

    Every segment is flown from its NLP node on the NLP's arcs, so the gap to the CVODES flight is
    the closed form's error alone.  ``defects`` (``optimisation.error_control``), known at segment
    ends only, are added in proportion to the angle flown, keeping the curve continuous.
    """
    model = arc_model(problem)
    ac, coeff = problem.sail.ac * result.ac_scale, problem.sail.coefficients
    kappa = _throttles(result)
    per_sub = max(1, samples // model.sub_arcs)
    first = start_node(result.x_start)
    starts = np.column_stack([first, result.nodes[:, :-1]])
    pieces = [first[:, None]]
    for k in range(result.alpha.size):
        if getattr(result, "delta", None) is None:
            xs, _ = propagate(starts[:4, k], [result.alpha[k]], [result.lengths[k]], ac,
                              throttles=[kappa[k]], samples=per_sub, coefficients=coeff,
                              model=model)
        else:
            xs, _ = propagate3d(starts[:4, k], starts[5:, k], [result.alpha[k]],
                                [result.delta[k]], [result.lengths[k]], ac,
                                throttles=[kappa[k]], samples=per_sub, coefficients=coeff,
                                model=model)
        xs = xs[:, 1:]
        xs[4] += starts[4, k]
        if defects is not None:
            xs += np.outer(np.asarray(defects, float)[:, k],
                           np.arange(1, xs.shape[1] + 1) / xs.shape[1])
        pieces.append(xs)
    return np.column_stack(pieces)


def verify(problem, result):
    """Fly ``result``'s schedule (an ``NLPResult``; ``throttle`` None is full thrust) with CVODES
    and measure its misses: a :class:`Verification`.  The flight is kept only at the departure and
    segment ends, so that a verdict never depends on how densely :func:`sampled` draws it."""
    if getattr(result, "delta", None) is not None:
        return verify3d(problem, result)
    ac, coeff = problem.sail.ac * result.ac_scale, problem.sail.coefficients
    # CVODES flies from the exact departure (a body's ephemeris, not the NLP's track).
    x0_exact = problem.start_state(result)
    kappa = _throttles(result)
    try:
        flown = simulate(x0_exact, result.alpha, result.durations, ac, throttles=kappa,
                         length_in="time", coefficients=coeff, tol=VERIFY_TOLERANCE)
        check = simulate(x0_exact, result.alpha, result.durations, ac, throttles=kappa,
                         length_in="time", coefficients=coeff, tol=CHECK_TOLERANCE)
    except Exception as err:  # CVODES gave up (e.g. an escaping orbit): report, do not hide
        return Verification(np.full((5, 1), np.nan), _failed(), f"CVODES failed: {err}")
    xf_nlp = result.nodes[:4, -1]
    xf_cv = flown[:4, -1]
    dr, dv, dth = state_miss(xf_cv, xf_nlp)
    misses = {"miss_r_km": dr, "miss_v_m_s": dv, "miss_theta_deg": dth}
    err_r, err_v, _ = state_miss(check[:4, -1], xf_cv)
    misses.update(verifier_error_r_km=err_r, verifier_error_v_m_s=err_v)
    misses.update(target_miss(problem.target, xf_cv, flown[4, -1], result.epoch))
    _add_window_miss(misses, problem.target, result.epoch, flown[4, -1])
    nlp_target = target_miss(problem.target, xf_nlp, float(np.sum(result.durations)),
                             result.epoch)
    misses["nlp_target_miss_r_km"] = nlp_target["target_miss_r_km"]
    return Verification(flown, misses)


def _throttles(result):
    """kappa per segment (ones for a sail always on)."""
    return (np.ones(result.alpha.size) if getattr(result, "throttle", None) is None
            else np.asarray(result.throttle, float))


def _failed():
    """The misses of a flight CVODES could not finish: all unknown."""
    return {k: None for k in ("miss_r_km", "miss_v_m_s", "miss_theta_deg",
                              "target_miss_r_km", "target_miss_v_m_s",
                              "verifier_error_r_km", "verifier_error_v_m_s")}


def polar_view(flight, x_start):
    """A 3-D flight's Cartesian samples (7 x M) as [r, theta, v_r, v_theta, t] for the
    plots: theta is the angle swept from the 8-row ``x_start``'s theta (samples less
    than half a turn apart), v_theta = |r x v| / r."""
    pos = flight[:3]
    r = np.linalg.norm(pos, axis=0)
    cos = np.clip(np.sum(pos[:, 1:] * pos[:, :-1], axis=0) / (r[1:] * r[:-1]), -1, 1)
    return _polar(flight, float(x_start[1]) + np.r_[0.0, np.cumsum(np.arccos(cos))])


def _node_view(flight, result):
    """:func:`polar_view` of a flight's states at the departure and each segment's end,
    however far apart: theta is the NLP's own there plus the signed angle from its
    node's position to the flight's about the node's angular momentum."""
    nodes = np.column_stack([start_node(result.x_start), result.nodes])
    node = np.column_stack([node_cartesian(n) for n in nodes.T])
    axis = np.cross(node[:3].T, node[3:6].T).T
    axis /= np.linalg.norm(axis, axis=0)
    turn = np.arctan2(np.sum(np.cross(node[:3].T, flight[:3].T).T * axis, axis=0),
                      np.sum(node[:3] * flight[:3], axis=0))
    return _polar(flight, nodes[1] + turn)


def _polar(flight, theta):
    """[r, theta, v_r, v_theta, t] of Cartesian states (7 x M) at the angles ``theta``."""
    pos, vel = flight[:3], flight[3:6]
    r = np.linalg.norm(pos, axis=0)
    h = np.linalg.norm(np.cross(pos.T, vel.T), axis=1)
    return np.vstack([r, theta, np.sum(pos * vel, axis=0) / r, h / r, flight[6]])


def verify3d(problem, result):
    """:func:`verify` in three dimensions, in the turning plane (``simulate.FORMS_3D``), held in
    Cartesian coordinates of the ecliptic of J2000 to the NLP's final node and to the target body's
    state at the flown arrival (``miss3d``).  The verifier's error adds the gap to a flight of the
    Cartesian equations, as two forms do not share their integration errors (THEORY.md §5.5)."""
    ac, coeff = problem.sail.ac * result.ac_scale, problem.sail.coefficients
    args = (problem.start_state(result), result.alpha, result.delta, result.durations, ac)
    kappa = _throttles(result)
    try:
        judged = simulate3d(*args, throttles=kappa, length_in="time", coefficients=coeff,
                            tol=VERIFY_TOLERANCE)
        check = simulate3d(*args, throttles=kappa, length_in="time", coefficients=coeff,
                           tol=CHECK_TOLERANCE)
        cartesian = simulate3d(*args, throttles=kappa, length_in="time",
                               coefficients=coeff, tol=VERIFY_TOLERANCE, form="cartesian")
    except Exception as err:  # CVODES gave up: report, do not hide
        return Verification(np.full((5, 1), np.nan), _failed(), f"CVODES failed: {err}",
                            np.full((7, 1), np.nan))
    yf = judged[:6, -1]
    dr, dv = cartesian_miss(yf, node_cartesian(result.nodes[:, -1]))
    view = _node_view(judged, result)
    misses = {"miss_r_km": dr, "miss_v_m_s": dv,
              "miss_theta_deg": float(np.degrees(view[1, -1] - result.nodes[1, -1]))}
    (tol_r, tol_v), (form_r, form_v) = (cartesian_miss(other[:6, -1], yf)
                                        for other in (check, cartesian))
    misses.update(verifier_error_r_km=tol_r + form_r, verifier_error_v_m_s=tol_v + form_v)
    tf = float(judged[6, -1])
    tof_nlp = float(np.sum(result.durations))
    if hasattr(problem.target, "miss3d"):
        misses.update(problem.target.miss3d(yf, tf, result.epoch))
        nlp = problem.target.miss3d(node_cartesian(result.nodes[:, -1]), tof_nlp,
                                    result.epoch)
        misses["nlp_target_miss_r_km"] = nlp["target_miss_r_km"]
    else:
        # An orbit target (or none) holds r, v_r and h only: the plane's polar view is exact.
        misses.update(target_miss(problem.target, view[:4, -1], tf, result.epoch))
    _add_window_miss(misses, problem.target, result.epoch, tf)
    return Verification(view, misses, None, judged)


@dataclass(frozen=True)
class Sampled:
    """A schedule drawn for the files and figures: the closed form the NLP solved
    (``closed_form``, 5 x M, :func:`closed_form_curve`) and its CVODES flight
    (``cvodes``, 5 x M, None when CVODES failed; in 3-D a view of ``cartesian``, 7 x M)."""

    closed_form: np.ndarray
    cvodes: Optional[np.ndarray]
    cartesian: Optional[np.ndarray] = None


def sampled(problem, result, defects=None, samples=SAMPLES):
    """``result``'s schedule drawn with ``samples`` points a segment (a :class:`Sampled`):
    the closed form from the NLP's nodes with ``defects``, and CVODES from the exact
    departure.  Apart from the verdict's flight, because stopping CVODES at each sample
    moves a flight's end by as much as the verifier's own error."""
    closed = closed_form_curve(problem, result, samples, defects)
    ac, coeff = problem.sail.ac * result.ac_scale, problem.sail.coefficients
    kappa, y0 = _throttles(result), problem.start_state(result)
    try:
        if getattr(result, "delta", None) is None:
            return Sampled(closed, simulate(y0, result.alpha, result.durations, ac,
                                            throttles=kappa, samples=samples,
                                            length_in="time", coefficients=coeff,
                                            tol=VERIFY_TOLERANCE))
        flown = simulate3d(y0, result.alpha, result.delta, result.durations, ac,
                           throttles=kappa, samples=samples, length_in="time",
                           coefficients=coeff, tol=VERIFY_TOLERANCE)
    except Exception:  # the verdict's flight says why
        return Sampled(closed, None)
    return Sampled(closed, polar_view(flown, result.x_start), flown)


def _add_window_miss(misses, target, epoch, tof):
    """Add ``arrival_outside_window_days`` to ``misses`` if ``target`` has an arrival window."""
    late = window_miss(target, epoch, tof)
    if late is not None:
        misses["arrival_outside_window_days"] = late
