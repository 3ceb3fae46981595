"""What a problem asks for: the objective it minimises and the target it must reach.

Each kind carries its own behaviour (the NLP's cost or constraints, a flown state's miss in
km and m/s, how its value reads), so callers ask it rather than test its kind; a target with
:attr:`tracks_body` counts revolution classes in whole turns on the body.  Fields (au, deg,
days) are range-checked when made; methods take canonical states (au, rad, au/TU, t in TU; mu = 1).
"""

import functools
import math
from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from esail_opt.bodies import dates, lookup
from esail_opt.errors import InputError, check_range
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_from_polar, orbital_energy

__all__ = ["MinTime", "MaxRadius", "MaxEnergy", "FinalStateExpression", "MinAcceleration",
           "CircularOrbit", "Orbit", "Rendezvous", "BodyRendezvous", "BodyIntercept",
           "OBJECTIVES", "TARGETS", "state_miss", "cartesian_miss"]


def cartesian(x):
    """Position (au) and velocity (au/TU) in the polar frame's axes, for misses."""
    r, th, vr, vt = (np.asarray(x[i], float) for i in range(4))
    c, s = np.cos(th), np.sin(th)
    return np.array([r * c, r * s]), np.array([vr * c - vt * s, vr * s + vt * c])


def state_miss(x, y):
    """Miss between two polar states: (position km, velocity m/s, polar angle deg), the
    angle unwrapped (theta_x - theta_y), so that a whole turn apart shows as 360 deg."""
    px, vx = cartesian(x)
    py, vy = cartesian(y)
    return (units.length_to_km(float(np.linalg.norm(px - py))),
            units.speed_to_m_s(float(np.linalg.norm(vx - vy))),
            math.degrees(float(x[1] - y[1])))


def cartesian_miss(y, z):
    """(position km, velocity m/s) between two canonical Cartesian states."""
    d = np.asarray(y, float).ravel()[:6] - np.asarray(z, float).ravel()[:6]
    return (units.length_to_km(float(np.linalg.norm(d[:3]))),
            units.speed_to_m_s(float(np.linalg.norm(d[3:]))))


# ---------------------------------------------------------------- objectives


@dataclass(frozen=True)
class MinTime:
    """Minimise the time of flight (the target fixes the end)."""

    fixed_time = False
    free_acceleration = False
    meaning = f"time of flight, TU (1 TU = {units.TU_DAYS:.10g} d; minimised)"

    @staticmethod
    def cost(xf, tf):
        return tf

    @staticmethod
    def shown_as():
        """(factor, unit) that turn the NLP's objective into what a user reads."""
        return units.TU_DAYS, " d"


@dataclass(frozen=True)
class _FixedTime:
    tof_days: float

    fixed_time = True
    free_acceleration = False

    def __post_init__(self):
        check_range("objective.tof_days", self.tof_days, 0, 36525, low_open=True, unit="days")

    @staticmethod
    def shown_as():
        return 1.0, ""


@dataclass(frozen=True)
class MaxRadius(_FixedTime):
    """Maximise the final solar distance after ``tof_days`` days."""

    meaning = "-(final r), au (minimised)"

    @staticmethod
    def cost(xf, tf):
        return -xf[0]


@dataclass(frozen=True)
class MaxEnergy(_FixedTime):
    """Maximise the final orbital energy v^2/2 - 1/r after ``tof_days`` days: while bound,
    the osculating semimajor axis a = -1 / (2 E) without a's pole at E = 0."""

    meaning = "-(final energy v^2/2 - 1/r), canonical (minimised)"

    @staticmethod
    def cost(xf, tf):
        return -orbital_energy(xf)


