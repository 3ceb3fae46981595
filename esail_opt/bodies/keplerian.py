"""Small bodies on Keplerian orbits about the Sun, from osculating elements at an epoch.

A :class:`SmallBody` holds heliocentric osculating elements referred to the ecliptic and
equinox of J2000 (the frame of :mod:`~esail_opt.bodies.ephemeris`), in boundary units
(au, degrees, an ISO 8601 epoch in TDB).  Its state at another date is the two-body
motion with mu_sun = 1 in canonical units: the mean anomaly grows at n = a^(-3/2) per TU,
Kepler's equation gives the eccentric anomaly, and the orbit's orientation is fixed.

This ignores the planets' pull, so it drifts from the real body as the date moves from
the epoch (for a main-belt asteroid, of order 1e-4 au a year; far more for a near-Earth
asteroid after a close planetary encounter).  It is the standard preliminary-design
model of a small-body target; elements with an epoch near the mission dates keep it
close.
"""

import math
from dataclasses import dataclass, field as _field

import numpy as np

from esail_opt.bodies.dates import check_tracked, iso_from_jd, jd_from_iso
from esail_opt.bodies.ephemeris import polar_from_ecliptic
from esail_opt.errors import InputError, check_printable, check_range
from esail_opt.physics import constants as units

#: The semimajor axes a small body may have, au: the range every other target's
#: radius takes (``optimisation.goals``), so that a body is refused where a circular
#: orbit of its radius would be.  Below 0.05 au (ten solar radii) the orbit grazes
#: the Sun; beyond 100 au the period passes 1000 years.  Outside it the seeding and
#: the NLP failed later, with a line naming another field (the seed's pitch, the
#: revolutions).
A_AU_RANGE = (0.05, 100.0)

#: Newton's method on Kepler's equation stops when the step is below this, rad.
KEPLER_TOL = 1e-15
_KEPLER_MAX_ITER = 60


def eccentric_anomaly(mean_anomaly, e):
    """Solve Kepler's equation E - e sin E = M for E (elliptic, 0 <= e < 1).

    M is first reduced to (-pi, pi], E is returned in the same branch plus the
    removed whole turns, so E - M is continuous.  The start E0 = M + 0.85 e sign(sin M)
    (Danby's) keeps Newton's method monotone and fast for every e < 1, including high
    eccentricities where the start E0 = M can overshoot; iteration stops when every step
    is below :data:`KEPLER_TOL`, capped at 60 iterations, after which the residual is
    checked.

    Parameters
    ----------
    mean_anomaly : float or numpy.ndarray
        M, rad.
    e : float
        Eccentricity in [0, 1).

    Returns
    -------
    float or numpy.ndarray
        E, rad, of the shape of ``mean_anomaly``.
    """
    m = np.asarray(mean_anomaly, dtype=float)
    turns = np.round(m / (2 * math.pi))
    reduced = m - 2 * math.pi * turns
    ecc = float(e)
    big_e = reduced + 0.85 * ecc * np.sign(np.sin(reduced))
    for _ in range(_KEPLER_MAX_ITER):
        step = (big_e - ecc * np.sin(big_e) - reduced) / (1 - ecc * np.cos(big_e))
        big_e = big_e - step
        if np.all(np.abs(step) < KEPLER_TOL):
            break
    residual = np.abs(big_e - ecc * np.sin(big_e) - reduced)
    if not np.all(residual < 1e-13):
        raise ArithmeticError(f"Kepler's equation did not converge (residual {residual.max():.3g})")
    result = big_e + 2 * math.pi * turns
    return float(result) if np.ndim(mean_anomaly) == 0 else result


#: The perihelion's two angles and what each is, for the line that refuses a body
#: given both or neither.
_PERIHELION_CHOICE = (
    "give exactly one: argument_of_perihelion_deg (omega, measured from the ascending node "
    "in the orbit's plane; JPL's small-body database lists it as w) in [-360, 360] deg, "
    "or perihelion_deg (the longitude of perihelion, node + omega) in [-720, 720] deg")


def _wrapped_deg(angle):
    """``angle`` (deg) wrapped into [0, 360)."""
    wrapped = angle % 360.0
    return 0.0 if wrapped == 360.0 else wrapped  # a tiny negative angle rounds up to 360


