"""One fixed attitude flown from a parking orbit: the paper's closed form against CVODES.

This is the job behind ``esail-opt propagate`` and the paper's Figs. 3-4.  The
closed form is the paper's, one arc without rectification, and its end is where
its own clock reaches the horizon.  theta is measured from the parking orbit's
apse line (the paper's convention), so theta0 = nu0.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from esail_opt.errors import InputError, check_range
from esail_opt.physics import constants as units
from esail_opt.physics.elements import polar_from_classical
from esail_opt.physics.thrust import EXACT, radial_transverse
from esail_opt.propagation.rectified import rectified_function
from esail_opt.propagation.simulate import SimulationError, simulate

METHODS = ("closed-form", "cvodes", "both")
#: Beyond theta_max (q3 = 0), or where the transverse speed s of Eq. 11 reaches 0,
#: r = r0 / (q3 s) of Eq. 9 leaves (0, inf) and the clock diverges.  Near those
#: points the first-order arc is meaningless long before the divergence, so an arc
#: counts as valid only while every sample keeps r within (0, r0 / VALIDITY_FLOOR].
VALIDITY_FLOOR = 0.01


@dataclass(frozen=True)
class FixedAttitudeCase:
    """A parking orbit, a sail and a horizon, in the boundary's units.

    Attributes
    ----------
    a0 : float
        Parking orbit semimajor axis, au.
    e0 : float
        Parking orbit eccentricity, [0, 1).
    nu0 : float
        Departure true anomaly, deg.
    ac : float
        Characteristic acceleration, mm/s^2, > 0.
    alpha : float
        Pitch angle alpha_n, deg, in [-90, 90].
    years : float
        Horizon, years (365.25 days), > 0.
    """

    a0: float
    e0: float
    nu0: float
    ac: float
    alpha: float
    years: float
    coefficients: tuple = EXACT

    def __post_init__(self):
        check_range("a0", self.a0, 0, low_open=True, unit="au")
        check_range("e0", self.e0, 0, 1, high_open=True)
        check_range("nu0", self.nu0, -360, 360, unit="deg")
        check_range("ac", self.ac, 0, low_open=True, unit="mm/s^2")
        check_range("alpha", self.alpha, -90, 90, unit="deg")
        check_range("years", self.years, 0, low_open=True)

    def state0(self):
        """Departure polar state, canonical units, theta from the apse line."""
        x = polar_from_classical(self.a0, self.e0, 0.0, math.radians(self.nu0))
        return np.array(x, float).ravel()

    def thrust(self):
        return radial_transverse(math.radians(self.alpha), self.coefficients)

    def horizon(self):
        return units.time_from_years(self.years)

    def ac_canonical(self):
        return units.accel_from_mm_s2(self.ac)


def samples_for(case, minimum=200, per_revolution=32):
    """Sample count resolving the short-period oscillation: 32 per parking-orbit period."""
    period = 2 * math.pi * case.a0**1.5
    return max(minimum, int(math.ceil(per_revolution * case.horizon() / period)))


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
    x0 = np.r_[case.state0(), 0.0]
    arc = rectified_function(1, samples, "theta", case.coefficients)
    ac, alpha = case.ac_canonical(), math.radians(case.alpha)

    def run(angle):
        xs, q3 = arc(x0, ac, alpha, angle)
        return np.array(xs), float(q3)

    def valid(xs, q3):
        r, t = xs[0], xs[4]
        return (q3 > 0 and np.all(np.isfinite(xs)) and np.all(r > 0)
                and np.all(r <= x0[0] / VALIDITY_FLOOR) and np.all(np.diff(t) > 0))

    horizon = case.horizon()
    # Double the angle until the clock passes the horizon or the arc stops being valid.
    low, high = 0.0, horizon * x0[3] / x0[0]
    while True:
        xs, q3 = run(high)
        if not valid(xs, q3):
            good, bad = low, high
            while bad - good > 1e-9 * bad:
                mid = 0.5 * (good + bad)
                good, bad = (mid, bad) if valid(*run(mid)) else (good, mid)
            reach = run(good)[0][4, -1] if good > 0 else 0.0
            if reach < horizon:
                allowed = units.time_to_days(reach) / units.YEAR_DAYS
                raise InputError(
                    f"years = {case.years:g} is past theta_max: the first-order arc holds "
                    f"(q3 > 0, r within {1 / VALIDITY_FLOOR:g} r0) only up to theta - theta0 "
                    f"= {math.degrees(good):.1f} deg; allowed years in (0, {allowed:.3g})"
                )
            high = good
            break
        if xs[4, -1] >= horizon:
            break
        low, high = high, 2 * high
    angle = brentq(lambda a: run(a)[0][4, -1] - horizon, low, high, xtol=1e-13, rtol=1e-15)
    return np.column_stack([x0, run(angle)[0]])


def cvodes(case, samples):
    """Eqs. 1-2 by CVODES to the horizon, sampled at equal steps of theta.

    A first run in time finds the angle at the horizon; a second, with theta as
    the independent variable, samples it.
    """
    x0 = case.state0()
    ac, alpha = case.ac_canonical(), math.radians(case.alpha)
    end = simulate(x0, [alpha], [case.horizon()], ac, coefficients=case.coefficients)
    return cvodes_at_theta(case, end[1, -1] - x0[1], samples)


def cvodes_at_theta(case, angle, samples):
    """Eqs. 1-2 by CVODES with theta as the independent variable, ``samples`` steps."""
    return simulate(
        case.state0(), [math.radians(case.alpha)], [angle], case.ac_canonical(),
        samples=samples, independent="theta", coefficients=case.coefficients,
    )


def relative_error(case, closed):
    """Eq. 27: max over theta of |r_n - r| / r0, r_n by CVODES at the same theta.

    Returns eps and whether it covers the closed form's whole arc.  It does not
    when the true trajectory escapes before sweeping the closed form's angle (an
    escaping orbit's theta tends to a finite limit, and CVODES in theta fails):
    the maximum is then over the angles it reaches by the horizon.
    """
    samples = closed.shape[1] - 1
    span = closed[1, -1] - closed[1, 0]
    x0 = case.state0()
    end = simulate(x0, [math.radians(case.alpha)], [case.horizon()], case.ac_canonical(),
                   coefficients=case.coefficients)[:, -1]
    reached = int(samples * min(1.0, (end[1] - x0[1]) / span))
    try:
        numeric, kept = cvodes_at_theta(case, span, samples), samples
    except SimulationError:
        numeric, kept = cvodes_at_theta(case, span * reached / samples, reached), reached
    error = np.abs(numeric[0] - closed[0, : kept + 1]) / closed[0, 0]
    return float(np.max(error)), kept == samples


def to_boundary(xs):
    """Samples in the boundary's units, as the JSON and plots speak them."""
    return {
        "t_days": units.time_to_days(xs[4]).tolist(),
        "theta_deg": np.degrees(xs[1]).tolist(),
        "r_au": xs[0].tolist(),
        "vr_km_s": units.speed_to_km_s(xs[2]).tolist(),
        "vtheta_km_s": units.speed_to_km_s(xs[3]).tolist(),
    }


def run(case, method="both", samples=None):
    """What ``esail-opt propagate`` writes: one object per method, and eps for both."""
    if method not in METHODS:
        raise InputError(f"method = {method!r} is not one of {', '.join(METHODS)}")
    samples = samples_for(case) if samples is None else samples
    out = {
        "input": {
            "a0_au": case.a0, "e0": case.e0, "nu0_deg": case.nu0, "ac_mm_s2": case.ac,
            "alpha_deg": case.alpha, "years": case.years, "samples": samples,
            "b1": case.coefficients[0], "b2": case.coefficients[1],
        }
    }
    if method in ("closed-form", "both"):
        closed = closed_form(case, samples)
        out["closed_form"] = to_boundary(closed)
    if method in ("cvodes", "both"):
        out["cvodes"] = to_boundary(cvodes(case, samples))
    if method == "both":
        out["eps"], out["eps_over_whole_arc"] = relative_error(case, closed)
    return out