@dataclass(frozen=True)
class FinalStateExpression(_FixedTime):
    """Minimise a user expression of the final state after ``tof_days`` days.

    Attributes
    ----------
    function : callable
        ``function(x)`` of the final polar state [r, theta, v_r, v_theta] (a canonical CasADi
        column) returns a scalar CasADi expression to *minimise*, of CasADi operations for exact
        derivatives; e.g. ``lambda x: -x[0] * x[3]`` maximises the angular momentum.
    """

    function: Callable = None
    tof_days: float = 365.25

    meaning = "user expression of the final state, canonical (minimised)"

    def __post_init__(self):
        super().__post_init__()
        if not callable(self.function):
            raise InputError(f"objective.function = {self.function!r} is not callable")

    def cost(self, xf, tf):
        value = self.function(xf)
        size = value.numel() if hasattr(value, "numel") else np.size(value)
        if not isinstance(value, (ca.MX, ca.SX, ca.DM, float, int)) or size != 1:
            raise InputError("objective.function must return one scalar CasADi expression "
                             f"of the final state, not {value!r}")
        return value


# ---------------------------------------------------------------- targets


def _miss(position_km, velocity_m_s, **more):
    return {"target_miss_r_km": position_km, "target_miss_v_m_s": velocity_m_s, **more}


@dataclass(frozen=True)
class CircularOrbit:
    """End on the circular orbit of radius ``radius_au`` (r = R, v_r = 0, v_theta = sqrt(mu/R))."""

    radius_au: float

    tracks_body = False

    def __post_init__(self):
        check_range("target.radius_au", self.radius_au, 0.05, 100, unit="au")

    @property
    def aim_radius_au(self):
        return self.radius_au

    def constraints(self, xf, tf, turns, t0=0.0):
        r, _, vr, vt = xf[0], xf[1], xf[2], xf[3]
        return [r - self.radius_au, vr, vt - self.radius_au ** -0.5]

    def miss(self, x, t, t0=0.0):
        """The radial distance to the orbit, and the error from the local circular velocity."""
        r, _, vr, vt = (float(v) for v in np.ravel(x)[:4])
        dv = math.hypot(vr, vt - self.radius_au ** -0.5)
        return _miss(units.length_to_km(abs(r - self.radius_au)), units.speed_to_m_s(dv))


@dataclass(frozen=True)
class Orbit:
    """End on the orbit (a, e), anywhere and with any apse line: the constraints are the
    energy -1/(2a) and the angular momentum sqrt(a (1 - e^2)), smooth where the apse line is
    not (e = 0 included)."""

    a_au: float
    e: float

    tracks_body = False

    def __post_init__(self):
        check_range("target.a_au", self.a_au, 0.05, 100, unit="au")
        check_range("target.e", self.e, 0, 1, high_open=True)

    @property
    def aim_radius_au(self):
        return self.a_au

    def constraints(self, xf, tf, turns, t0=0.0):
        return [orbital_energy(xf) + 0.5 / self.a_au,
                xf[0] * xf[3] - math.sqrt(self.a_au * (1 - self.e ** 2))]

    def miss(self, x, t, t0=0.0):
        """Position miss max(|da|, a |de|), its parts given apart (an orbit with a free apse
        line has no unique nearest point; an error of e moves it by about a de); no
        velocity miss."""
        a, e = (float(v) for v in classical_from_polar(np.ravel(x)[:4])[:2])
        da_km = units.length_to_km(abs(a - self.a_au))
        de_km = units.length_to_km(abs(e - self.e) * self.a_au)
        return _miss(max(da_km, de_km), None, target_miss_a_km=da_km,
                     target_miss_e=abs(e - self.e))


@dataclass(frozen=True)
class Rendezvous:
    """Meet a body on a circular orbit: position and velocity.

    Attributes
    ----------
    radius_au : float
        The body's orbit radius, au.
    phase_deg : float
        The body's polar angle at departure (t = 0), deg; it moves at n = sqrt(mu / R^3).
    """

    radius_au: float
    phase_deg: float

    tracks_body = True

    def __post_init__(self):
        check_range("target.radius_au", self.radius_au, 0.05, 100, unit="au")
        check_range("target.phase_deg", self.phase_deg, -360, 360, unit="deg")

    @property
    def aim_radius_au(self):
        return self.radius_au

    def body_angle(self, t, t0=0.0):
        """The body's unwrapped polar angle t TU after departure, rad: phase0 + n t (t0
        plays no part)."""
        return math.radians(self.phase_deg) + t * self.radius_au ** -1.5

    def turns_behind(self, theta, t, t0=0.0):
        """Whole turns k between the sail at polar angle theta and the body at time t: the
        next whole turn ahead of the lag, since the sail, from a faster inner orbit, can
        only gain angle by waiting."""
        return int(math.ceil((theta - self.body_angle(t)) / (2 * math.pi)))

    def constraints(self, xf, tf, turns, t0=0.0):
        # The turn count is fixed from the guess: matching the angle mod 2 pi by (cos, sin)
        # pairs would give two parallel constraint gradients.
        r, th, vr, vt = xf[0], xf[1], xf[2], xf[3]
        return [r - self.radius_au, th - self.body_angle(tf) - 2 * math.pi * turns, vr,
                vt - self.radius_au ** -0.5]

    def miss(self, x, t, t0=0.0):
        """The distance and the relative speed to the body at time t."""
        body = [self.radius_au, self.body_angle(t), 0.0, self.radius_au ** -0.5]
        dr, dv, _ = state_miss(np.ravel(x)[:4], body)
        return _miss(dr, dv)