@dataclass(frozen=True, init=False)
class SmallBody:
    """A small body on a heliocentric Keplerian orbit (ecliptic and equinox J2000).

    The perihelion's direction is given by exactly one of two angles, by name:

    - ``argument_of_perihelion_deg``, omega, measured from the ascending node in the
      orbit's plane.  JPL's small-body database lists w, the argument of perihelion:
      paste it here.  The shipped bodies are written this way.
    - ``perihelion_deg``, the longitude of perihelion varpi = node + omega, which some
      catalogues (and planetary tables) give instead.

    Both or neither is refused (both lie in the same range of angles, so a catalogue's
    w given as the longitude would not be caught by a range).  The other one is derived:
    ``body.argument_of_perihelion_deg`` and ``body.perihelion_deg`` are both readable
    whichever was given.  Every angle after ``node_deg`` is keyword-only, so that no
    position in the argument list can stand for the wrong one.

    Attributes (boundary units)
    ---------------------------
    name : str
        What the body is called, e.g. ``"(101955) Bennu"``.
    a_au : float
        Semimajor axis, au, in [0.05, 100] (:data:`A_AU_RANGE`).
    e : float
        Eccentricity in [0, 1) (elliptic orbits only).
    inclination_deg : float
        Inclination to the ecliptic of J2000, deg, in [0, 90): the package's polar state
        describes prograde motion about the ecliptic pole, so retrograde and polar orbits,
        whose projected longitude stalls or runs backwards, are refused.
    node_deg : float
        Longitude of the ascending node (Omega, JPL's "om"), deg, in [-360, 360].
    argument_of_perihelion_deg : float
        Argument of perihelion omega (JPL's "w"), deg, from the node: in [-360, 360] when
        given, wrapped into [0, 360) when derived from ``perihelion_deg``.
    perihelion_deg : float (read-only property)
        Longitude of perihelion varpi = node + omega, deg: in [-720, 720] when given
        (as a keyword argument), always read back wrapped into [0, 360).
    mean_anomaly_deg : float
        Mean anomaly at the epoch, deg, in [-360, 360].
    epoch : str
        ISO 8601 date of the elements, TDB, in the tracked span 2000-2060
        (``dates.TRACK_SPAN``): the two-body model drifts from the real body as the
        date moves from the epoch, so elements from outside the years a mission is
        flown in are refused rather than carried decades.
    source : str
        Where the elements come from.

    Every field is checked when the body is created; a bad one raises InputError naming
    ``body.<field>`` and its allowed range.  A solution file holds the body's fields
    with ``argument_of_perihelion_deg``; an older one's ``perihelion_deg`` still reads.
    """

    name: str
    a_au: float
    e: float
    inclination_deg: float
    node_deg: float
    argument_of_perihelion_deg: float
    mean_anomaly_deg: float
    epoch: str
    source: str = ""
    epoch_jd: float = _field(init=False, repr=False, compare=False)

    def __init__(self, name, a_au, e, inclination_deg, node_deg, *,
                 argument_of_perihelion_deg=None, perihelion_deg=None,
                 mean_anomaly_deg, epoch, source=""):
        if not isinstance(name, str) or not name.strip():
            raise InputError(f"body.name = {name!r} must be a non-empty string")
        check_printable("body.name", name)
        if not isinstance(source, str):
            raise InputError(f"body.source = {source!r} must be a string")
        if (argument_of_perihelion_deg is None) == (perihelion_deg is None):
            raise InputError(f"body.argument_of_perihelion_deg = {argument_of_perihelion_deg!r} "
                             f"and body.perihelion_deg = {perihelion_deg!r}: "
                             f"{_PERIHELION_CHOICE}")
        node = check_range("body.node_deg", node_deg, -360.0, 360.0, unit="deg")
        if argument_of_perihelion_deg is not None:
            argument = check_range("body.argument_of_perihelion_deg",
                                   argument_of_perihelion_deg, -360.0, 360.0, unit="deg")
        else:
            argument = _wrapped_deg(check_range("body.perihelion_deg", perihelion_deg,
                                                -720.0, 720.0, unit="deg") - node)
        checked = {
            "name": name,
            "a_au": check_range("body.a_au", a_au, *A_AU_RANGE, unit="au"),
            "e": check_range("body.e", e, 0.0, 1.0, high_open=True),
            "inclination_deg": check_range("body.inclination_deg", inclination_deg,
                                           0.0, 90.0, high_open=True, unit="deg"),
            "node_deg": node,
            "argument_of_perihelion_deg": argument,
            "mean_anomaly_deg": check_range("body.mean_anomaly_deg", mean_anomaly_deg,
                                            -360.0, 360.0, unit="deg"),
            "epoch": epoch,
            "source": source,
            "epoch_jd": check_tracked(jd_from_iso(epoch, "body.epoch"), "body.epoch"),
        }
        for key, value in checked.items():
            object.__setattr__(self, key, value)

    @property
    def perihelion_deg(self):
        """Longitude of perihelion varpi = node + argument of perihelion, deg, in [0, 360)."""
        return _wrapped_deg(self.node_deg + self.argument_of_perihelion_deg)

    @property
    def mean_motion(self):
        """n = a^(-3/2), rad/TU (mu_sun = 1)."""
        return self.a_au ** -1.5

    @property
    def period_days(self):
        """Orbital period, days."""
        return units.time_to_days(2 * math.pi / self.mean_motion)

    def ecliptic_state(self, jd, field="body", jd2=0.0):
        """Heliocentric ecliptic-J2000 state ``[x, y, z, vx, vy, vz]`` (au, au/TU).

        Parameters
        ----------
        jd : float or array_like of shape (M,)
            Julian date(s), TDB.  Any finite date: the two-body model has no span.
        field : str
            Name used in error messages (``<field>.date``).
        jd2 : float or array_like
            A second part of the date, days, as for the planets
            (:func:`esail_opt.bodies.ephemeris.ecliptic_state`).

        Returns
        -------
        numpy.ndarray
            Shape (6,) for a scalar date, (6, M) for M dates.
        """
        scalar = np.ndim(jd) == 0 and np.ndim(jd2) == 0
        dates = np.atleast_1d(np.asarray(jd, dtype=float))
        extra = np.broadcast_to(np.asarray(jd2, dtype=float), dates.shape)
        if not np.all(np.isfinite(dates + extra)):
            raise InputError(f"{field}.date = {jd!r} is not a finite Julian date")
        a, e = self.a_au, self.e
        n = self.mean_motion
        # The days since the epoch are formed before the second part is added, so that
        # a split date keeps its microseconds.
        since = units.time_from_days((dates - self.epoch_jd) + extra)
        m = math.radians(self.mean_anomaly_deg) + n * since
        big_e = eccentric_anomaly(m, e)
        cos_e, sin_e = np.cos(big_e), np.sin(big_e)
        root = math.sqrt(1 - e * e)
        rate = n / (1 - e * cos_e)  # dE/dt
        # Perifocal frame: x towards perihelion, y 90 deg ahead in the orbital plane.
        p = np.array([a * (cos_e - e), a * root * sin_e])
        v = np.array([-a * sin_e * rate, a * root * cos_e * rate])
        rotation = self._perifocal_to_ecliptic()
        state = np.vstack([rotation @ p, rotation @ v])
        return state[:, 0] if scalar else state

    def polar_state(self, jd, field="body", jd2=0.0):
        """State projected onto the ecliptic as ``([r, theta, v_r, v_theta], z)``.

        Same contract as :func:`esail_opt.bodies.ephemeris.polar_state`.
        """
        return polar_from_ecliptic(self.ecliptic_state(jd, field, jd2))

    def _perifocal_to_ecliptic(self):
        """The 3x2 matrix R3(-node) R1(-i) R3(-argument of perihelion), first two columns."""
        node = math.radians(self.node_deg)
        inc = math.radians(self.inclination_deg)
        arg = math.radians(self.argument_of_perihelion_deg)
        cn, sn = math.cos(node), math.sin(node)
        ci, si = math.cos(inc), math.sin(inc)
        cw, sw = math.cos(arg), math.sin(arg)
        return np.array([
            [cn * cw - sn * sw * ci, -cn * sw - sn * cw * ci],
            [sn * cw + cn * sw * ci, -sn * sw + cn * cw * ci],
            [sw * si, cw * si],
        ])

    def describe(self):
        """One line for logs and reports."""
        return (f"{self.name}: a = {self.a_au:.6f} au, e = {self.e:.6f}, "
                f"i = {self.inclination_deg:.4f} deg, epoch {iso_from_jd(self.epoch_jd)} TDB")


