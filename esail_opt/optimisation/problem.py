"""A trajectory optimisation problem, stated in the boundary's units and checked on creation.

A problem file (as in ``problems/``) builds one :class:`Problem` named ``problem``: plain
data in au, days, degrees, km/s and mm/s^2, every field range-checked when built (an
``InputError`` names the field and range).  Its methods convert to canonical units.
"""

import math
from dataclasses import dataclass, field
from typing import Optional, Union

import casadi as ca
import numpy as np

from esail_opt.bodies import dates, lookup
from esail_opt.errors import InputError, check_printable, check_range
from esail_opt.optimisation.goals import (
    OBJECTIVES, TARGETS, BodyIntercept, BodyRendezvous, CircularOrbit, FinalStateExpression,
    MaxEnergy, MaxRadius, MinAcceleration, MinTime, Orbit, Rendezvous,
)
from esail_opt.physics import constants as units
from esail_opt.physics.elements import (cartesian_from_polar3d, orbital_energy,
                                        polar3d_from_cartesian, polar_from_classical)
from esail_opt.physics.thrust import BEST_FIT, EXACT
from esail_opt.propagation.arcs import ArcModel

__all__ = [
    "ParkingOrbit", "PolarState", "BodyDeparture", "Sail", "Segments", "MinTime", "MaxRadius",
    "MaxEnergy", "FinalStateExpression", "MinAcceleration", "CircularOrbit", "Orbit",
    "Rendezvous", "BodyRendezvous", "BodyIntercept", "PathConstraints", "Tolerance",
    "Problem", "EXACT", "BEST_FIT",
]


#: What a problem's name may hold, as its refusal says: it names the output folder.
NAME_ALLOWED = ("printable characters without '/' or '\\' (the problem name is its "
                "output folder's name)")


def _check_bool(name, value):
    # A string would be truthy whatever it says ("no", "False").
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name} = {value!r} is not True or False")


def _check_finite_positive_int(name, value, low=1):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} = {value!r} is not an integer in [{low}, inf)")
    if value < low:
        raise InputError(f"{name} = {value!r} is outside [{low}, inf)")
    return int(value)


# ---------------------------------------------------------------- departure


@dataclass(frozen=True)
class ParkingOrbit:
    """Depart from a Keplerian parking orbit.

    Attributes
    ----------
    a_au : float
        Semimajor axis, au, > 0.
    e : float
        Eccentricity, [0, 1).
    omega_deg : float
        Argument of perihelion from the polar frame's x axis, deg, [-360, 360].
    nu_deg : float
        Departure true anomaly, deg, [-360, 360]; the initial value if ``free_anomaly``.
    free_anomaly : bool
        Let the optimiser choose where on the parking orbit to leave.
    """

    a_au: float
    e: float = 0.0
    omega_deg: float = 0.0
    nu_deg: float = 0.0
    free_anomaly: bool = False

    def __post_init__(self):
        check_range("departure.a_au", self.a_au, 0, low_open=True, unit="au")
        check_range("departure.e", self.e, 0, 1, high_open=True)
        check_range("departure.omega_deg", self.omega_deg, -360, 360, unit="deg")
        check_range("departure.nu_deg", self.nu_deg, -360, 360, unit="deg")
        _check_bool("departure.free_anomaly", self.free_anomaly)

    def state(self, nu=None):
        """Canonical polar state at true anomaly ``nu`` (rad, a float or CasADi symbol;
        default the stated one)."""
        nu = math.radians(self.nu_deg) if nu is None else nu
        return polar_from_classical(self.a_au, self.e, math.radians(self.omega_deg), nu)