@dataclass(frozen=True)
class MinAcceleration(_FixedTime):
    """The smallest characteristic acceleration that makes the transfer in ``tof_days``.

    The sail's ``ac_mm_s2`` then only seeds and scales a_c, a decision variable, and every
    segment's throttle kappa is free in the sail's throttle bounds ([0, 1] unless
    ``Sail(throttle=True)`` narrows them), so arcs needing less than full thrust do not cost
    a_c.  Meant for fixed departure and arrival dates (a porkchop).
    """

    free_acceleration = True
    meaning = (f"characteristic acceleration a_c, canonical (1 = {units.ACC_UNIT_MM_S2:.10g} "
               "mm/s^2; minimised)")

    @staticmethod
    def cost(xf, tf):
        raise TypeError("MinAcceleration's cost is the a_c variable of the NLP")

    @staticmethod
    def shown_as():
        return units.ACC_UNIT_MM_S2, " mm/s^2"


# ---------------------------------------------------------------- bodies on real orbits


def _check_arrival_window(window):
    """The arrival window as a pair of Julian dates (TDB), or None."""
    if window is None:
        return None
    if not isinstance(window, (tuple, list)) or len(window) != 2:
        raise InputError(f"target.arrival_window = {window!r} is not a pair (earliest, latest) "
                         "of ISO 8601 dates")
    # In the tracked span: the NLP sees the body through its track, which ends there.
    lo, hi = (lookup.check_span(dates.jd_from_iso(day, f"target.arrival_window[{i}]"),
                                f"target.arrival_window[{i}]") for i, day in enumerate(window))
    if hi < lo:
        raise InputError(f"target.arrival_window = {tuple(window)!r}: its end comes before its "
                         "start")
    return lo, hi