def _from_horizons(name, designation, elements, epoch, solution):
    """A shipped body from JPL Horizons' heliocentric ecliptic J2000 osculating elements.

    Parameters
    ----------
    name : str
        The body's name, e.g. ``"(101955) Bennu"``.
    designation : str
        The body as Horizons names it, for ``source``.
    elements : tuple of float
        Horizons' own elements in its order, (A au, EC, IN deg, OM deg, W deg, MA deg),
        given to :class:`SmallBody` as printed: W is ``argument_of_perihelion_deg``.
    epoch : str
        ISO 8601 date of the elements (0 h TDB).
    solution : str
        Which orbit solution, for ``source``.
    """
    a, e, inclination, node, argument, mean_anomaly = elements
    return SmallBody(
        name=name, a_au=a, e=e, inclination_deg=inclination, node_deg=node,
        argument_of_perihelion_deg=argument, mean_anomaly_deg=mean_anomaly, epoch=epoch,
        source=(f"JPL Horizons heliocentric ecliptic J2000 osculating elements of "
                f"{designation}, epoch JD {jd_from_iso(epoch):.1f} ({epoch}.0) TDB, {solution}"))


#: (101955) Bennu, a near-Earth (Apollo) asteroid, target of OSIRIS-REx.
BENNU = _from_horizons(
    "(101955) Bennu", "101955 Bennu",
    (1.1263910258948120, 0.2037450762416414, 6.0349437702479403, 2.060866195696420,
     66.22306084084298, 101.7039520024729),
    "2011-01-01",
    "orbit solution dated 2021-01-07 (OSIRIS-REx solution, Farnocchia et al. 2021, Icarus "
    "369, 114594; trajectory sb-101955-118)")

#: (1) Ceres, the largest main-belt body.
CERES = _from_horizons(
    "(1) Ceres", "1 Ceres",
    (2.769289292143484, 0.07687465013145245, 10.59127767086216, 80.3011901917491,
     73.80896808746482, 130.3159688200986),
    "2020-01-01", "orbit solution JPL#48 dated 2021-04-13")

#: The small bodies the package ships, by lower-case short name.
SMALL_BODIES = {"bennu": BENNU, "ceres": CERES}