@dataclass(frozen=True)
class PolarState:
    """Depart from an explicit polar state.

    Attributes
    ----------
    r_au : float
        Solar distance, au, > 0.
    theta_deg : float
        Polar angle, deg, [-360, 360].
    vr_km_s, vtheta_km_s : float
        Radial and transverse velocity, km/s; the orbit must be bound (e < 1) and
        prograde (vtheta > 0), as the closed form requires.
    """

    r_au: float
    theta_deg: float
    vr_km_s: float
    vtheta_km_s: float
    free_anomaly: bool = field(default=False, init=False)

    def __post_init__(self):
        check_range("departure.r_au", self.r_au, 0, low_open=True, unit="au")
        check_range("departure.theta_deg", self.theta_deg, -360, 360, unit="deg")
        check_range("departure.vr_km_s", self.vr_km_s, unit="km/s")
        check_range("departure.vtheta_km_s", self.vtheta_km_s, 0, low_open=True, unit="km/s")
        x = self.state()
        if orbital_energy(x) >= 0:
            v_esc = units.speed_to_km_s(math.sqrt(2 / x[0]))
            raise InputError(f"departure speed = {units.speed_to_km_s(math.hypot(x[2], x[3])):.4g} "
                             f"km/s is outside [0, {v_esc:.4g}) km/s (the escape speed: e < 1)")

    def state(self, nu=None):
        """Canonical polar state (``nu`` is ignored: there is no orbit to slide along)."""
        return np.array([self.r_au, math.radians(self.theta_deg),
                         units.speed_from_km_s(self.vr_km_s),
                         units.speed_from_km_s(self.vtheta_km_s)])


