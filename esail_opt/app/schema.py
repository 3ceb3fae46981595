"""The version of ``solution.json`` and what a reader of the file accepts.

A file carries ``schema_version``; :data:`SCHEMA_VERSION` is the one this code writes.  A
version changes when a key is added, removed or changes meaning or unit.  A reader accepts
the versions of :data:`READABLE` (a key added later reads as absent, None or empty; one
whose meaning changed is renamed by :func:`upgrade`) and refuses any other (:func:`check`).
Each key is spelled once, on its field in :mod:`esail_opt.app.solution`.  One unit per
quantity, the polish included: lengths and position misses in km (au for radii and
semimajor axes), speeds and velocity misses in m/s (km/s for state velocities), times in
days, angles in degrees.  The layout and each version's changes: ``schema_changes.md``.
"""

import numpy as np

from esail_opt.errors import InputError
from esail_opt.physics import constants as units

SCHEMA_VERSION = 8
#: Versions this code reads (``schema_changes.md``); a version-5 file through :func:`upgrade`.
READABLE = (2, 3, 4, 5, 6, 7, 8)


def check(data, source):
    """Raise InputError, naming ``source``, unless ``data`` is of a readable version."""
    found = data.get("schema_version", 1) if isinstance(data, dict) else None
    if found not in READABLE:
        raise InputError(f"{source}: solution.json schema version {found}, but this esail_opt "
                         f"reads versions {', '.join(map(str, READABLE))}; solve the problem "
                         "again to rewrite it")


def upgrade(data):
    """``data``, a readable ``solution.json``, with the keys of version 8: a 3-D version-5
    file's ``out_of_plane_km`` becomes ``normal_miss_km`` (version 6 in
    ``schema_changes.md``), the body's own distance from the ecliptic None."""
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


#: The keys of a 3-D state: heliocentric, ecliptic of J2000, au and km/s.
STATE_KEYS = ("x_au", "y_au", "z_au", "vx_km_s", "vy_km_s", "vz_km_s")


def state_fields(state):
    """A canonical state, (6,) or (6, M) ``[x, y, z, vx, vy, vz]`` in au and au/TU (ecliptic
    of J2000), as the fields of :data:`STATE_KEYS`: floats, or lists of M floats."""
    values = np.asarray(state, dtype=float)
    if values.shape[:1] != (6,) or values.ndim > 2:
        raise ValueError(f"a state has 6 components by rows, got shape {values.shape}")
    converted = np.concatenate([values[:3], units.speed_to_km_s(values[3:])])
    return {key: (row.tolist() if values.ndim == 2 else float(row))
            for key, row in zip(STATE_KEYS, converted)}


def state_from_fields(fields, source):
    """The canonical state (6,) or (6, M) that :func:`state_fields` wrote; InputError,
    naming ``source`` and the key, for a key missing or a value not a finite number."""
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

