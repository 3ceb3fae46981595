"""Dates: the one place where calendar dates become times and back.

A date is ISO 8601, ``YYYY-MM-DD``, ``YYYY-MM-DDTHH:MM`` or ``YYYY-MM-DDTHH:MM:SS[.fff]``
(a space may stand for the ``T``), read as **TDB**, the ephemeris's time scale.  A trailing
``TDB`` is accepted; a ``Z`` or a UTC offset is refused, since UTC is not converted.  A UTC
date read as TDB is about 69 s late, at most a few thousand km of a planet's motion: a
fraction of a 10,000 km rendezvous tolerance.  Canonical time is TU
(``esail_opt.physics.constants.TU_DAYS`` days) since J2000.0, 2000-01-01T12:00:00 TDB.
"""

import datetime as _dt
import math
import re

import numpy as np

from esail_opt.errors import InputError
from esail_opt.physics import constants as units

#: Julian date of the epoch J2000.0 (2000-01-01T12:00:00 TDB).
J2000_JD = 2451545.0
#: The time scale of every date read and written: the ephemeris's.
TIME_SCALE = "TDB"

#: The form a date must have, as told to a user whose date is refused.
ISO_FORM = "YYYY-MM-DD[THH:MM[:SS]]"

# JD of 2000-01-01T00:00:00, the origin of the proleptic Gregorian day count below.
_JD_2000_MIDNIGHT = J2000_JD - 0.5
_ORDINAL_2000 = _dt.date(2000, 1, 1).toordinal()

#: The dates (TDB) every date a problem gives must lie in (departures, arrivals, scans, a
#: small body's epoch): the span of the bodies' tracks (``bodies.lookup``).
TRACK_SPAN = ("2000-01-01", "2060-01-01")

_PATTERN = re.compile(
    r"(\d{4})-(\d{2})-(\d{2})"
    r"(?:[T ](\d{2}):(\d{2})(?::(\d{2})(\.\d+)?)?)?"
    r"(?:\s*TDB)?"
)


def jd_from_iso(text, field="date"):
    """Julian date (TDB) of an ISO 8601 date (proleptic Gregorian, read as TDB); a date
    without a time is at 00:00:00, JD ``N.5``.  ``field`` names the date in messages.

    Raises InputError if ``text`` is not such a date, names a day that does not exist
    (2030-02-30), an hour past 23, a minute or second past 59 (TDB has no leap seconds),
    or carries a UTC marker.
    """
    if not isinstance(text, str):
        raise InputError(f"{field} = {text!r} is not an ISO 8601 date ({ISO_FORM})")
    stripped = text.strip()
    match = _PATTERN.fullmatch(stripped)
    if match is None:
        if stripped.endswith("Z") or re.search(r"[+-]\d{2}:?\d{2}$", stripped[10:]):
            raise InputError(
                f"{field} = {text!r} carries a time zone; dates are read as TDB, "
                f"write {ISO_FORM} without Z or an offset"
            )
        raise InputError(f"{field} = {text!r} is not an ISO 8601 date ({ISO_FORM})")
    year, month, day, hour, minute, second, fraction = match.groups()
    try:
        date = _dt.date(int(year), int(month), int(day))
        clock = _dt.time(int(hour or 0), int(minute or 0), int(second or 0))
    except ValueError:
        raise InputError(f"{field} = {text!r} is not an ISO 8601 date ({ISO_FORM})") from None
    seconds = clock.hour * 3600 + clock.minute * 60 + clock.second
    if fraction:
        seconds += float(fraction)
    days = date.toordinal() - _ORDINAL_2000
    return _JD_2000_MIDNIGHT + days + seconds / units.DAY


def iso_from_jd(jd):
    """ISO 8601 date ``YYYY-MM-DDTHH:MM:SS[.fff]`` (TDB) of a Julian date, rounded to the
    millisecond (written only when not zero): a second of a planet's motion is some 30 km,
    more than a verified miss may be.  InputError if ``jd`` is not a finite number or lies
    outside the years 1-9999."""
    try:
        value = float(jd)
    except (TypeError, ValueError):
        raise InputError(f"jd = {jd!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(f"jd = {jd!r} is not a finite Julian date")
    # Days and seconds split before rounding: no float holds the seconds since year 1.
    days_from_2000 = value - _JD_2000_MIDNIGHT
    whole = math.floor(days_from_2000)
    milliseconds = round((days_from_2000 - whole) * units.DAY * 1000)
    try:
        stamp = (_dt.datetime.fromordinal(_ORDINAL_2000 + whole)
                 + _dt.timedelta(milliseconds=milliseconds))
    except (ValueError, OverflowError):
        raise InputError(f"jd = {jd!r} is outside the years 1-9999") from None
    text = f"{stamp.year:04d}-{stamp.month:02d}-{stamp.day:02d}T{stamp:%H:%M:%S}"
    return text + (f".{stamp.microsecond // 1000:03d}" if stamp.microsecond else "")


def tu_from_jd(jd):
    """Canonical time (TU since J2000.0 TDB) of a Julian date (float, or numpy array of
    any shape)."""
    return _same_kind(units.time_from_days(np.asarray(jd, dtype=float) - J2000_JD), jd)


def jd_from_tu(t):
    """Julian date (TDB) of a canonical time in TU since J2000.0 (float or numpy array)."""
    return _same_kind(J2000_JD + units.time_to_days(np.asarray(t, dtype=float)), t)


def jd_split_from_tu(t):
    """A canonical time as a Julian date in two parts, (J2000's JD, days since J2000), that
    keep the microseconds one float of a Julian date rounds away."""
    return J2000_JD, _same_kind(units.time_to_days(np.asarray(t, dtype=float)), t)


def _same_kind(value, like):
    return float(value) if np.ndim(like) == 0 else value


def check_tracked(jd, field):
    """Return the Julian date ``jd`` if it lies in :data:`TRACK_SPAN`, else raise
    InputError naming ``field`` and the span."""
    lo, hi = (jd_from_iso(day) for day in TRACK_SPAN)
    if not lo <= jd <= hi:  # NaN is refused too
        shown = iso_from_jd(jd) if math.isfinite(jd) else repr(jd)
        raise InputError(f"{field} = {shown} is outside the dates esail_opt tracks bodies "
                         f"on, [{TRACK_SPAN[0]}, {TRACK_SPAN[1]}] (TDB)")
    return jd
