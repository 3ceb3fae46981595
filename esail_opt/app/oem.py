"""A flown trajectory as a CCSDS Orbit Ephemeris Message (OEM, CCSDS 502.0-B) in KVN, as
GMAT, Orekit, STK and SPICE's ``mkspk`` read it: centre ``SUN``, TDB to the microsecond
(2 cm at 40 km/s), km and km/s to 15 digits (0.5 mm within 6.7 au), written through the
``oem`` package (imported on first use) so that the layout is that library's reading of
the standard.  The frame is DE421's ICRF (:func:`~esail_opt.bodies.ephemeris.icrf_from_ecliptic`),
so that a body's DE421 state reads back as DE421's own.  Each schedule segment is a data
segment of its own: a polynomial across a thrust switch would smear the jump in
acceleration (hundreds of km at a day's spacing).
"""

import datetime as _dt
from pathlib import Path

import numpy as np

from esail_opt.runtime.files import atomic_path
from esail_opt.bodies.dates import TIME_SCALE, jd_from_iso
from esail_opt.bodies.ephemeris import icrf_from_ecliptic
from esail_opt.errors import InputError
from esail_opt.physics import constants as units

#: The version of the standard written (the ``oem`` package's current one).
OEM_VERSION = "2.0"
CENTER_NAME = "SUN"
REF_FRAME = "ICRF"
TIME_SYSTEM = TIME_SCALE
#: The epochs' format, as the ``oem`` package writes them.
EPOCH_FORMAT = "%Y-%m-%dT%H:%M:%S.%f"
#: Hermite interpolation of degree 7 (four samples, positions and velocities) within a
#: data segment: on a day's spacing it follows a flight to well under a metre.
INTERPOLATION = "HERMITE"
INTERPOLATION_DEGREE = 7


def states_km_km_s(states):
    """Canonical states (6, N), au and au/TU, in km and km/s (what :func:`write_oem` takes)."""
    values = np.array(states, dtype=float)
    values[:3] = units.length_to_km(values[:3])
    values[3:] = units.speed_to_km_s(values[3:])
    return values


def write_oem(path, object_name, epochs, states_km_kms_ecliptic, *, jd2=0.0, object_id=None,
              originator="esail_opt", creation_date=None, breaks=(), comments=()):
    """Write a trajectory to ``path`` (renamed onto it whole, its folder created) as a CCSDS
    OEM in KVN, heliocentric ICRF, TDB, km and km/s.

    ``epochs`` (N, strictly increasing) are ISO 8601 dates read as TDB (:func:`jd_from_iso`,
    about 40 us) or Julian dates (TDB); ``jd2`` (days, one or N) is added to each, keeping
    the microseconds one float of a Julian date loses.  ``states_km_kms_ecliptic`` (6, N) is
    ``[x, y, z, vx, vy, vz]`` in the ecliptic of J2000, km and km/s (:func:`states_km_km_s`).
    ``object_id`` is ``object_name`` by default (a planned sail has no designator),
    ``creation_date`` (UTC) now.  ``breaks``: sample indices where the thrust switches, each
    ending one data segment and starting the next.  ``comments``: one-line ``COMMENT`` lines
    after the version line.  Raises InputError naming ``oem.<argument>`` for states not
    (6, N) or not finite, epochs of another count, not finite or not increasing at the
    microsecond, or a name or comment that is empty or spans lines.
    """
    states = _checked_states(states_km_kms_ecliptic)
    count = states.shape[1]
    edges = [0] + sorted({int(b) for b in breaks if 0 < int(b) < count - 1}) + [count - 1]
    stamps = _epochs(epochs, jd2, count)
    fields = {"object_name": object_name, "object_id": object_name if object_id is None else object_id,
              "originator": originator}
    lines = {f"comments[{k}]": c for k, c in enumerate(comments)}
    for key, value in {**fields, **lines}.items():
        if not isinstance(value, str) or not value.strip() or "\n" in value or "\r" in value:
            raise InputError(f"oem.{key} = {value!r} must be a non-empty one-line string")
    created = creation_date or _dt.datetime.now(_dt.timezone.utc)
    message = _message(fields, created.strftime("%Y-%m-%dT%H:%M:%S"), stamps,
                       icrf_from_ecliptic(states), edges)
    with atomic_path(path) as tmp:
        message.save_as(tmp, file_format="kvn")
        if comments:
            _insert_comments(tmp, comments)


