"""One fixed attitude flown from a parking orbit: the paper's closed form against CVODES.

Two jobs share it.  ``esail-opt propagate`` flies the paper's closed form (one arc,
no rectification) to where its own clock reaches the horizon, and CVODES to the
horizon.  The paper's Figs. 3-4 measure Eq. 27 over the numerical integration's
swept angle in the horizon (the closed form, a function of theta, has no clock
there): :func:`eps_over_swept_angle`.  theta is measured from the parking orbit's
apse line (the paper's convention), so theta0 = nu0.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from esail_opt.errors import InputError, check_range
from esail_opt.physics import constants as units
from esail_opt.physics.elements import polar_from_classical
from esail_opt.physics.thrust import EXACT
from esail_opt.propagation.rectified import rectified_function
from esail_opt.propagation.simulate import SimulationError, simulate

METHODS = ("closed-form", "cvodes", "both")
#: Beyond theta_max (q3 = 0), or where the transverse speed s of Eq. 11 reaches 0,
#: r = r0 / (q3 s) of Eq. 9 leaves (0, inf) and the clock diverges.  Near those
#: points the first-order arc is meaningless long before the divergence, so an arc
#: counts as valid only while every sample keeps r within (0, r0 / VALIDITY_FLOOR].
VALIDITY_FLOOR = 0.01
#: Samples per revolution: enough to resolve the short-period oscillation of r.
PER_REVOLUTION = 32
MIN_SAMPLES = 200


@dataclass(frozen=True)
class FixedAttitudeCase:
    """A parking orbit, a sail and a horizon, in the boundary's units.

    Attributes
    ----------
    a0_au : float
        Parking orbit semimajor axis, au.
    e0 : float
        Parking orbit eccentricity, [0, 1).
    nu0_deg : float
        Departure true anomaly, deg.
    ac_mm_s2 : float
        Characteristic acceleration, mm/s^2, > 0.
    alpha_deg : float
        Pitch angle alpha_n, deg, in [-90, 90].
    years : float
        Horizon, years (365.25 days), > 0.
    coefficients : tuple
        The thrust model's (b1, b2) of Eqs. 3-4.
    """

    a0_au: float
    e0: float
    nu0_deg: float
    ac_mm_s2: float
    alpha_deg: float
    years: float
    coefficients: tuple = EXACT

    def __post_init__(self):
        check_range("a0_au", self.a0_au, 0, low_open=True, unit="au")
        check_range("e0", self.e0, 0, 1, high_open=True)
        check_range("nu0_deg", self.nu0_deg, -360, 360, unit="deg")
        check_range("ac_mm_s2", self.ac_mm_s2, 0, low_open=True, unit="mm/s^2")
        check_range("alpha_deg", self.alpha_deg, -90, 90, unit="deg")
        check_range("years", self.years, 0, low_open=True)

    def state0(self):
        """Departure polar state, canonical units, theta from the apse line."""
        x = polar_from_classical(self.a0_au, self.e0, 0.0, math.radians(self.nu0_deg))
        return np.array(x, float).ravel()

    @property
    def alpha(self):
        """Pitch angle, rad."""
        return math.radians(self.alpha_deg)

    @property
    def horizon(self):
        """Horizon, canonical time units."""
        return units.time_from_years(self.years)

    @property
    def ac(self):
        """Characteristic acceleration, canonical units."""
        return units.accel_from_mm_s2(self.ac_mm_s2)


def samples_for(case, minimum=MIN_SAMPLES, per_revolution=PER_REVOLUTION):
    """Sample count resolving the short-period oscillation over the horizon:
    ``per_revolution`` per parking-orbit period, at least ``minimum``."""
    period = 2 * math.pi * case.a0_au**1.5
    return max(minimum, int(math.ceil(per_revolution * case.horizon / period)))


def samples_over(span, minimum=MIN_SAMPLES, per_revolution=PER_REVOLUTION):
    """Sample count resolving the short-period oscillation over ``span`` rad of theta."""
    return max(minimum, int(math.ceil(per_revolution * span / (2 * math.pi))))


def _arc(case, samples):
    """``run(angle) -> (xs, q3)``: the closed form's one arc over ``angle`` rad of theta,
    xs of shape (5, samples + 1) from the departure, canonical units."""
    x0 = np.r_[case.state0(), 0.0]
    arc = rectified_function(1, samples, "theta", case.coefficients)
    ac, alpha = case.ac, case.alpha

    def run(angle):
        xs, q3 = arc(x0, ac, alpha, angle)
        return np.column_stack([x0, np.array(xs)]), float(q3)

    return run


def _valid(xs, q3):
    """Whether an arc holds: q3 > 0, r within (0, r0 / VALIDITY_FLOOR], time advancing."""
    r, t = xs[0], xs[4]
    return (q3 > 0 and np.all(np.isfinite(xs)) and np.all(r > 0)
            and np.all(r <= r[0] / VALIDITY_FLOOR) and np.all(np.diff(t) > 0))


def _validity_limit(run, good, bad):
    """The largest valid angle between ``good`` (valid) and ``bad`` (not), by bisection."""
    while bad - good > 1e-9 * bad:
        mid = 0.5 * (good + bad)
        good, bad = (mid, bad) if _valid(*run(mid)) else (good, mid)
    return good


def _horizon_bracket(case, run):
    """Angles (low, high) whose closed-form clock straddles the horizon.

    The angle doubles until the clock passes the horizon or the arc stops holding.

    Raises
    ------
    InputError
        If the arc stops holding before its clock reaches the horizon.
    """
    horizon = case.horizon
    x0 = case.state0()
    low, high = 0.0, horizon * x0[3] / x0[0]
    while True:
        xs, q3 = run(high)
        if not _valid(xs, q3):
            good = _validity_limit(run, low, high)
            reach = run(good)[0][4, -1] if good > 0 else 0.0
            if reach < horizon:
                allowed = units.time_to_days(reach) / units.YEAR_DAYS
                raise InputError(
                    f"years = {case.years:g} is past theta_max: the first-order arc holds "
                    f"(q3 > 0, r within {1 / VALIDITY_FLOOR:g} r0) only up to theta - theta0 "
                    f"= {math.degrees(good):.1f} deg; allowed years in (0, {allowed:.3g})"
                )
            return low, good
        if xs[4, -1] >= horizon:
            return low, high
        low, high = high, 2 * high


def closed_form(case, samples):
    """The paper's single first-order arc, sampled at ``samples`` equal steps of theta.

    The arc angle is the root of the closed form's own clock t(theta) = horizon.

    Returns
    -------
    numpy.ndarray, shape (5, samples + 1)
        [r, theta, v_r, v_theta, t], canonical units.

    Raises
    ------
    InputError
        If the horizon lies past the arc's validity (see VALIDITY_FLOOR).
    """
    run = _arc(case, samples)
    horizon = case.horizon
    low, high = _horizon_bracket(case, run)
    angle = brentq(lambda a: run(a)[0][4, -1] - horizon, low, high, xtol=1e-13, rtol=1e-15)
    return run(angle)[0]


def closed_form_over(case, span, samples):
    """The paper's single first-order arc over theta0 .. theta0 + ``span`` (rad).

    Returns
    -------
    numpy.ndarray, shape (5, samples + 1)
        [r, theta, v_r, v_theta, t] at equal steps of theta, canonical units; t is
        the closed form's own clock.

    Raises
    ------
    InputError
        If the arc does not hold over the whole span (see VALIDITY_FLOOR).
    """
    xs, q3 = _arc(case, samples)(span)
    if not _valid(xs, q3):
        raise InputError(
            f"the first-order arc does not hold (q3 > 0, r within {1 / VALIDITY_FLOOR:g} r0) "
            f"over theta - theta0 = {math.degrees(span):.1f} deg"
        )
    return xs


def swept_angle(case):
    """theta - theta0 (rad) that CVODES on Eqs. 1-2 reaches at the horizon."""
    x0 = case.state0()
    end = simulate(x0, [case.alpha], [case.horizon], case.ac,
                   coefficients=case.coefficients)
    return float(end[1, -1] - x0[1])


def cvodes(case, samples):
    """Eqs. 1-2 by CVODES to the horizon, sampled at equal steps of theta.

    A first run in time finds the angle at the horizon; a second, with theta as
    the independent variable, samples it.
    """
    return cvodes_at_theta(case, swept_angle(case), samples)


def cvodes_at_theta(case, angle, samples):
    """Eqs. 1-2 by CVODES with theta as the independent variable, ``samples`` steps."""
    return simulate(
        case.state0(), [case.alpha], [angle], case.ac,
        samples=samples, length_in="theta", coefficients=case.coefficients,
    )


def relative_error(case, closed):
    """Eq. 27 over the closed form's own arc: max of |r_n - r| / r0 at its angles.

    r_n is CVODES at the same theta.  Returns eps, whether it covers the whole
    arc, and the last angle it covers (rad).  It does not cover the whole arc
    when the true trajectory escapes short of the closed form's span (an escaping
    orbit's theta tends to a finite limit, and CVODES in theta fails): the maximum
    is then over the angles it reaches by the horizon.
    """
    samples = closed.shape[1] - 1
    span = closed[1, -1] - closed[1, 0]
    reached = int(samples * min(1.0, swept_angle(case) / span))
    try:
        numeric, kept = cvodes_at_theta(case, span, samples), samples
    except SimulationError:
        numeric, kept = cvodes_at_theta(case, span * reached / samples, reached), reached
    error = np.abs(numeric[0] - closed[0, : kept + 1]) / closed[0, 0]
    return float(np.max(error)), kept == samples, float(numeric[1, -1])


def eps_over_swept_angle(case, samples=None):
    """Eq. 27 as the paper's Figs. 3-4 measure it: over CVODES's swept angle.

    CVODES on Eqs. 1-2 flies the horizon in time; its angle at the end bounds the
    comparison, and the closed form (a function of theta) and CVODES in theta are
    sampled at the same ``samples`` equal steps of theta up to there.

    Returns
    -------
    eps : float
        max over theta of |r_n - r| / r0.
    span : float
        The swept angle theta_end - theta0, rad.

    Raises
    ------
    InputError
        If the closed form does not hold over the swept angle.
    """
    span = swept_angle(case)
    samples = samples_over(span) if samples is None else samples
    closed = closed_form_over(case, span, samples)
    numeric = cvodes_at_theta(case, span, samples)
    return float(np.max(np.abs(numeric[0] - closed[0])) / closed[0, 0]), span


def to_boundary(xs):
    """Samples in the boundary's units, as the JSON and plots speak them."""
    return {
        "t_days": units.time_to_days(xs[4]).tolist(),
        "theta_deg": np.degrees(xs[1]).tolist(),
        "r_au": xs[0].tolist(),
        "vr_km_s": units.speed_to_km_s(xs[2]).tolist(),
        "vtheta_km_s": units.speed_to_km_s(xs[3]).tolist(),
    }


