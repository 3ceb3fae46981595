"""Planets from JPL's DE421, heliocentric and in the ecliptic frame of J2000.

jplephem evaluates the `de421` package's Chebyshev tables (km and km/day about the
solar-system barycentre, ICRF axes); this module subtracts the Sun (up to about 0.01 au
from the barycentre), rotates the axes about x by the obliquity 84381.448 arcsec (IAU 1976,
as JPL's ecliptic frame), so that atan2(y, x) is the ecliptic longitude, and converts to au
and au/TU.  :func:`ecliptic_state` is the 3-D state; :func:`polar_state` its projection on
the ecliptic, which the planar problems fly against.

``earth`` is the **Earth-Moon barycentre**: about 4,700 km from Earth's centre, below a
10,000 km rendezvous tolerance, and free of the Moon's monthly wobble that a smooth
:mod:`~esail_opt.bodies.track` would otherwise have to resolve.

Dates are Julian dates in TDB (:mod:`~esail_opt.bodies.dates`), each checked against
:data:`SPAN_JD`, since jplephem would extrapolate up to one record beyond the tables' end.
The tables run from 1899-12-04 to 2200-02-01, wider than the 1900-2050 the package's
description names, and agree with ERFA's plan94 past 2050 as before.  Each body's table
loads on first use.
"""

import math

import numpy as np

from esail_opt.bodies.dates import iso_from_jd
from esail_opt.errors import InputError
from esail_opt.physics import constants as units

#: Names accepted for planets (any case).  ``earth`` is the Earth-Moon barycentre.
PLANETS = ("mercury", "venus", "earth", "mars", "jupiter", "saturn")

#: Obliquity of the ecliptic at J2000 that defines the ecliptic-J2000 axes, rad.
OBLIQUITY_J2000 = math.radians(84381.448 / 3600.0)

_SEGMENT = {"earth": "earthmoon"}
_AU_KM = units.AU / 1e3
_COS_EPS = math.cos(OBLIQUITY_J2000)
_SIN_EPS = math.sin(OBLIQUITY_J2000)

_ephemeris = None


def _load():
    """The jplephem Ephemeris of DE421, created once (its tables load per body, lazily)."""
    global _ephemeris
    if _ephemeris is None:
        import de421
        from jplephem import Ephemeris

        _ephemeris = Ephemeris(de421)
    return _ephemeris


def _span():
    # In jplephem's old format every table's records divide [jalpha, jomega].
    eph = _load()
    return float(eph.jalpha), float(eph.jomega)


#: (first, last) Julian date (TDB) the ephemeris covers, read from the loaded DE421 header.
SPAN_JD = _span()


def check_span(jd, field="date"):
    """Raise InputError unless every Julian date in ``jd`` lies within :data:`SPAN_JD`."""
    values = np.atleast_1d(np.asarray(jd, dtype=float))
    first, last = SPAN_JD
    bad = ~((values >= first) & (values <= last))  # NaN is bad too
    if bad.any():
        worst = values[bad][0]
        shown = iso_from_jd(worst) if math.isfinite(worst) else repr(float(worst))
        raise InputError(
            f"{field} = {shown} (JD {worst:.6g}) is outside the ephemeris span "
            f"[{iso_from_jd(first)}, {iso_from_jd(last)}] TDB"
        )


#: Rotation from DE421's ICRF axes to the ecliptic of J2000, ``ecliptic = ECLIPTIC_FROM_ICRF
#: @ icrf``; the package rotates only through :func:`ecliptic_from_icrf` and its inverse.
ECLIPTIC_FROM_ICRF = np.array([[1.0, 0.0, 0.0],
                               [0.0, _COS_EPS, _SIN_EPS],
                               [0.0, -_SIN_EPS, _COS_EPS]])