@dataclass(frozen=True)
class _BodyTarget:
    """A body on its real orbit at the arrival date: a DE421 planet or a small body.

    Attributes
    ----------
    body : str or SmallBody
        A planet name (``bodies.ephemeris.PLANETS``) or a :class:`~esail_opt.bodies.SmallBody`.
    arrival_window : (str, str) or None
        Earliest and latest arrival, ISO 8601 dates (TDB) in the tracked span 2000-2060,
        ending after the earliest departure; None leaves the arrival free.

    The NLP sees the body through a smooth fit of its ephemeris (``bodies.track``); the
    verification holds the flight to the ephemeris itself, so the fit's error is verified.
    """

    body: object
    arrival_window: tuple = None

    tracks_body = True
    matches_velocity = True

    def __post_init__(self):
        lookup.check_body(self.body, "target.body")
        _check_arrival_window(self.arrival_window)

    @property
    def aim_radius_au(self):
        return lookup.mean_radius_au(self.body)

    @property
    def arrival_jd(self):
        """(earliest, latest) arrival as Julian dates (TDB), or None."""
        return _check_arrival_window(self.arrival_window)

    def body_state(self, t0, t):
        """The body's smooth polar state (theta unwrapped) at departure epoch t0 plus t
        (TU; numbers or CasADi symbols)."""
        return lookup.track(self.body).polar(t0 + t)

    def body_angle(self, t, t0=0.0):
        return float(np.ravel(self.body_state(t0, t))[1])

    def turns_behind(self, theta, t, t0=0.0):
        """:meth:`Rendezvous.turns_behind` for the body at t0 + t."""
        return int(math.ceil((theta - self.body_angle(t, t0)) / (2 * math.pi)))

    def constraints(self, xf, tf, turns, t0=0.0):
        body = self.body_state(t0, tf)
        rows = [xf[0] - body[0], xf[1] - body[1] - 2 * math.pi * turns]
        if self.matches_velocity:
            rows += [xf[2] - body[2], xf[3] - body[3]]
        return rows

    def miss(self, x, t, t0=0.0):
        """Distance (and, for a rendezvous, relative speed) to the body's ephemeris state
        at t0 + t, with the encounter speed and the out-of-plane distance the plane ignores."""
        state, z_au = lookup.polar_state_at(self.body, t0 + t, "target.body")
        dr, dv, _ = state_miss(np.ravel(x)[:4], state)
        return _miss(dr, dv if self.matches_velocity else None,
                     relative_speed_km_s=dv / 1e3,
                     out_of_plane_km=units.length_to_km(abs(z_au)))


    def cylindrical_constraints(self, yf, theta_f, tf, turns, t0=0.0):
        """A 3-D body target's rows: the sail's final Cartesian state ``yf`` less the body's on its
        smooth 3-D track at t0 + tf, in the ecliptic's cylindrical coordinates
        [rho, lambda - 2 pi turns, z] (and, for a rendezvous, [v_rho, v_lambda, v_z]), the sail's
        longitude unwrapped near ``theta_f``.  Like the planar theta row, it pulls the final angle
        towards its turn, where periodic Cartesian rows have local optima half a turn off."""
        body = lookup.track3(self.body).cylindrical(t0 + tf)
        sail = _cylindrical()(yf, theta_f)
        rows = [sail[0] - body[0], sail[1] - body[1] - 2 * math.pi * turns,
                sail[2] - body[4]]
        if self.matches_velocity:
            rows += [sail[3] - body[2], sail[4] - body[3], sail[5] - body[5]]
        return [ca.vertcat(*rows)]

    def miss3d(self, y, t, t0=0.0):
        """:meth:`miss` of the Cartesian state ``y`` against the body's exact, unprojected
        ecliptic state, with the part of the distance along the ecliptic's normal."""
        body = lookup.ecliptic_state_at(self.body, t0 + t, "target.body")
        dr, dv = cartesian_miss(y, body)
        return _miss(dr, dv if self.matches_velocity else None,
                     relative_speed_km_s=dv / 1e3,
                     out_of_plane_km=units.length_to_km(abs(float(body[2]))),
                     normal_miss_km=units.length_to_km(abs(float(np.ravel(y)[2] - body[2]))))


@functools.lru_cache(maxsize=None)
def _cylindrical():
    """``(y[6], near) -> [rho, lambda, z, v_rho, v_lambda, v_z]`` of the ecliptic state
    y, the longitude within half a turn of ``near``; SX, a small block of derivatives."""
    y, near = ca.SX.sym("y", 6), ca.SX.sym("near")
    c, s = ca.cos(near), ca.sin(near)
    lon = near + ca.atan2(c * y[1] - s * y[0], c * y[0] + s * y[1])
    rho = ca.sqrt(y[0] ** 2 + y[1] ** 2)
    return ca.Function("cylindrical", [y, near],
                       [ca.vertcat(rho, lon, y[2], (y[0] * y[3] + y[1] * y[4]) / rho,
                                   (y[0] * y[4] - y[1] * y[3]) / rho, y[5])])


@dataclass(frozen=True)
class BodyRendezvous(_BodyTarget):
    """Meet a body on its real orbit: its position and velocity at arrival."""


@dataclass(frozen=True)
class BodyIntercept(_BodyTarget):
    """Reach a body's position on its real orbit, at any relative speed (a fly-by or a
    kinetic impactor); the relative speed at encounter is reported."""

    matches_velocity = False


OBJECTIVES = (MinTime, MaxRadius, MaxEnergy, FinalStateExpression, MinAcceleration)
TARGETS = (CircularOrbit, Orbit, Rendezvous, BodyRendezvous, BodyIntercept)