def _eps_entries(case, closed):
    """The propagate JSON's eps, its coverage and the range of theta it was taken over."""
    eps, whole, end = relative_error(case, closed)
    source = ("the closed form's own arc: the angle its clock spans in the horizon" if whole
              else "the angles CVODES reaches in the horizon (it escapes short of the "
                   "closed form's span)")
    theta_range = {"from_deg": math.degrees(closed[1, 0]), "to_deg": math.degrees(end),
                   "source": source}
    return {"eps": eps, "eps_over_whole_arc": whole, "eps_theta_range": theta_range}


def run(case, method="both", samples=None):
    """What ``esail-opt propagate`` writes: one object per method, and eps for both."""
    if method not in METHODS:
        raise InputError(f"method = {method!r} is not one of {', '.join(METHODS)}")
    samples = samples_for(case) if samples is None else samples
    out = {
        "input": {
            "a0_au": case.a0_au, "e0": case.e0, "nu0_deg": case.nu0_deg,
            "ac_mm_s2": case.ac_mm_s2, "alpha_deg": case.alpha_deg, "years": case.years,
            "samples": samples, "b1": case.coefficients[0], "b2": case.coefficients[1],
        }
    }
    if method in ("closed-form", "both"):
        closed = closed_form(case, samples)
        out["closed_form"] = to_boundary(closed)
    if method in ("cvodes", "both"):
        out["cvodes"] = to_boundary(cvodes(case, samples))
    if method == "both":
        out.update(_eps_entries(case, closed))
    return out
