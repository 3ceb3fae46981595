"""Layer 2, bodies and time: dates (ISO 8601, TDB), planets from DE421 in the ecliptic of
J2000, small bodies on Keplerian orbits, and smooth tracks of their states for the NLP.

Imports only :mod:`esail_opt.physics` and :mod:`esail_opt.errors`.
"""

from esail_opt.bodies.dates import J2000_JD, iso_from_jd, jd_from_iso, jd_from_tu, tu_from_jd
from esail_opt.bodies.ephemeris import (
    OBLIQUITY_J2000,
    PLANETS,
    SPAN_JD,
    ecliptic_state,
    polar_from_ecliptic,
    polar_state,
)
from esail_opt.bodies.keplerian import BENNU, CERES, SMALL_BODIES, SmallBody, eccentric_anomaly
from esail_opt.bodies.track import Track, track_of

__all__ = [
    "J2000_JD", "jd_from_iso", "iso_from_jd", "tu_from_jd", "jd_from_tu",
    "PLANETS", "SPAN_JD", "OBLIQUITY_J2000", "ecliptic_state", "polar_state",
    "polar_from_ecliptic",
    "SmallBody", "BENNU", "CERES", "SMALL_BODIES", "eccentric_anomaly",
    "Track", "track_of",
]
