"""The version of ``solution.json`` and what a reader of the file accepts.

A file carries ``schema_version``; :data:`SCHEMA_VERSION` is the one this code writes.
A version changes when a key is added, removed or changes meaning or unit.  A reader
accepts the versions of :data:`READABLE`: a key added after a file's version reads as
absent (None, or empty), and a key whose meaning changed is renamed by :func:`upgrade`
before the file is read.  Any other version is refused (:func:`check`) rather than
guessed at.

Each key is spelled once, on its field in :mod:`esail_opt.app.solution`.  Units are one
per quantity everywhere in the file, the polish included: lengths and position misses
in km (au for radii and semimajor axes), speeds and velocity misses in m/s (km/s for
state velocities), times in days, angles in degrees.  The layout of the current
version, and how each version differs from the one before, are in
``schema_changes.md`` beside this module.
"""

import numpy as np

from esail_opt.errors import InputError
from esail_opt.physics import constants as units

SCHEMA_VERSION = 7
#: Versions this code reads: versions 3 to 5 only added fields, so a version-2 file
#: reads as one of a problem off the calendar, a version-3 polish has no start of its
#: own, a file before version 5 names no classes, and a version-4 file is a planar one;
#: a version-5 file is read through :func:`upgrade`.
READABLE = (2, 3, 4, 5, 6, 7)


def check(data, source):
    """Raise InputError, naming ``source``, unless ``data`` is of a readable version."""
    found = data.get("schema_version", 1) if isinstance(data, dict) else None
    if found not in READABLE:
        raise InputError(f"{source}: solution.json schema version {found}, but this esail_opt "
                         f"reads versions {', '.join(map(str, READABLE))}; solve the problem "
                         "again to rewrite it")


def upgrade(data):
    """``data``, a readable ``solution.json``, with the keys of version 7 (those it added
    are read as absent): a 3-D flight of
    version 5 gave a target's ``out_of_plane_km`` (in ``target_body`` and in the
    verifications, the polish's included) as the flight's distance from the body along
    the ecliptic's normal, which is ``normal_miss_km`` now; the body's own distance from
    the ecliptic is then unknown (None)."""
    three_d = "x_au" in (data.get("final_state") or {})
    if data.get("schema_version") != 5 or not three_d:
        return data
    return _renamed(data)


def _renamed(value):
    if not isinstance(value, dict):
        return value
    out = {}
    for key, item in value.items():
        if key in ("target_body", "verification") and isinstance(item, dict) \
                and "out_of_plane_km" in item:
            item = {**item, "normal_miss_km": item["out_of_plane_km"], "out_of_plane_km": None}
        out[key] = _renamed(item)
    return out


#: The keys of a state in three dimensions, as a later version will give every state:
#: heliocentric, in the ecliptic of J2000, positions in au and velocities in km/s.
STATE_KEYS = ("x_au", "y_au", "z_au", "vx_km_s", "vy_km_s", "vz_km_s")


def state_fields(state):
    """A canonical state as the fields of :data:`STATE_KEYS`.

    Parameters
    ----------
    state : array_like, shape (6,) or (6, M)
        ``[x, y, z, vx, vy, vz]`` in au and au/TU, ecliptic of J2000.

    Returns
    -------
    dict
        Floats for one state; lists of M floats for M states (trajectory samples).
    """
    values = np.asarray(state, dtype=float)
    if values.shape[:1] != (6,) or values.ndim > 2:
        raise ValueError(f"a state has 6 components by rows, got shape {values.shape}")
    converted = np.concatenate([values[:3], units.speed_to_km_s(values[3:])])
    return {key: (row.tolist() if values.ndim == 2 else float(row))
            for key, row in zip(STATE_KEYS, converted)}


def state_from_fields(fields, source):
    """The canonical state (6,) or (6, M) that :func:`state_fields` wrote.

    Raises InputError, naming ``source`` and the key, if a key is missing or a value is
    not a finite number.
    """
    if not isinstance(fields, dict):
        raise InputError(f"{source} = {fields!r} is not an object with {', '.join(STATE_KEYS)}")
    rows = []
    for key in STATE_KEYS:
        if key not in fields:
            raise InputError(f"{source}.{key} is missing")
        try:
            row = np.asarray(fields[key], dtype=float)
        except (TypeError, ValueError):
            row = np.array(np.nan)
        if row.ndim > 1 or not np.all(np.isfinite(row)):
            raise InputError(f"{source}.{key} = {fields[key]!r} is not a finite number "
                             "(or list of them)")
        rows.append(row)
    if len({row.shape for row in rows}) != 1:
        raise InputError(f"{source}: {', '.join(STATE_KEYS)} differ in length")
    state = np.array(rows)
    state[3:] = units.speed_from_km_s(state[3:])
    return state

