"""One way to ask for any body, planet or small body, by what a problem file names.

A body is a planet's name (read from DE421) or a
:class:`~esail_opt.bodies.keplerian.SmallBody`; the optimisation layer asks this module for
its exact state at a date, its smooth track for the NLP and its label, whichever it is.

Every track spans :data:`TRACK_SPAN`, built once per body and process, so that one NLP
serves a scan over any dates in it, the dates being parameters rather than structure; sixty
years, not all of DE421, since fitting grows with the span.  An exact state's polar angle is
put on the track's branch (theta unwrapped from the span's start), so that a seed flown from
it and the NLP's departure from the track agree on theta, not only modulo 2 pi.
"""

import dataclasses
import functools
import math

import numpy as np

from esail_opt.bodies import ephemeris
from esail_opt.bodies.dates import (
    TRACK_SPAN, check_tracked, jd_from_iso, jd_from_tu, jd_split_from_tu, tu_from_jd)
from esail_opt.bodies.keplerian import SmallBody
from esail_opt.bodies.track import track3_on, track_of
from esail_opt.errors import InputError


def check_body(body, field):
    """Raise InputError, naming ``field``, unless ``body`` is a known planet or a SmallBody."""
    if isinstance(body, SmallBody):
        return body
    if isinstance(body, str) and body.strip().lower() in ephemeris.PLANETS:
        return body
    raise InputError(f"{field} = {body!r} is not a SmallBody or one of: "
                     f"{', '.join(ephemeris.PLANETS)}")


def describe(body):
    """The body as a solution file holds it: a planet's name, or a small body's fields."""
    if isinstance(body, SmallBody):
        return {f.name: getattr(body, f.name) for f in dataclasses.fields(body) if f.init}
    return _key(body)


def resolve(description):
    """The body :func:`describe` wrote (raises InputError if it is not one)."""
    if isinstance(description, dict):
        return SmallBody(**description)
    return check_body(description, "body")


def _key(body):
    return body.strip().lower() if isinstance(body, str) else body


def name(body):
    """The body's name as the solution files give it."""
    return body.name if isinstance(body, SmallBody) else _key(body)


def source(body):
    """Where the body's states come from, in words."""
    if isinstance(body, SmallBody):
        return f"Keplerian orbit from osculating elements: {body.source}"
    return "JPL DE421 (jplephem), heliocentric, ecliptic of J2000"


@functools.lru_cache(maxsize=None)
def _track(key):
    return track_of(key, *(jd_from_iso(d) for d in TRACK_SPAN))


def track(body):
    """The body's smooth track over :data:`TRACK_SPAN` (``bodies.track.Track``)."""
    return _track(_key(body))


def polar_state(body, jd, field="body", jd2=0.0):
    """Exact polar state [r, theta, v_r, v_theta] (canonical) at Julian date ``jd`` (TDB;
    plus ``jd2`` days, a date's second part) with theta on the track's branch, and the
    out-of-plane distance z (au)."""
    body = _key(body)
    if isinstance(body, SmallBody):
        x, z = body.polar_state(jd, field, jd2)
    else:
        x, z = ephemeris.polar_state(body, jd, field, jd2)
    x = np.array(x, float).ravel()
    branch = float(np.ravel(track(body).polar(tu_from_jd(jd + jd2)))[1])
    x[1] += 2 * math.pi * round((branch - x[1]) / (2 * math.pi))
    return x, float(z)


def polar_state_at(body, t, field="body"):
    """:func:`polar_state` at canonical time ``t`` (TU since J2000 TDB), the date kept in
    two parts (``dates.jd_split_from_tu``) whose microseconds the verification and the polish
    need: a metre of a planet's motion is a few tens of them."""
    jd, days = jd_split_from_tu(float(t))
    return polar_state(body, jd, field, days)


def track_correction(body, t):
    """The body's exact polar state less its smooth track's at time ``t`` (TU since J2000
    TDB): tens of metres, which the polish adds so that its 1 m holds against the source."""
    exact, _ = polar_state_at(body, t)
    return exact - np.ravel(track(body).polar(float(t)))


@functools.lru_cache(maxsize=None)
def _mean_radius(key):
    if isinstance(key, SmallBody):
        return float(key.a_au)
    # The osculating semimajor axis at J2000: what the seeding propagation aims at.
    x, _ = ephemeris.polar_state(key, jd_from_tu(0.0))
    r, vr, vt = x[0], x[2], x[3]
    return float(1.0 / (2.0 / r - (vr * vr + vt * vt)))


def mean_radius_au(body):
    """A representative orbit radius of the body, au (the osculating semimajor axis)."""
    return _mean_radius(_key(body))


def check_span(jd, field):
    """Raise InputError, naming ``field``, if ``jd`` lies outside what the tracks cover
    (:data:`TRACK_SPAN`); return ``jd``."""
    return check_tracked(jd, field)


# ------------------------------------------------------------------- in three dimensions


def ecliptic_state(body, jd, field="body", jd2=0.0):
    """Exact heliocentric ecliptic-J2000 state ``[x, y, z, vx, vy, vz]`` (au, au/TU), shape
    (6,) or (6, M), at Julian date(s) ``jd`` (TDB) plus ``jd2`` days; projected, it is
    :func:`polar_state`'s but for theta's branch."""
    body = _key(body)
    if isinstance(body, SmallBody):
        return body.ecliptic_state(jd, field, jd2)
    return ephemeris.ecliptic_state(body, jd, field, jd2)


def ecliptic_state_at(body, t, field="body"):
    """:func:`ecliptic_state` at canonical time ``t`` (TU since J2000 TDB), the date kept
    in two parts as in :func:`polar_state_at`."""
    jd, days = jd_split_from_tu(float(t))
    return ecliptic_state(body, jd, field, days)


@functools.lru_cache(maxsize=None)
def _track3(key):
    return track3_on(_track(key), key, refine=True)


def track3(body):
    """The body's smooth 3-D track over :data:`TRACK_SPAN` (``bodies.track.Track3``) on
    :func:`track`'s samples, unless z needed finer ones (then the two agree to tens of
    metres)."""
    return _track3(_key(body))


def track3_correction(body, t):
    """The body's exact ecliptic state less its smooth 3-D track's at time ``t`` (TU since
    J2000 TDB): :func:`track_correction` in three dimensions."""
    return ecliptic_state_at(body, t) - np.ravel(track3(body).state(float(t)))