@dataclass(frozen=True)
class BodyDeparture:
    """Depart from a body on its real orbit: a DE421 planet or a small body.

    Attributes
    ----------
    body : str or SmallBody
        A planet name (``esail_opt.bodies.ephemeris.PLANETS``; "earth" is the Earth-Moon
        barycentre, see ``bodies.ephemeris``) or a :class:`~esail_opt.bodies.SmallBody`.
    date : str or None
        Departure date, ISO 8601 (read as TDB), in the tracked span 2000-2060.  Give
        it or ``window``, not both.
    window : (str, str) or None
        Earliest and latest departure, ISO 8601 (TDB), in the same span: the date
        becomes a decision variable of the NLP inside it, seeded by a coarse scan of
        the window.
    vinf_km_s : float
        Hyperbolic excess speed from the launcher, km/s, in [0, 10]; 0 (the default)
        leaves on the body's own orbit.
    vinf_angle_deg : float or None
        Direction of the excess velocity in the orbit plane, deg in [-180, 180], from
        the local horizontal (prograde) towards the radial outward direction; None
        leaves it free to the optimiser.
    """

    body: object
    date: Optional[str] = None
    window: Optional[tuple] = None
    vinf_km_s: float = 0.0
    vinf_angle_deg: Optional[float] = None

    free_anomaly = False

    def __post_init__(self):
        lookup.check_body(self.body, "departure.body")
        if self.date is None and self.window is None:
            raise InputError("departure.date = None: give a date (ISO 8601, e.g. "
                             "'2031-06-01') or a window (earliest, latest)")
        if self.date is not None and self.window is not None:
            # A date given with a window would be silently ignored.
            raise InputError(f"departure.date = {self.date!r} and departure.window = "
                             f"{self.window!r}: give one of them, not both (a window "
                             "frees the date; a date fixes it)")
        if self.date is not None:
            lookup.check_span(dates.jd_from_iso(self.date, "departure.date"), "departure.date")
        if self.window is not None:
            if not isinstance(self.window, (tuple, list)) or len(self.window) != 2:
                raise InputError(f"departure.window = {self.window!r} is not a pair "
                                 "(earliest, latest) of ISO 8601 dates")
            lo, hi = self.window_jd
            if hi < lo:
                raise InputError(f"departure.window = {tuple(self.window)!r}: its end comes "
                                 "before its start")
        check_range("departure.vinf_km_s", self.vinf_km_s, 0, 10, unit="km/s")
        if self.vinf_angle_deg is not None:
            check_range("departure.vinf_angle_deg", self.vinf_angle_deg, -180, 180, unit="deg")

    @property
    def window_jd(self):
        """(earliest, latest) departure as Julian dates (TDB), or None for a fixed date."""
        if self.window is None:
            return None
        return tuple(lookup.check_span(dates.jd_from_iso(w, f"departure.window[{i}]"),
                                       f"departure.window[{i}]")
                     for i, w in enumerate(self.window))

    @property
    def free_date(self):
        return self.window is not None

    @property
    def free_direction(self):
        """Whether the NLP chooses the excess velocity's direction."""
        return self.vinf_km_s > 0 and self.vinf_angle_deg is None

    def epoch_jd(self):
        """The departure date (or the free date's seed) as a Julian date, TDB; a window
        seeds at its start (``optimisation.pipeline`` scans it first)."""
        return dates.jd_from_iso(self.date if self.date is not None else self.window[0])

    def epoch(self):
        """The departure date (or seed) as canonical time since J2000 TDB, TU."""
        return dates.tu_from_jd(self.epoch_jd())

    def _excess(self, angle):
        v = units.speed_from_km_s(self.vinf_km_s)
        return v * ca.sin(angle), v * ca.cos(angle)

    def seed_angle(self):
        """The excess velocity's direction as given, else 0 (along the local horizontal)."""
        return 0.0 if self.vinf_angle_deg is None else math.radians(self.vinf_angle_deg)

    def state_at(self, t0, angle=None):
        """Exact polar state (ephemeris, canonical) at epoch t0 (TU since J2000) with the
        excess velocity at ``angle`` (rad; default :meth:`seed_angle`)."""
        x, _ = lookup.polar_state_at(self.body, t0, "departure.body")
        dvr, dvt = self._excess(self.seed_angle() if angle is None else angle)
        return x + np.array([0.0, 0.0, float(dvr), float(dvt)])

    def state(self, nu=None):
        """Exact canonical polar state at the departure date (``nu`` is ignored)."""
        return self.state_at(self.epoch())

    def nlp_state(self, t0, angle):
        """The departure state inside the NLP: the body's smooth track at epoch ``t0``
        (TU since J2000, number or symbol) plus the excess velocity at ``angle``."""
        x = lookup.track(self.body).polar(t0)
        dvr, dvt = self._excess(angle)
        return ca.vertcat(x[0], x[1], x[2] + dvr, x[3] + dvt)

    def plane_state(self, y, angle, t0):
        """The 3-D departure as the NLP's start, [r, theta, v_r, v_theta, qw, qx, qy, qz]
        (numbers or CasADi expressions): the polar state inside the plane of the body's
        ecliptic state ``y`` (``elements.polar3d_from_cartesian``) plus the excess velocity
        at ``angle`` in that plane, and the plane's quaternion.  theta is put on the branch
        of the body's planar track at epoch ``t0``, so that it is continuous in the epoch
        and a rendezvous counts its turns as the planar model does."""
        x, quat = polar3d_from_cartesian(y)
        ref = lookup.track(self.body).polar(t0)[1]
        turns = ca.floor((ref - x[1]) / (2 * math.pi) + 0.5)
        dvr, dvt = self._excess(angle)
        return ca.vertcat(x[0], x[1] + 2 * math.pi * turns, x[2] + dvr, x[3] + dvt, quat)

    def plane_state_at(self, t0, angle=None):
        """:meth:`plane_state` of the body's exact ecliptic state (DE421 unprojected, or a
        small body's six elements) at epoch t0 (TU since J2000), as numbers."""
        y = lookup.ecliptic_state_at(self.body, t0, "departure.body")
        angle = self.seed_angle() if angle is None else angle
        return np.array(self.plane_state(ca.DM(y), angle, t0), float).ravel()

    def cartesian_at(self, t0, angle=None):
        """The exact 3-D departure [x, y, z, vx, vy, vz] (ecliptic of J2000, canonical) at
        epoch t0 with the excess velocity at ``angle``: what a 3-D schedule is flown from."""
        x = self.plane_state_at(t0, angle)
        return np.array(cartesian_from_polar3d(x[:4], x[4:]), float).ravel()

    def nlp_plane_state(self, t0, angle, correction=0):
        """:meth:`plane_state` inside the NLP: on the body's smooth 3-D track at epoch
        ``t0`` (number or symbol) plus ``correction`` (Cartesian, 6)."""
        return self.plane_state(lookup.track3(self.body).function(t0) + correction, angle, t0)


