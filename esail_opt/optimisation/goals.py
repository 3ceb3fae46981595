"""What a problem asks for: the objective it minimises and the target it must reach.

Each kind carries its own behaviour, so the transcription, the verification and the
solution files ask it instead of testing which kind it is:

* an objective gives the NLP's cost (:meth:`cost`), says whether it fixes the time of
  flight, and how its value reads to a user (:attr:`meaning`, :meth:`shown_as`);
* a target gives the NLP's equality constraints on the final state (:meth:`constraints`),
  the miss of a flown state from it in km and m/s (:meth:`miss`), the radius the
  seeding propagation aims at (:attr:`aim_radius_au`), and whether its final polar
  angle is tied to a moving body (:attr:`tracks_body`: revolution classes are then
  whole turns on the body, not windows of the final angle).

All fields are in the boundary's units (au, deg, days) and range-checked on creation;
states handed to the methods are canonical (au, rad, au/TU with mu = 1; time in TU).
"""

import math
from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from esail_opt.errors import InputError, check_range
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_from_polar, orbital_energy

__all__ = ["MinTime", "MaxRadius", "MaxEnergy", "FinalStateExpression", "CircularOrbit",
           "Orbit", "Rendezvous", "OBJECTIVES", "TARGETS", "state_miss"]


def cartesian(x):
    """Position (au) and velocity (au/TU) in the polar frame's axes, for misses."""
    r, th, vr, vt = (np.asarray(x[i], float) for i in range(4))
    c, s = np.cos(th), np.sin(th)
    return np.array([r * c, r * s]), np.array([vr * c - vt * s, vr * s + vt * c])


def state_miss(x, y):
    """Miss between two polar states: (position km, velocity m/s, polar angle deg).

    The angle is the unwrapped difference theta_x - theta_y, so a whole revolution of
    disagreement shows as 360 deg instead of vanishing.
    """
    px, vx = cartesian(x)
    py, vy = cartesian(y)
    return (units.length_to_km(float(np.linalg.norm(px - py))),
            units.speed_to_m_s(float(np.linalg.norm(vx - vy))),
            math.degrees(float(x[1] - y[1])))


# ---------------------------------------------------------------- objectives


@dataclass(frozen=True)
class MinTime:
    """Minimise the time of flight (the target fixes the end)."""

    fixed_time = False
    meaning = "time of flight, TU (minimised)"

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
    """Maximise the final orbital energy v^2/2 - 1/r after ``tof_days`` days.

    While the orbit stays bound, this is the same as maximising the final osculating
    semimajor axis a = -1 / (2 E), without a's pole at E = 0.
    """

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
        ``function(x)`` with ``x`` the final polar state [r, theta, v_r, v_theta] as a
        CasADi column (canonical units: au, rad, au/TU with mu = 1) returns a scalar
        CasADi expression to *minimise*.  Use CasADi operations (``casadi.sqrt``,
        ``casadi.cos``, ...) so that Ipopt gets exact derivatives; e.g. maximising the
        angular momentum is ``lambda x: -x[0] * x[3]``.
    tof_days : float
        Fixed time of flight, days.
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

    def constraints(self, xf, tf, turns):
        r, _, vr, vt = xf[0], xf[1], xf[2], xf[3]
        return [r - self.radius_au, vr, vt - self.radius_au ** -0.5]

    def miss(self, x, t):
        """The radial distance to the orbit, and the velocity error against the local
        circular velocity."""
        r, _, vr, vt = (float(v) for v in np.ravel(x)[:4])
        dv = math.hypot(vr, vt - self.radius_au ** -0.5)
        return _miss(units.length_to_km(abs(r - self.radius_au)), units.speed_to_m_s(dv))


@dataclass(frozen=True)
class Orbit:
    """End on the orbit (a, e), anywhere and with any apse line.

    The constraints are the energy -1/(2a) and the angular momentum sqrt(a (1 - e^2)),
    which are smooth where the apse line is not (e = 0 included).
    """

    a_au: float
    e: float

    tracks_body = False

    def __post_init__(self):
        check_range("target.a_au", self.a_au, 0.05, 100, unit="au")
        check_range("target.e", self.e, 0, 1, high_open=True)

    @property
    def aim_radius_au(self):
        return self.a_au

    def constraints(self, xf, tf, turns):
        return [orbital_energy(xf) + 0.5 / self.a_au,
                xf[0] * xf[3] - math.sqrt(self.a_au * (1 - self.e ** 2))]

    def miss(self, x, t):
        """A position on an orbit whose apse line is free has no unique nearest point, so
        the position miss is max(|da|, a |de|) (an error of e moves the orbit by about
        a de), with the two parts given apart; there is no velocity miss."""
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
        The body's polar angle at departure (t = 0), deg; it moves at the mean
        motion n = sqrt(mu / R^3).
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

    def body_angle(self, t):
        """The body's polar angle at time t (TU), rad, unwrapped: phase0 + n t."""
        return math.radians(self.phase_deg) + t * self.radius_au ** -1.5

    def turns_behind(self, theta, t):
        """Whole turns k between the sail at polar angle theta and the body at time t.

        The sail arrives from an inner (faster) orbit, so it can gain angle on the body
        by waiting, not lose it: the next whole turn ahead of the lag."""
        return int(math.ceil((theta - self.body_angle(t)) / (2 * math.pi)))

    def constraints(self, xf, tf, turns):
        # The turn count is fixed from the guess: matching the angle mod 2 pi by (cos, sin)
        # pairs would give two parallel constraint gradients.
        r, th, vr, vt = xf[0], xf[1], xf[2], xf[3]
        return [r - self.radius_au, th - self.body_angle(tf) - 2 * math.pi * turns, vr,
                vt - self.radius_au ** -0.5]

    def miss(self, x, t):
        """The distance and the relative speed to the body at time t."""
        body = [self.radius_au, self.body_angle(t), 0.0, self.radius_au ** -0.5]
        dr, dv, _ = state_miss(np.ravel(x)[:4], body)
        return _miss(dr, dv)


OBJECTIVES = (MinTime, MaxRadius, MaxEnergy, FinalStateExpression)
TARGETS = (CircularOrbit, Orbit, Rendezvous)
