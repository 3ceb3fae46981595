"""The schema of ``solution.json``: its version, and what each field holds.

This is the one place the file's layout is written down. Only the records of
:mod:`esail_opt.app.solution` name these keys, each on its field; the plot, search and
sweep modules read the typed Solution's fields, named as the keys are except where
``Solution``'s docstring says otherwise. Units are one per
quantity everywhere in the file, the polish included: lengths and position misses in km
(au for radii and semimajor axes), speeds and velocity misses in m/s (km/s for state
velocities), times in days, angles in degrees.

How each version differs from the one before is told in ``schema_changes.md`` beside
this module.

Top level
---------
schema_version : int
    :data:`SCHEMA_VERSION`.
problem : object
    The settings as solved: ``name``, ``description``, ``ac_mm_s2``, ``coefficients``,
    ``alpha_bounds_deg``, ``segments`` (the count N used), ``segments_per_revolution``,
    ``sub_arcs`` (what the error control ended with), ``sub_arcs_requested``,
    ``equal_segments``, ``objective`` (its kind), ``target`` (``kind`` and fields, or
    null), ``departure`` (``kind`` and fields), ``departure_state``, ``r_min_au``,
    ``q3_margin``, and ``throttle_bounds`` for a throttled sail.  ``departure_state``
    is the state the schedule is flown from.
status, outcome, converged, acceptable : str, str, bool, bool
    Ipopt's return status of the last solve; its ``Outcome`` (``optimisation.outcome``)
    as a word, "converged" / "acceptable" / "infeasible" / "failed"; whether that is
    converged; whether it is acceptable.
verified, verification_note : bool, str
    Converged, and the CVODES flight meets ``tolerance`` with the verifier's own error
    added; one line naming each missed bound.
tolerance : object
    ``position_km``, ``velocity_m_s``.
objective, objective_meaning : float, str
    The NLP's objective (canonical units) and what it means.
tof_days, iterations, stages, solve_seconds, constraint_violation, min_q3
    Time of flight; Ipopt iterations and seconds summed over every solve of the run;
    each stage's status and iterations; the final constraint violation; the smallest
    closed-form validity margin q3.
schedule : list of object
    Per segment: ``t_days`` and ``theta_deg`` at its start, ``alpha_deg`` in [-90, 90),
    ``duration_days``, ``dtheta_deg``, ``local_error_km`` (the closed form's position
    error over the segment against Eqs. 1-2 from the same start node) and, for a
    throttled sail, ``throttle``.
final_state : object
    The NLP's final state: ``r_au``, ``theta_deg``, ``vr_km_s``, ``vtheta_km_s``,
    ``a_au``, ``e``.
verification : object
    The CVODES flight: ``miss_r_km``, ``miss_v_m_s``, ``miss_theta_deg`` against the NLP's
    final state; ``target_miss_r_km``, ``target_miss_v_m_s`` against the target (an (a, e)
    target adds ``target_miss_a_km`` and ``target_miss_e``); ``nlp_target_miss_r_km``;
    ``verifier_error_r_km``, ``verifier_error_v_m_s`` (two CVODES flights at 3e-16 and
    1e-15 apart; in 3-D, plus the gap to a flight on the Cartesian equations); ``error``; ``cvodes_final_state``, ``cvodes_tof_days``; for a target
    with an arrival window, ``arrival_outside_window_days`` (0 inside it; a flight more
    than a second outside is not verified).
refinement : object
    The error control's record (the key is older than the stage's name): ``rounds``
    (per round: sub-arcs, status, iterations, tof and misses; empty when the closed form
    found no optimum) and ``starts`` (``label``, ``status``, ``iterations`` of each start
    tried when the first found no optimum).
trajectory : object
    ``closed_form`` and ``cvodes`` samples (``r_au``, ``theta_deg``, ``vr_km_s``,
    ``vtheta_km_s``, ``a_au``, ``e``, ``t_days``), and ``polished`` after a polish.

On the calendar (a BodyDeparture; absent otherwise)
---------------------------------------------------
departure_date, arrival_date : str
    ISO 8601, TDB, to the millisecond (``YYYY-MM-DDTHH:MM:SS.sss``, the fraction left
    out when it is zero); the arrival is the departure plus the NLP's time of flight.
departure_epoch_days : float
    The departure's epoch, days since J2000 (2000-01-01T12:00:00 TDB), as solved: to a
    fraction of a microsecond, where the date is rounded to the millisecond (a
    planet moves some 35 m in one).  With ``tof_days`` (``polish.tof_days`` for the
    polished flight) it gives the arrival to the same precision, so that a 1 m
    polish can be checked from the file.
departure_body : object
    ``name``, ``source`` (the ephemeris or the elements), ``out_of_plane_km`` (the body's
    distance from the ecliptic at departure, which the 2-D model drops), ``vinf_km_s`` and
    ``vinf_angle_deg`` (from the local horizontal towards radial outward).
target_body : object
    For a BodyRendezvous or BodyIntercept: ``name``, ``source``, ``kind``,
    ``out_of_plane_km`` (the body's distance from the ecliptic at the flown arrival),
    ``relative_speed_km_s`` of the flight against the body there and, in 3-D,
    ``normal_miss_km`` (the flight's distance from the body along the ecliptic's
    normal; also in the verification's misses).
ac_mm_s2_required : float
    For a MinAcceleration objective: the characteristic acceleration found, mm/s^2.  A
    run that found no point (``outcome`` "infeasible" or "failed") gives its last
    iterate's, which its schedule's throttles are fractions of: no sail is required
    by it (see ``nearest_feasible``).

Classes and the edge of the feasible (version 5)
------------------------------------------------
classes : object
    ``looked_at``: per turn count k on the target body that the solve looked at (a
    MinTime or MinAcceleration rendezvous; empty otherwise): ``revolutions_k``,
    ``label``, ``status``, ``iterations``, ``objective`` (canonical, as the top-level
    one), ``tof_days``, ``ac_mm_s2_required`` (MinAcceleration), ``constraint_violation``
    (of its last point), ``verified`` (null when not flown), ``chosen`` and
    ``projected`` (true when its values are the projected model's: a 3-D run's class
    that was not solved in 3-D; absent otherwise); and
    ``not_looked_at``, one line on the classes not solved.
nearest_feasible : object
    Only for a fixed-time solve that found no point: ``departure_date`` (null off the
    calendar), ``tof_days``, ``ac_mm_s2_required``, ``verified``, ``note``,
    ``infeasible_tof_days`` (the longest time of flight found infeasible: the edge lies
    between the two) and ``iterations`` (of the walk that found it).

After a polish
--------------
objective_closed_form, objective_exact, tof_days_exact
polish : object
    ``status``, ``converged``, ``outcome``, ``iterations``, ``seconds``,
    ``constraint_violation``, ``objective``, ``tof_days``, ``bounds`` (``position_km``,
    ``velocity_m_s``: 1 m and 1 mm/s), ``within_bounds_vs_nlp``,
    ``within_bounds_vs_target``, ``verified``, ``note``, ``schedule``, ``final_state``,
    ``verification`` (the keys of the top-level one), and the polished flight's own
    ``departure_state`` and (as at the top level, where they apply)
    ``departure_date``, ``arrival_date``, ``departure_body``, ``target_body`` and
    ``ac_mm_s2_required``: ``schedule`` flown from ``departure_state`` is the flight
    verified.  The top-level ``verified`` judges the closed form's flight alone; the
    command's exit status is 0 only when ``polish.verified`` holds too.
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