# ---------------------------------------------------------------- sail and arcs


@dataclass(frozen=True)
class Sail:
    """The E-sail: characteristic acceleration at 1 au, thrust model, pitch bounds.

    Attributes
    ----------
    ac_mm_s2 : float
        Characteristic acceleration at r_E = 1 au, mm/s^2, in (0, 100].
    coefficients : tuple of float
        (b1, b2) of Eqs. 3-4: ``EXACT`` (3/4, 1/4) or ``BEST_FIT``.
    alpha_min_deg, alpha_max_deg : float
        Pitch bounds, deg, a subset of [-90, 90] with min <= max.
    throttle : bool
        Make each segment's throttle kappa a decision variable: the tether voltage scales
        the thrust, so the segment flies at kappa a_c (kappa = 0 is a coast).  Off by
        default: the sail is always fully on.  Prefer ``Segments(equal=True)`` with it:
        free lengths let adjacent coasts trade duration, a flat direction on which the
        exact polish can stall.
    throttle_min, throttle_max : float
        Bounds on kappa, a subset of [0, 1] with min <= max (used only with
        ``throttle``); equal bounds fix kappa, e.g. 1 reproduces the always-on NLP.
    clock_min_deg, clock_max_deg : float
        Bounds on the clock angle delta of a problem flown in three dimensions, deg, a
        subset of [-180, 180] with min <= max: the sail's normal turned by delta about
        the Sun-sail line (0: in the orbital plane, on the side of the motion; positive
        toward the angular momentum; ``physics.thrust.radial_transverse_normal``).  The
        full circle (the default) leaves delta free, any number of turns apart
        (``Problem.clock_bounds``); a planar problem has no clock angle.
    """

    ac_mm_s2: float
    coefficients: tuple = EXACT
    alpha_min_deg: float = -90.0
    alpha_max_deg: float = 90.0
    throttle: bool = False
    throttle_min: float = 0.0
    throttle_max: float = 1.0
    clock_min_deg: float = -180.0
    clock_max_deg: float = 180.0

    def __post_init__(self):
        check_range("sail.ac_mm_s2", self.ac_mm_s2, 0, 100, low_open=True, unit="mm/s^2")
        if len(self.coefficients) != 2:
            raise InputError(f"sail.coefficients = {self.coefficients!r} is not a pair (b1, b2)")
        b1 = check_range("sail.coefficients[0] (b1)", self.coefficients[0], 0, 1, low_open=True)
        check_range("sail.coefficients[1] (b2)", self.coefficients[1], 0, b1)
        lo = check_range("sail.alpha_min_deg", self.alpha_min_deg, -90, 90, unit="deg")
        check_range("sail.alpha_max_deg", self.alpha_max_deg, lo, 90, unit="deg")
        _check_bool("sail.throttle", self.throttle)
        k_lo = check_range("sail.throttle_min", self.throttle_min, 0, 1)
        check_range("sail.throttle_max", self.throttle_max, k_lo, 1)
        c_lo = check_range("sail.clock_min_deg", self.clock_min_deg, -180, 180, unit="deg")
        check_range("sail.clock_max_deg", self.clock_max_deg, c_lo, 180, unit="deg")

    @property
    def ac(self):
        """Characteristic acceleration in canonical units (mu / au^2)."""
        return units.accel_from_mm_s2(self.ac_mm_s2)