def _insert_comments(path, comments):
    """COMMENT lines right after ``CCSDS_OEM_VERS``, where the standard puts the
    header's comments (the ``oem`` package reads them and writes none)."""
    text = Path(path).read_text().splitlines(keepends=True)
    block = "".join(f"COMMENT {c}\n" for c in comments)
    Path(path).write_text(text[0] + block + "".join(text[1:]))


def _checked_states(states):
    values = np.asarray(states, dtype=float)
    if values.ndim != 2 or values.shape[0] != 6 or values.shape[1] < 1:
        raise InputError(f"oem.states has shape {values.shape}; expected (6, N), N >= 1: "
                         "x, y, z (km) and vx, vy, vz (km/s) by rows")
    if not np.all(np.isfinite(values)):
        raise InputError("oem.states holds a value that is not finite")
    return values


def _epochs(epochs, jd2, count):
    """The epochs (TDB, two-part Julian dates), checked and rounded to the microsecond by
    astropy, as naive datetimes read back from that text, which the ``oem`` writer formats
    to the same text: formatting astropy Time scalars one by one cost most of the writing."""
    from astropy.time import Time

    if isinstance(epochs, str):
        epochs = [epochs]
    listed = list(np.atleast_1d(np.asarray(epochs, dtype=object)))
    if len(listed) != count:
        raise InputError(f"oem.epochs has {len(listed)} dates for {count} states")
    if all(isinstance(e, str) for e in listed):
        first = np.array([jd_from_iso(e, f"oem.epochs[{k}]") for k, e in enumerate(listed)])
    else:
        try:
            first = np.asarray(listed, dtype=float)
        except (TypeError, ValueError):
            raise InputError("oem.epochs must be ISO 8601 dates or Julian dates (TDB)") from None
    extra = np.asarray(jd2, dtype=float)
    if extra.ndim > 1 or extra.size not in (1, count):
        raise InputError(f"oem.jd2 has {extra.size} values for {count} epochs")
    second = np.broadcast_to(extra, first.shape)
    if not (np.all(np.isfinite(first)) and np.all(np.isfinite(second))):
        raise InputError("oem.epochs holds a date that is not finite")
    text = list(Time(first, second, format="jd", scale="tdb", precision=6)
                .strftime(EPOCH_FORMAT))
    if count > 1 and not all(a < b for a, b in zip(text[:-1], text[1:])):
        raise InputError("oem.epochs must increase strictly, by at least a microsecond")
    return [_dt.datetime.fromisoformat(t) for t in text]


def _message(fields, created, stamps, states, edges):
    """The ``oem`` message, one data segment between each pair of consecutive ``edges``."""
    from oem import OrbitEphemerisMessage
    from oem.components import EphemerisSegment, HeaderSection, MetaDataSection

    header = HeaderSection({"CCSDS_OEM_VERS": OEM_VERSION, "CREATION_DATE": created,
                            "ORIGINATOR": fields["originator"]})
    segments = []
    for first, last in zip(edges[:-1], edges[1:]):
        part = slice(first, last + 1)
        metadata = MetaDataSection({
            "OBJECT_NAME": fields["object_name"], "OBJECT_ID": fields["object_id"],
            "CENTER_NAME": CENTER_NAME, "REF_FRAME": REF_FRAME, "TIME_SYSTEM": TIME_SYSTEM,
            "START_TIME": stamps[first].strftime(EPOCH_FORMAT),
            "STOP_TIME": stamps[last].strftime(EPOCH_FORMAT),
            **_interpolation(last - first + 1),
        }, version=OEM_VERSION)
        columns = (tuple(stamps[part]),) + tuple(tuple(float(v) for v in row[part])
                                                 for row in states)
        segments.append(EphemerisSegment(metadata, columns, version=OEM_VERSION))
    return OrbitEphemerisMessage(header, segments)


def _interpolation(samples):
    """The interpolation a data segment of ``samples`` states supports: Hermite of
    :data:`INTERPOLATION_DEGREE`, or of the highest odd degree its samples allow."""
    degree = min(INTERPOLATION_DEGREE, 2 * samples - 1)
    return {"INTERPOLATION": INTERPOLATION, "INTERPOLATION_DEGREE": str(degree)}
