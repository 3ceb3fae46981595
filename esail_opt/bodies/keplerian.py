"""Small bodies on Keplerian orbits about the Sun, from osculating elements at an epoch.

A :class:`SmallBody` holds heliocentric osculating elements in the ecliptic and equinox of
J2000 (the frame of :mod:`~esail_opt.bodies.ephemeris`) in au, degrees and an ISO 8601 epoch
(TDB); its state at another date is two-body motion with mu_sun = 1 (n = a^(-3/2) per TU).
Ignoring the planets, it drifts from the real body away from the epoch (of order 1e-4 au a
year for a main-belt asteroid): the standard preliminary-design model, kept close by an
epoch near the mission's dates.
"""

import math
from dataclasses import dataclass, field as _field

import numpy as np

from esail_opt.bodies.dates import check_tracked, iso_from_jd, jd_from_iso
from esail_opt.bodies.ephemeris import polar_from_ecliptic
from esail_opt.errors import InputError, check_printable, check_range
from esail_opt.physics import constants as units

#: The semimajor axes a small body may have, au: every other target's range of radius
#: (``optimisation.goals``).  Below 0.05 au (ten solar radii) the orbit grazes the Sun;
#: beyond 100 au the period passes 1000 years.
A_AU_RANGE = (0.05, 100.0)

#: Newton's method on Kepler's equation stops when the step is below this, rad.
KEPLER_TOL = 1e-15
_KEPLER_MAX_ITER = 60


def eccentric_anomaly(mean_anomaly, e):
    """Solve Kepler's equation E - e sin E = M for E, rad, of the shape of ``mean_anomaly``
    (M, rad, float or array; 0 <= e < 1).

    M is reduced to (-pi, pi] and its whole turns added back to E, so E - M is continuous.
    Danby's start E0 = M + 0.85 e sign(sin M) keeps Newton's method monotone for every
    e < 1, where E0 = M can overshoot; it stops at steps below :data:`KEPLER_TOL` (at most
    60 iterations) and raises ArithmeticError if the residual is then above 1e-13.
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


#: The line that refuses a body given both perihelion angles or neither.
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

    The perihelion is given by exactly one of two keyword angles: ``argument_of_perihelion_deg``
    (omega, from the ascending node in the orbit's plane: JPL's small-body database's w,
    pasted as is) or ``perihelion_deg`` (the longitude varpi = node + omega, as some
    catalogues give).  Both or neither is refused, since no range tells one from the other;
    both are readable whichever was given.  Every angle after ``node_deg`` is keyword-only.

    Fields, in boundary units, each checked on creation (InputError naming ``body.<field>``
    and its allowed range):

    - ``name``: what the body is called, e.g. ``"(101955) Bennu"``.
    - ``a_au``: semimajor axis, au, in [0.05, 100] (:data:`A_AU_RANGE`).
    - ``e``: eccentricity in [0, 1) (elliptic orbits only).
    - ``inclination_deg``: to the ecliptic of J2000, deg, in [0, 90): the polar state
      describes prograde motion about the ecliptic pole, and a polar or retrograde orbit's
      projected longitude stalls or runs backwards.
    - ``node_deg``: longitude of the ascending node (Omega, JPL's "om"), deg, in [-360, 360].
    - ``argument_of_perihelion_deg``: omega (JPL's "w"), deg, in [-360, 360] when given,
      wrapped into [0, 360) when derived.
    - ``perihelion_deg`` (read-only property): varpi, deg, in [-720, 720] when given, read
      back wrapped into [0, 360).
    - ``mean_anomaly_deg``: mean anomaly at the epoch, deg, in [-360, 360].
    - ``epoch``: ISO 8601 date of the elements, TDB, within ``dates.TRACK_SPAN`` (2000-2060),
      so that the two-body model is not carried decades from its epoch.
    - ``source``: where the elements come from.

    A solution file holds ``argument_of_perihelion_deg``; one holding ``perihelion_deg``
    reads too.
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
        """Heliocentric ecliptic-J2000 state ``[x, y, z, vx, vy, vz]`` (au, au/TU), shape (6,)
        or (6, M), at Julian date(s) ``jd`` (TDB) plus ``jd2`` days, as the planets'
        (:func:`esail_opt.bodies.ephemeris.ecliptic_state`).  Any finite date (else InputError
        naming ``<field>.date``): the two-body model has no span."""
        scalar = np.ndim(jd) == 0 and np.ndim(jd2) == 0
        dates = np.atleast_1d(np.asarray(jd, dtype=float))
        extra = np.broadcast_to(np.asarray(jd2, dtype=float), dates.shape)
        if not np.all(np.isfinite(dates + extra)):
            raise InputError(f"{field}.date = {jd!r} is not a finite Julian date")
        a, e = self.a_au, self.e
        n = self.mean_motion
        # Days since the epoch before ``jd2`` is added: a split date keeps its microseconds.
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
        """``([r, theta, v_r, v_theta], z)`` projected onto the ecliptic, as
        :func:`esail_opt.bodies.ephemeris.polar_state`."""
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
    """A shipped body from JPL Horizons' heliocentric ecliptic J2000 osculating elements, in
    Horizons' order and as printed (A au, EC, IN deg, OM deg, W deg, MA deg) at ``epoch``
    (0 h TDB); ``designation`` and ``solution`` go into ``source``."""
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