@dataclass(frozen=True)
class Segments:
    """Control segments: N pieces of constant pitch, each made of closed-form sub-arcs.

    Attributes
    ----------
    count : int or None
        Number N of constant-pitch segments, >= 1; None (the default) means 20 unless
        ``per_revolution`` is given.
    sub_arcs : int
        Rectified closed-form arcs chained inside each segment, >= 1: accuracy without
        more controls, the error against Eqs. 1-2 falling like 1/n^2 (THEORY.md §3.8);
        one is often enough at 20 or more segments a revolution.
    equal : bool
        Equal segment angles (one shared length) or free ones.
    extrapolate : bool
        Richardson-extrapolate every sub-arc (whole and two halves, combined for a
        second-order error) at three times the arcs.  Off by default: it gains about
        what more sub-arcs do at the same cost (see ``segment_methods.closed_form_segment``).
    per_revolution : int or None
        Segments per revolution K, >= 1, instead of ``count`` (not both), for spirals
        whose turns are not known beforehand: N = ceil(K angle / 2 pi), ``angle`` being
        what the constant-pitch seed flies (``seed.initial_guess``); an optimum of more
        than 1.25 N / K turns is solved again on K a turn of its own
        (``error_control.DENSITY_SLACK``).
    """

    count: Optional[int] = None
    # The arc model's defaults, so that a default problem flies ArcModel()'s arcs.
    sub_arcs: int = ArcModel.sub_arcs
    equal: bool = True
    extrapolate: bool = ArcModel.extrapolate
    per_revolution: Optional[int] = None

    def __post_init__(self):
        if self.per_revolution is None:
            # count's default of 20 holds only without a per-revolution rule.
            object.__setattr__(self, "count", 20 if self.count is None else self.count)
            _check_finite_positive_int("segments.count", self.count)
        else:
            _check_finite_positive_int("segments.per_revolution", self.per_revolution)
            if self.count is not None:
                raise InputError(f"segments.count = {self.count!r} and segments.per_revolution "
                                 f"= {self.per_revolution!r}: give one of them, not both")
        _check_finite_positive_int("segments.sub_arcs", self.sub_arcs)
        _check_bool("segments.equal", self.equal)
        _check_bool("segments.extrapolate", self.extrapolate)

    def count_for(self, angle):
        """Number of segments for a seed that flies ``angle`` rad: ``count`` if fixed,
        else ceil(per_revolution * angle / 2 pi), at least 1."""
        if self.per_revolution is None:
            return self.count
        # The tiny tolerance keeps an exact whole number of turns from rounding up.
        return max(1, math.ceil(self.per_revolution * angle / (2 * math.pi) - 1e-9))


# ---------------------------------------------------------------- path and problem


@dataclass(frozen=True)
class PathConstraints:
    """Path constraints of the NLP.

    Attributes
    ----------
    r_min_au : float
        Smallest solar distance allowed at the segment nodes, au, >= 0.
    q3_margin : float
        Smallest q3 allowed at every closed-form arc's end, (0, 1): the first-order
        solution is only meaningful while q3 > 0 (THEORY.md §3.7).
    """

    r_min_au: float = 0.1
    q3_margin: float = 0.2

    def __post_init__(self):
        check_range("path.r_min_au", self.r_min_au, 0, 100, unit="au")
        check_range("path.q3_margin", self.q3_margin, 0, 1, low_open=True, high_open=True)


@dataclass(frozen=True)
class Tolerance:
    """How close the schedule, flown on Eqs. 1-2, must end to what the NLP promised.

    A run is *verified* only when its flight meets both bounds against the target, or
    without one against the NLP's own final state; the closed form is refined until they
    hold (``optimisation.error_control``).

    Attributes
    ----------
    position_km : float
        Bound on the flown position miss, km, in [1e-3, 1e8].
    velocity_m_s : float
        Bound on the flown velocity miss, m/s, in [1e-6, 1e5].
    """

    position_km: float = 10_000.0
    velocity_m_s: float = 10.0

    def __post_init__(self):
        check_range("tolerance.position_km", self.position_km, 1e-3, 1e8, unit="km")
        check_range("tolerance.velocity_m_s", self.velocity_m_s, 1e-6, 1e5, unit="m/s")


