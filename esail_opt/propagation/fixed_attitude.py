"""One fixed attitude flown from a parking orbit: the paper's closed form (one arc, no
rectification) against CVODES, over the horizon.

The paper's Figs. 3-4 measure Eq. 27 over the angle CVODES sweeps in the horizon
(:func:`eps_over_swept_angle`, :func:`eps_over_swept_angles`).  theta is measured from the
parking orbit's apse line, as in the paper, so theta0 = nu0.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from esail_opt.errors import InputError, check_range
from esail_opt.physics import constants as units
from esail_opt.physics.elements import polar_from_classical
from esail_opt.physics.thrust import EXACT
from esail_opt.propagation.arcs import FIRST_ORDER
from esail_opt.propagation.batch import arcs_at_angles
from esail_opt.propagation.rectified import rectified_function
from esail_opt.propagation.simulate import SimulationError, simulate

#: The first-order arc is meaningless well before r = r0 / (q3 s) of Eq. 9 diverges
#: (q3 = 0 or s = 0), so it counts as valid only while every sample keeps r within
#: (0, r0 / VALIDITY_FLOOR].
VALIDITY_FLOOR = 0.01
#: Samples per revolution: enough to resolve the short-period oscillation of r.
PER_REVOLUTION = 32
MIN_SAMPLES = 200


@dataclass(frozen=True)
class FixedAttitudeCase:
    """A parking orbit, a sail and a horizon, in the boundary's units: ``a0_au``, the
    parking orbit's semimajor axis (au, > 0); ``e0``, its eccentricity, in [0, 1);
    ``nu0_deg``, the departure true anomaly (deg, in [-360, 360]); ``ac_mm_s2``, the
    characteristic acceleration (mm/s^2, > 0); ``alpha_deg``, the pitch alpha_n (deg, in
    [-90, 90]); ``years``, the horizon (years of 365.25 days, > 0); ``coefficients``, the
    (b1, b2) of Eqs. 3-4.
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
    """Samples over the horizon: ``per_revolution`` per parking-orbit period, at least
    ``minimum``."""
    period = 2 * math.pi * case.a0_au**1.5
    return max(minimum, int(math.ceil(per_revolution * case.horizon / period)))


def samples_over(span, minimum=MIN_SAMPLES, per_revolution=PER_REVOLUTION):
    """Samples over ``span`` rad of theta, as :func:`samples_for`."""
    return max(minimum, int(math.ceil(per_revolution * span / (2 * math.pi))))


def _arc(case, samples):
    """``run(angle) -> (xs, q3)``: the closed form's one arc over ``angle`` rad of theta,
    xs of shape (5, samples + 1) from the departure, canonical units."""
    x0 = np.r_[case.state0(), 0.0]
    arc = rectified_function(1, samples=samples, coefficients=case.coefficients,
                             model=FIRST_ORDER)
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


def _validity_limit(case, good, bad):
    """The largest valid angle between ``good`` (valid) and ``bad`` (not), by bisection, and
    the arc's time there.  Each angle is sampled as :func:`samples_over` asks, rounded up to
    a power of two so that a few arcs serve the whole search: the horizon's samples would
    make each step of a long horizon's search cost as much as the whole horizon."""
    runs = {}

    def run(angle):
        count = 1 << (samples_over(angle) - 1).bit_length()
        if count not in runs:
            runs[count] = _arc(case, count)
        return runs[count](angle)

    while bad - good > 1e-9 * bad:
        mid = 0.5 * (good + bad)
        good, bad = (mid, bad) if _valid(*run(mid)) else (good, mid)
    return good, (run(good)[0][4, -1] if good > 0 else 0.0)


def _horizon_bracket(case, run):
    """Angles (low, high) whose closed-form clock straddles the horizon, by doubling;
    InputError if the arc stops holding before its clock reaches the horizon."""
    horizon = case.horizon
    x0 = case.state0()
    low, high = 0.0, horizon * x0[3] / x0[0]
    while True:
        xs, q3 = run(high)
        if not _valid(xs, q3):
            good, reach = _validity_limit(case, low, high)
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
    """The paper's single first-order arc to where its own clock reaches the horizon,
    [r, theta, v_r, v_theta, t] (canonical) at ``samples`` equal steps of theta, shape
    (5, samples + 1); InputError if the horizon lies past the arc's validity
    (:data:`VALIDITY_FLOOR`)."""
    run = _arc(case, samples)
    horizon = case.horizon
    low, high = _horizon_bracket(case, run)
    angle = brentq(lambda a: run(a)[0][4, -1] - horizon, low, high, xtol=1e-13, rtol=1e-15)
    return run(angle)[0]