def _rotate(matrix, vectors):
    values = np.asarray(vectors, dtype=float)
    if values.shape[:1] not in ((3,), (6,)):
        raise ValueError(f"expected 3 or 6 components along the first axis, got shape {values.shape}")
    rotated = np.empty_like(values)
    # Term by term: a matrix product may fuse or reorder the sums, changing the last bits.
    for block in range(0, values.shape[0], 3):
        x, y, z = values[block], values[block + 1], values[block + 2]
        for row in range(3):
            rotated[block + row] = matrix[row, 0] * x + matrix[row, 1] * y + matrix[row, 2] * z
    return rotated


def ecliptic_from_icrf(vectors):
    """A new array: ICRF (DE421's equatorial axes) positions, shape (3, ...), or states,
    shape (6, ...), each half rotated, turned to the ecliptic of J2000, in the same units."""
    return _rotate(ECLIPTIC_FROM_ICRF, vectors)


def icrf_from_ecliptic(vectors):
    """The inverse of :func:`ecliptic_from_icrf` (the transposed rotation), same contract."""
    return _rotate(ECLIPTIC_FROM_ICRF.T, vectors)


def planet_key(name, field="body"):
    """The canonical lower-case planet name, or InputError listing the allowed names."""
    key = name.strip().lower() if isinstance(name, str) else None
    if key not in PLANETS:
        raise InputError(f"{field} = {name!r} is not a known planet; use one of {', '.join(PLANETS)}")
    return key


def ecliptic_state(name, jd, field="body", jd2=0.0):
    """Heliocentric ecliptic-J2000 state ``[x, y, z, vx, vy, vz]`` (au, au/TU) of the planet
    ``name`` (one of :data:`PLANETS`, any case, else InputError naming ``field``): shape (6,)
    for a scalar date, (6, M) for M dates.

    ``jd`` is the Julian date(s), TDB, plus ``jd2`` days, within :data:`SPAN_JD` (else
    InputError naming ``<field>.date``).  One float of a JD resolves about 40 microseconds, a
    metre of a planet's motion; a date split by :func:`~esail_opt.bodies.dates.jd_split_from_tu`
    keeps what a metre-level polish needs.
    """
    key = planet_key(name, field)
    scalar = np.ndim(jd) == 0 and np.ndim(jd2) == 0
    dates = np.atleast_1d(np.asarray(jd, dtype=float))
    extra = np.broadcast_to(np.asarray(jd2, dtype=float), dates.shape)
    check_span(dates + extra, f"{field}.date")
    eph = _load()

    def state(segment):
        bundle = eph.compute_bundle(segment, dates, extra)
        return np.concatenate((eph.position_from_bundle(bundle),
                               eph.velocity_from_bundle(bundle)))

    state = ecliptic_from_icrf(state(_SEGMENT.get(key, key)) - state("sun"))
    state[:3] /= _AU_KM
    state[3:] *= units.TU_DAYS / _AU_KM
    return state[:, 0] if scalar else state


def polar_from_ecliptic(state):
    """Project ecliptic state(s) ``[x, y, z, vx, vy, vz]``, shape (6,) or (6, M), canonical
    units, onto the ecliptic: ``([r, theta, v_r, v_theta], z)``, shapes (4,) or (4, M) and
    () or (M,), theta = atan2(y, x) in (-pi, pi], z the height the projection drops (au).

    The velocity is the projection's time derivative, ``v_r = (x vx + y vy) / r`` and
    ``v_theta = (x vy - y vx) / r``, so dr/dt = v_r and r dtheta/dt = v_theta hold exactly.
    """
    s = np.asarray(state, dtype=float)
    x, y, z, vx, vy = s[0], s[1], s[2], s[3], s[4]
    r = np.hypot(x, y)
    polar = np.array([r, np.arctan2(y, x), (x * vx + y * vy) / r, (x * vy - y * vx) / r])
    return polar, (float(z) if np.ndim(z) == 0 else z)


def polar_state(name, jd, field="body", jd2=0.0):
    """:func:`ecliptic_state` projected by :func:`polar_from_ecliptic`: ``[r, theta, v_r,
    v_theta]`` (au, rad, au/TU; theta the ecliptic longitude) and the height z (au)."""
    return polar_from_ecliptic(ecliptic_state(name, jd, field, jd2))