#: Box on a clock angle free over the full circle, rad: two turns either way of a start
#: in [-pi, pi] (``ipopt.wrap_clock``), since unbounded, a clock that hardly moves the
#: flight can run off by millions of turns.  Not a limit: a solve that ends on it is taken
#: on from its attitudes wrapped (``ipopt.solve_transcription``).
CLOCK_ROOM = 4 * math.pi

#: Whether a real-body problem with ``planar=None`` flies in the ecliptic projection:
#: False, since only the 3-D model meets a body's unprojected state.
PLANAR_DEFAULT = False

Departure = Union[ParkingOrbit, PolarState, BodyDeparture]
Objective = Union[MinTime, MaxRadius, MaxEnergy, FinalStateExpression, MinAcceleration]
Target = Optional[Union[CircularOrbit, Orbit, Rendezvous, BodyRendezvous, BodyIntercept]]


@dataclass(frozen=True)
class Problem:
    """One mission: departure, sail, segments, objective, target and path constraints.

    Attributes
    ----------
    name : str
        Used for the default output folder ``results/<name>/``: printable characters
        (``str.isprintable``: no control character, no lone surrogate) without ``/``
        or ``\\``.  A ``$`` is allowed.
    departure : ParkingOrbit, PolarState or BodyDeparture
    sail : Sail
    segments : Segments
    objective : MinTime, MaxRadius, MaxEnergy, FinalStateExpression or MinAcceleration
    target : CircularOrbit, Orbit, Rendezvous, BodyRendezvous, BodyIntercept or None
        None leaves the final state free (then the objective must fix the time).
    path : PathConstraints
    guess_alpha_deg : float or None
        Constant pitch of the forward propagation that seeds the NLP; default +45 deg
        when the target lies outward, -45 deg inward, +45 deg with no target.
    max_revolutions : float
        Bound on the total swept angle, revolutions; it also bounds each free segment.
    tolerance : Tolerance
        What the flown schedule must meet to be reported as verified.
    description : str
    planar : bool or None
        Fly a real-body problem in the ecliptic projection (True) or in three dimensions
        (False: DE421's unprojected states, a clock angle per segment, the planar motion
        in a turning plane).  None takes :data:`PLANAR_DEFAULT`.  A problem off the
        calendar (circles, (a, e) orbits, ``Rendezvous``) is planar, and False is refused
        there.
    """

    name: str
    departure: Departure
    sail: Sail
    segments: Segments = Segments()
    objective: Objective = MinTime()
    target: Target = None
    path: PathConstraints = PathConstraints()
    guess_alpha_deg: Optional[float] = None
    max_revolutions: float = 20.0
    tolerance: Tolerance = Tolerance()
    description: str = ""
    planar: Optional[bool] = None

    def __post_init__(self):
        check_printable("name", self.name, NAME_ALLOWED)
        if any(c in self.name for c in "/\\"):
            raise InputError(f"name = {self.name!r} holds a path separator; allowed: "
                             f"{NAME_ALLOWED}")
        for attr, kinds in (("departure", (ParkingOrbit, PolarState, BodyDeparture)),
                            ("sail", (Sail,)),
                            ("segments", (Segments,)),
                            ("objective", OBJECTIVES),
                            ("path", (PathConstraints,)), ("tolerance", (Tolerance,))):
            if not isinstance(getattr(self, attr), kinds):
                names = ", ".join(k.__name__ for k in kinds)
                raise InputError(f"{attr} = {getattr(self, attr)!r} is not one of: {names}")
        if self.target is not None and not isinstance(self.target, TARGETS):
            raise InputError(f"target = {self.target!r} is not one of: CircularOrbit, Orbit, "
                             "Rendezvous, BodyRendezvous, BodyIntercept, None")
        dated = isinstance(self.departure, BodyDeparture)
        if isinstance(self.target, (BodyRendezvous, BodyIntercept)) and not dated:
            raise InputError(f"target = {type(self.target).__name__} needs a dated departure: "
                             "departure = BodyDeparture(body=..., date=...)")
        if self.objective.free_acceleration and self.target is None:
            raise InputError("objective = MinAcceleration needs a target to reach")
        if self.target is None and not self.objective.fixed_time:
            raise InputError("objective = MinTime needs a target (target = None leaves "
                             "nothing to reach); use a fixed-time objective")
        if dated and self.objective.fixed_time:
            self._check_arrival_tracked()
        if dated and getattr(self.target, "arrival_window", None) is not None:
            self._check_arrival_after_departure()
        if self.guess_alpha_deg is not None:
            lo, hi = self.sail.alpha_min_deg, self.sail.alpha_max_deg
            check_range("guess_alpha_deg", self.guess_alpha_deg, lo, hi, unit="deg")
        check_range("max_revolutions", self.max_revolutions, 0, 1000, low_open=True)
        if self.planar not in (None, True, False):
            raise InputError(f"planar = {self.planar!r} is not True, False or None")
        if self.planar is False and not dated:
            raise InputError("planar = False needs a real body: three dimensions are for "
                             "departure = BodyDeparture(...); idealised problems are planar")
        if self.segments.extrapolate and self.three_d():
            # Checked here so that a run is refused before it starts (a window scan).
            raise InputError("segments.extrapolate = True is not available in three "
                             "dimensions; use False (or planar=True)")

    def _check_arrival_tracked(self):
        """A fixed time of flight from a body says when the flight ends: refuse, before
        any solve, one that ends after the last date the bodies are tracked on."""
        dep = self.departure
        latest = dep.window_jd[1] if dep.window is not None else dep.epoch_jd()
        end = latest + self.objective.tof_days
        last = dates.jd_from_iso(lookup.TRACK_SPAN[1])
        if end > last:
            raise InputError(
                f"objective.tof_days = {self.objective.tof_days:g} d: leaving "
                f"{dates.iso_from_jd(latest)} the flight ends {dates.iso_from_jd(end)} TDB, "
                f"after {lookup.TRACK_SPAN[1]}, the last date bodies are tracked on; "
                "shorten the flight or depart earlier")

    def _check_arrival_after_departure(self):
        """Refuse an arrival window that closes before the sail can leave: at or before
        the departure date, or the earliest date of a departure window; and, with a
        fixed time of flight, one that no departure date can arrive in."""
        dep = self.departure
        earliest = dep.window_jd[0] if dep.window is not None else dep.epoch_jd()
        field = "departure.window[0]" if dep.window is not None else "departure.date"
        opens, closes = self.target.arrival_jd
        window = tuple(self.target.arrival_window)
        if closes <= earliest:
            raise InputError(
                f"target.arrival_window = {window!r} closes on "
                f"{dates.iso_from_jd(closes)} TDB, not after {field} = "
                f"{dates.iso_from_jd(earliest)}: the arrival window must end after the "
                "earliest departure")
        if not self.objective.fixed_time:
            return
        tof = self.objective.tof_days
        latest = dep.window_jd[1] if dep.window is not None else earliest
        first, last = earliest + tof, latest + tof
        if first > closes or last < opens:
            raise InputError(
                f"objective.tof_days = {tof:g} d: departing as the problem allows, the flight "
                f"arrives from {dates.iso_from_jd(first)} to {dates.iso_from_jd(last)} TDB, "
                f"never inside target.arrival_window = {window!r}")

    def with_segments(self, count):
        """The same problem with ``count`` control segments (``--segments``; it replaces
        a ``per_revolution`` rule)."""
        return _replace(self, segments=_replace(self.segments, count=count, per_revolution=None))

    def with_tolerance(self, position_km=None, velocity_m_s=None):
        """The same problem with the tolerance's bounds replaced where given
        (``--tol-km``, ``--tol-m-s``)."""
        tol = self.tolerance
        return _replace(self, tolerance=Tolerance(
            tol.position_km if position_km is None else position_km,
            tol.velocity_m_s if velocity_m_s is None else velocity_m_s))

    # -- canonical views, the only unit conversions of this layer

    def three_d(self):
        """Whether it flies in 3-D: a real-body problem not ``planar`` (:data:`PLANAR_DEFAULT`)."""
        planar = PLANAR_DEFAULT if self.planar is None else self.planar
        return self.dated() and not planar

    def equations(self):
        """The equations of motion the problem is verified on, as a reader names them."""
        return "the equations of motion in 3-D" if self.three_d() else "Eqs. 1-2"

    def x0(self):
        """Departure polar state, canonical, numpy (in 3-D inside its plane, :meth:`plane_x0`)."""
        if self.three_d():
            return self.plane_x0()[:4]
        return np.array(self.departure.state(), float).ravel()

    def plane_x0(self):
        """The 3-D departure [r, theta, v_r, v_theta, qw, qx, qy, qz] at the (seed) epoch."""
        return self.departure.plane_state_at(self.epoch())

    def throttled(self):
        """Whether each segment has a throttle variable (a throttled sail, MinAcceleration)."""
        return bool(self.sail.throttle) or self.objective.free_acceleration

    def throttle_bounds(self):
        """Bounds (kappa_min, kappa_max) of the per-segment throttle, or None without one."""
        if not self.throttled():
            return None
        if not self.sail.throttle:
            return 0.0, 1.0
        return float(self.sail.throttle_min), float(self.sail.throttle_max)

    def dated(self):
        """Whether the problem lives on the calendar (it departs from a body)."""
        return isinstance(self.departure, BodyDeparture)

    def epoch(self):
        """Departure epoch (or the free date's seed), TU since J2000 TDB; 0 off the calendar."""
        return self.departure.epoch() if self.dated() else 0.0

    def free_date(self):
        return self.dated() and self.departure.free_date

    def start_state(self, result):
        """The exact departure (ephemeris, not the NLP's track) the verification flies
        ``result`` from; in three dimensions the Cartesian ecliptic state."""
        if self.three_d():
            return self.departure.cartesian_at(result.epoch, result.vinf_angle)
        if self.dated():
            return self.departure.state_at(result.epoch, result.vinf_angle)
        return np.asarray(result.x_start, float)

    def clock_free(self):
        """Whether the sail leaves the clock angle free over the full circle."""
        return self.sail.clock_min_deg == -180 and self.sail.clock_max_deg == 180

    def clock_bounds(self):
        """Bounds of the clock variables, rad: +-:data:`CLOCK_ROOM` for the full circle
        (delta is an angle, and a box at +-180 deg would be a wall through one
        attitude), else the sail's own."""
        if self.clock_free():
            return -CLOCK_ROOM, CLOCK_ROOM
        return math.radians(self.sail.clock_min_deg), math.radians(self.sail.clock_max_deg)

    def alpha_bounds(self):
        return math.radians(self.sail.alpha_min_deg), math.radians(self.sail.alpha_max_deg)

    def fixed_tof(self):
        """Fixed time of flight in TU, or None for minimum time."""
        if self.objective.fixed_time:
            return units.time_from_days(self.objective.tof_days)
        return None

    def tracks_body(self):
        """Whether the final polar angle is tied to a moving body (a rendezvous)."""
        return self.target is not None and self.target.tracks_body

    def aim_radius_au(self):
        """Radius the initial guess aims at, au, or None without a target."""
        return None if self.target is None else self.target.aim_radius_au


def _replace(obj, **changes):
    import dataclasses

    return dataclasses.replace(obj, **changes)