def swept_angle(case):
    """theta - theta0 (rad) that CVODES on Eqs. 1-2 reaches at the horizon."""
    x0 = case.state0()
    end = simulate(x0, [case.alpha], [case.horizon], case.ac,
                   coefficients=case.coefficients)
    return float(end[1, -1] - x0[1])


def cvodes_at_theta(case, angle, samples):
    """Eqs. 1-2 by CVODES with theta as the independent variable, ``samples`` steps."""
    return simulate(
        case.state0(), [case.alpha], [angle], case.ac,
        samples=samples, length_in="theta", coefficients=case.coefficients,
    )


def relative_error(case, closed):
    """Eq. 27 over the closed form's own arc: max of |r_n - r| / r0 at its angles, r_n
    CVODES at the same theta.  Returns eps, whether it covers the whole arc, and the last
    angle it covers (rad): an orbit that escapes short of the arc's span (its theta tends
    to a finite limit) is compared over the angles it reaches by the horizon.
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


@dataclass(frozen=True)
class SweptEps:
    """Eq. 27 of one case over the angle CVODES sweeps in the horizon: ``eps``, the max
    over theta of |r_n - r| / r0 (NaN with ``error``); ``span``, the swept angle, rad;
    ``closed`` and ``numeric``, the closed form (t on its own clock) and CVODES in theta,
    [r, theta, v_r, v_theta, t] at the same steps of theta; ``error``, the InputError
    saying why the closed form does not hold over the span, if it does not.
    """

    eps: float
    span: float
    closed: np.ndarray = None
    numeric: np.ndarray = None
    error: InputError = None


def eps_over_swept_angles(cases, samples=None):
    """Eq. 27 as the paper's Figs. 3-4 measure it, for many ``cases`` at once (all with
    the same thrust coefficients).

    Per case, the angle CVODES sweeps in the horizon bounds the comparison, the closed
    form and CVODES in theta sampled at the same ``samples`` equal steps of theta up to
    there (default :func:`samples_over` the span); the closed forms are one batched call.
    Returns one :class:`SweptEps` per case, in order; a case whose closed form does not
    hold over its span carries the InputError and no eps.
    """
    cases = list(cases)
    if len({c.coefficients for c in cases}) > 1:
        raise ValueError("the cases of one batch share their thrust coefficients")
    spans = [swept_angle(c) for c in cases]
    counts = [samples_over(span) if samples is None else samples for span in spans]
    # The angles arc_function would take for equal steps, to the last bit.
    angles = [span * (np.arange(n + 1) / n) for span, n in zip(spans, counts)]
    arcs = arcs_at_angles([c.state0() for c in cases], [c.ac for c in cases],
                          [c.alpha for c in cases], angles,
                          coefficients=cases[0].coefficients)
    out = []
    for case, span, n, (closed, q3) in zip(cases, spans, counts, arcs):
        if not _valid(closed, q3[-1]):
            out.append(SweptEps(math.nan, span, error=InputError(
                f"the first-order arc does not hold (q3 > 0, r within {1 / VALIDITY_FLOOR:g} "
                f"r0) over theta - theta0 = {math.degrees(span):.1f} deg")))
            continue
        numeric = cvodes_at_theta(case, span, n)
        eps = float(np.max(np.abs(numeric[0] - closed[0])) / closed[0, 0])
        out.append(SweptEps(eps, span, closed, numeric))
    return out


def eps_over_swept_angle(case, samples=None):
    """:func:`eps_over_swept_angles` for one case: ``(eps, span)``, eps the max over theta
    of |r_n - r| / r0 and span the swept angle, rad; InputError if the closed form does
    not hold over it."""
    (result,) = eps_over_swept_angles([case], samples)
    if result.error is not None:
        raise result.error
    return result.eps, result.span
