"""Planets from JPL's DE421, heliocentric and in the ecliptic frame of J2000.

The `de421` package ships DE421 as Chebyshev coefficients that `jplephem` evaluates
(``Ephemeris(de421).compute(name, jd)``: km and km/day, relative to the solar-system
barycentre, in the ICRF, i.e. equatorial axes).  This module

- subtracts the Sun, since the Sun itself moves up to about 0.01 au about the
  barycentre, far more than any tolerance here;
- rotates the equatorial axes to the ecliptic of J2000 about x by the obliquity
  84381.448 arcsec (IAU 1976, the value JPL's ecliptic frame uses), so that the polar
  angle atan2(y, x) is the ecliptic longitude;
- converts to canonical units: au (149,597,870.7 km) and au/TU.

:func:`ecliptic_state` is the planet's whole state in three dimensions, out of the
ecliptic as it is; :func:`polar_state` is its projection on the ecliptic, which the
planar problems fly against.  The rotation between the two frames is written once, in
:func:`ecliptic_from_icrf` and :func:`icrf_from_ecliptic` (the latter for outputs in
DE421's own ICRF, such as an orbit ephemeris message).

Which point ``earth`` is: the **Earth-Moon barycentre** (DE421's ``earthmoon``).  The sail
starts from Earth's sphere of influence (about 925,000 km across), and the barycentre is
only about 4,700 km from Earth's centre, below the 10,000 km tolerance of a rendezvous and
far inside the sphere of influence.  Earth's centre would add the Moon's monthly wobble
(4,700 km, 12.6 m/s), which a smooth :mod:`~esail_opt.bodies.track` of the barycentre
does not need to resolve.

Dates are Julian dates in TDB (see :mod:`~esail_opt.bodies.dates`).  The span is read
from the tables as loaded (:data:`SPAN_JD`); the `de421` package's tables run from
1899-12-04 to 2200-02-01, wider than the 1900-2050 its description names, and past 2050
they agree with ERFA's plan94 as well as before it.  jplephem itself would extrapolate
up to one record beyond the end, so this module checks every date against the span.  The coefficients load
lazily: the small header at import (for :data:`SPAN_JD`), each body's table on first use,
once.
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
    # Every table of the old jplephem format covers [jalpha, jomega]: the reader itself
    # divides that interval into the table's records, so it is the span of all of them.
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


#: The rotation from DE421's ICRF (equatorial) axes to the ecliptic-J2000 axes, about x by
#: :data:`OBLIQUITY_J2000`: ``ecliptic = ECLIPTIC_FROM_ICRF @ icrf``.  Its transpose turns
#: back; both directions go through :func:`ecliptic_from_icrf` and
#: :func:`icrf_from_ecliptic`, the one place the package rotates between the two.
ECLIPTIC_FROM_ICRF = np.array([[1.0, 0.0, 0.0],
                               [0.0, _COS_EPS, _SIN_EPS],
                               [0.0, -_SIN_EPS, _COS_EPS]])


def _rotate(matrix, vectors):
    values = np.asarray(vectors, dtype=float)
    if values.shape[:1] not in ((3,), (6,)):
        raise ValueError(f"expected 3 or 6 components along the first axis, got shape {values.shape}")
    rotated = np.empty_like(values)
    # Written out term by term (not a matrix product, which may fuse or reorder the
    # sums): the ecliptic states keep the exact bits they had before this function.
    for block in range(0, values.shape[0], 3):
        x, y, z = values[block], values[block + 1], values[block + 2]
        for row in range(3):
            rotated[block + row] = matrix[row, 0] * x + matrix[row, 1] * y + matrix[row, 2] * z
    return rotated


def ecliptic_from_icrf(vectors):
    """Rotate ICRF (DE421's equatorial axes) vectors or states to the ecliptic of J2000.

    Parameters
    ----------
    vectors : array_like, shape (3, ...) or (6, ...)
        Positions ``[x, y, z]``, or states ``[x, y, z, vx, vy, vz]`` whose two halves are
        each rotated; any units (a rotation keeps them).

    Returns
    -------
    numpy.ndarray
        A new array of the same shape.
    """
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
    """Heliocentric ecliptic-J2000 Cartesian state of a planet, canonical units.

    Parameters
    ----------
    name : str
        One of :data:`PLANETS`, any case; ``earth`` is the Earth-Moon barycentre.
    jd : float or array_like of shape (M,)
        Julian date(s), TDB, within :data:`SPAN_JD`.
    field : str
        The name used for ``name`` in error messages (the date is ``<field>.date``).
    jd2 : float or array_like
        A second part of the date, added to ``jd`` (days).  One float of a Julian date
        resolves about 40 microseconds, a metre of a planet's motion; a date split as
        J2000 plus the days since (:func:`esail_opt.bodies.dates.jd_split_from_tu`)
        keeps the microseconds that a metre-level polish is judged on.

    Returns
    -------
    numpy.ndarray
        ``[x, y, z, vx, vy, vz]`` in au and au/TU: shape (6,) for a scalar date, (6, M)
        for M dates.
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
    """Project ecliptic Cartesian state(s) onto the ecliptic as polar state(s).

    The position is projected orthogonally onto the ecliptic plane, and the velocity is
    the time derivative of that projection, i.e. the in-plane components (vx, vy) of the
    3-D velocity resolved along and across the projected radius:
    ``v_r = (x vx + y vy) / r`` and ``v_theta = (x vy - y vx) / r`` with ``r = hypot(x, y)``.
    So dr/dt = v_r and r dtheta/dt = v_theta hold exactly for the projected motion, which
    a smooth fit of the four components then respects.  The out-of-plane z is returned
    as well, since the projection drops it.

    Parameters
    ----------
    state : array_like, shape (6,) or (6, M)
        ``[x, y, z, vx, vy, vz]``, canonical units.

    Returns
    -------
    polar : numpy.ndarray, shape (4,) or (4, M)
        ``[r, theta, v_r, v_theta]``, theta = atan2(y, x) in (-pi, pi].
    z : float or numpy.ndarray, shape (M,)
        The out-of-plane coordinate, au.
    """
    s = np.asarray(state, dtype=float)
    x, y, z, vx, vy = s[0], s[1], s[2], s[3], s[4]
    r = np.hypot(x, y)
    polar = np.array([r, np.arctan2(y, x), (x * vx + y * vy) / r, (x * vy - y * vx) / r])
    return polar, (float(z) if np.ndim(z) == 0 else z)


def polar_state(name, jd, field="body", jd2=0.0):
    """A planet's state projected onto the ecliptic of J2000, as the package's polar state
    (arguments as :func:`ecliptic_state`).

    Returns
    -------
    polar : numpy.ndarray, shape (4,) or (4, M)
        ``[r, theta, v_r, v_theta]`` in au, rad and au/TU; theta is the ecliptic
        longitude in (-pi, pi].  See :func:`polar_from_ecliptic` for the projection.
    z : float or numpy.ndarray
        The ecliptic latitude's height, au, that the projection drops.
    """
    return polar_from_ecliptic(ecliptic_state(name, jd, field, jd2))
