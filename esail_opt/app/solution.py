"""A solved problem, in the boundary's units: its typed record, its files and its summary.

:func:`solve` runs the pipeline (``optimisation.pipeline``) and returns the
:class:`Solution` of its :class:`~esail_opt.optimisation.pipeline.Run`; it is what
``esail-opt solve`` and scripts call.  This module runs no stage itself: it only turns a
Run into boundary units and writes and reads it.

A Solution is typed: every part of ``solution.json`` is a field of a frozen dataclass
here, and :meth:`Solution.to_json` and :meth:`Solution.from_json` are the only places
that know the file's keys (:mod:`esail_opt.app.schema` documents them).  A fresh
Solution is made from its run's JSON form by the same :meth:`~Solution.from_json` that
reads a file back (:meth:`Solution.of`), so a solution loaded from disk prints, plots
and writes exactly as the one that wrote it.
"""

import csv
import dataclasses
import functools
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Tuple

import casadi as ca
import numpy as np

from esail_opt.app import schema
from esail_opt.app.files import json_ready, publish, write_json
from esail_opt.app.oem import states_km_km_s, write_oem
from esail_opt.bodies import dates, lookup
from esail_opt.errors import FigureError, InputError
from esail_opt.optimisation import pipeline
from esail_opt.optimisation.pipeline import Outcome, Round, StartTried
from esail_opt.optimisation.transcription import node_cartesian
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_from_polar

SCHEDULE_FIELDS = ("t_days", "theta_deg", "alpha_deg", "duration_days", "dtheta_deg")
#: The column a throttled problem adds: kappa per segment, in [0, 1].  Unthrottled
#: schedules leave it out, so their files stay as they were.
THROTTLE_FIELD = "throttle"
#: The closed form's local error per segment, km (absent from polished schedules).
LOCAL_ERROR_FIELD = "local_error_km"
#: The column a problem flown in three dimensions adds: the clock angle, deg.
CLOCK_FIELD = "clock_deg"
#: Every file :meth:`Solution.write` may put in its folder: the set that a new write
#: replaces whole (anything else in the folder is the user's and stays).
SOLUTION_FILES = ("solution.json", "schedule.csv", "schedule_polished.csv",
                  "trajectory.png", "timeline.png", "trajectory.oem")
STATE_FIELDS = ("r_au", "theta_deg", "vr_km_s", "vtheta_km_s", "a_au", "e")
#: What a 3-D flight's samples add: the Cartesian state (``schema.STATE_KEYS``) and the
#: osculating plane, deg.
PLANE_FIELDS = ("inclination_deg", "node_deg")


def _three_d_part(d, keys):
    """The keys of ``d`` among ``keys``, or None when it has none of them (a planar
    record, or a file of schema version 4)."""
    return {k: d[k] for k in keys if k in d} or None
#: The misses every verification writes, in the file's order (a target's own extras,
#: such as an (a, e) target's ``target_miss_a_km``, follow them).
CORE_MISSES = ("miss_r_km", "miss_v_m_s", "miss_theta_deg", "verifier_error_r_km",
               "verifier_error_v_m_s", "target_miss_r_km", "target_miss_v_m_s")


def _bad_file(source, what):
    return InputError(f"{source}: solution.json {what}; solve the problem again to rewrite it")


# ---------------------------------------------------------------- the typed record


@dataclass(frozen=True)
class State:
    """A polar state in boundary units, with its osculating a and e."""

    r_au: Optional[float]
    theta_deg: Optional[float]
    vr_km_s: Optional[float]
    vtheta_km_s: Optional[float]
    a_au: Optional[float]
    e: Optional[float]
    # In three dimensions: x_au .. vz_km_s in the ecliptic of J2000 (``schema.STATE_KEYS``).
    cartesian: Optional[Dict[str, float]] = None

    @classmethod
    def from_json(cls, d):
        return cls(**{k: d[k] for k in STATE_FIELDS},
                   cartesian=_three_d_part(d, schema.STATE_KEYS))

    def to_json(self):
        return {**{k: getattr(self, k) for k in STATE_FIELDS}, **(self.cartesian or {})}


@dataclass(frozen=True)
class Samples:
    """A sampled flight, boundary units, one list per quantity (None where NaN)."""

    r_au: List[Optional[float]]
    theta_deg: List[Optional[float]]
    vr_km_s: List[Optional[float]]
    vtheta_km_s: List[Optional[float]]
    a_au: List[Optional[float]]
    e: List[Optional[float]]
    t_days: List[Optional[float]]
    # A 3-D flight's Cartesian samples and osculating plane (``PLANE_FIELDS``).
    three_d: Optional[Dict[str, list]] = None

    FIELDS = STATE_FIELDS + ("t_days",)

    @classmethod
    def from_json(cls, d):
        if d is None:
            return None
        return cls(**{k: list(d[k]) for k in cls.FIELDS},
                   three_d=_three_d_part(d, schema.STATE_KEYS + PLANE_FIELDS))

    def to_json(self):
        return {**{k: list(getattr(self, k)) for k in self.FIELDS}, **(self.three_d or {})}


@dataclass(frozen=True)
class Segment:
    """One row of a schedule: its start, pitch and length; ``throttle`` only for a
    throttled problem, ``local_error_km`` only on an error-controlled closed form."""

    t_days: float
    theta_deg: float
    alpha_deg: float
    duration_days: float
    dtheta_deg: float
    throttle: Optional[float] = None
    local_error_km: Optional[float] = None
    clock_deg: Optional[float] = None

    @classmethod
    def from_json(cls, d):
        return cls(**{k: d[k] for k in SCHEDULE_FIELDS},
                   throttle=d.get(THROTTLE_FIELD), local_error_km=d.get(LOCAL_ERROR_FIELD),
                   clock_deg=d.get(CLOCK_FIELD))

    def to_json(self, throttled, local_error):
        out = {k: getattr(self, k) for k in SCHEDULE_FIELDS}
        if self.clock_deg is not None:
            out[CLOCK_FIELD] = self.clock_deg
        if throttled:
            out[THROTTLE_FIELD] = self.throttle
        if local_error:
            out[LOCAL_ERROR_FIELD] = self.local_error_km
        return out


@dataclass(frozen=True)
class Schedule:
    """A schedule's rows, and which of the optional columns it carries (a column may
    be present with null values: a segment CVODES could not fly has no local error)."""

    rows: Tuple[Segment, ...]
    throttled: bool
    local_errors: bool

    @classmethod
    def from_json(cls, rows):
        first = rows[0] if rows else {}
        return cls(tuple(Segment.from_json(r) for r in rows), THROTTLE_FIELD in first,
                   LOCAL_ERROR_FIELD in first)

    def to_json(self):
        return [r.to_json(self.throttled, self.local_errors) for r in self.rows]

    def __iter__(self):
        return iter(self.rows)

    def __len__(self):
        return len(self.rows)

    def __getitem__(self, i):
        return self.rows[i]


@dataclass(frozen=True)
class Bounds:
    """A position and a velocity bound, km and m/s."""

    position_km: float
    velocity_m_s: float

    @classmethod
    def from_json(cls, d):
        return cls(d["position_km"], d["velocity_m_s"])

    def to_json(self):
        return {"position_km": self.position_km, "velocity_m_s": self.velocity_m_s}


@dataclass(frozen=True)
class Flight:
    """The CVODES verification of a schedule: its misses against the NLP's final state
    and the target, the verifier's own error, and the flown final state.

    ``extra`` holds a target's own misses beyond :data:`CORE_MISSES` (an (a, e)
    target's ``target_miss_a_km`` and ``target_miss_e``, a body's
    ``relative_speed_km_s`` and ``out_of_plane_km``), by their file names: which ones
    exist depends on the target's kind.
    """

    miss_r_km: Optional[float]
    miss_v_m_s: Optional[float]
    miss_theta_deg: Optional[float]
    verifier_error_r_km: Optional[float]
    verifier_error_v_m_s: Optional[float]
    target_miss_r_km: Optional[float]
    target_miss_v_m_s: Optional[float]
    nlp_target_miss_r_km: Optional[float] = None
    extra: Dict[str, Optional[float]] = dataclasses.field(default_factory=dict)
    error: Optional[str] = None
    cvodes_final_state: Optional[State] = None
    cvodes_tof_days: Optional[float] = None

    @classmethod
    def from_json(cls, d):
        known = set(CORE_MISSES) | {"nlp_target_miss_r_km", "error", "cvodes_final_state",
                                    "cvodes_tof_days"}
        state = d.get("cvodes_final_state")
        return cls(**{k: d[k] for k in CORE_MISSES},
                   nlp_target_miss_r_km=d.get("nlp_target_miss_r_km"),
                   extra={k: v for k, v in d.items() if k not in known},
                   error=d.get("error"),
                   cvodes_final_state=None if state is None else State.from_json(state),
                   cvodes_tof_days=d.get("cvodes_tof_days"))

    def to_json(self):
        out = {k: getattr(self, k) for k in CORE_MISSES}
        out.update(self.extra)
        # A failed flight has no final state, nor an NLP-to-target miss of its own.
        if self.error is None:
            out["nlp_target_miss_r_km"] = self.nlp_target_miss_r_km
        out["error"] = self.error
        if self.error is None:
            out["cvodes_final_state"] = self.cvodes_final_state.to_json()
            out["cvodes_tof_days"] = self.cvodes_tof_days
        return out

    def miss(self, name):
        """A target's own miss by its file name (None when it has none of that name)."""
        return self.extra.get(name)


class Part:
    """A problem part (departure or target) as solved: its kind and its fields, which
    depend on the kind (``part.a_au`` of a ParkingOrbit, ``part.body`` of a
    BodyDeparture; a body is given as its description)."""

    __slots__ = ("kind", "fields")

    def __init__(self, kind, fields):
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "fields", dict(fields))

    def __setattr__(self, name, value):
        raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")

    def __getattr__(self, name):
        try:
            return object.__getattribute__(self, "fields")[name]
        except (KeyError, AttributeError):
            raise AttributeError(f"{type(self).__name__} has no field {name!r}") from None

    def __eq__(self, other):
        return (isinstance(other, Part) and self.kind == other.kind
                and self.fields == other.fields)

    def __repr__(self):
        return f"Part({self.kind!r}, {self.fields!r})"

    def __reduce__(self):
        # Copies and pickles rebuild through __init__: __setattr__ refuses every field.
        return (Part, (self.kind, self.fields))

    def has(self, name):
        """Whether this kind of part has field ``name``."""
        return name in self.fields

    @classmethod
    def from_json(cls, d):
        if d is None:
            return None
        return cls(d["kind"], {k: v for k, v in d.items() if k != "kind"})

    def to_json(self):
        return {"kind": self.kind, **self.fields}


@dataclass(frozen=True)
class Settings:
    """The problem as solved (solution.json's ``problem``): ``segments`` is the count
    used, also when a per-revolution rule set it; ``sub_arcs`` the count the error
    control ended with; ``throttle_bounds`` only for a throttled sail."""

    name: str
    description: Optional[str]
    ac_mm_s2: float
    coefficients: List[float]
    alpha_bounds_deg: List[float]
    segments: int
    segments_per_revolution: Optional[int]
    sub_arcs: int
    sub_arcs_requested: int
    equal_segments: bool
    objective: str
    target: Optional[Part]
    departure: Part
    departure_state: State
    r_min_au: Optional[float]
    q3_margin: Optional[float]
    throttle_bounds: Optional[List[float]] = None

    SIMPLE = ("name", "description", "ac_mm_s2", "coefficients", "alpha_bounds_deg",
              "segments", "segments_per_revolution", "sub_arcs", "sub_arcs_requested",
              "equal_segments", "objective")

    @classmethod
    def from_json(cls, d):
        return cls(**{k: d[k] for k in cls.SIMPLE}, target=Part.from_json(d["target"]),
                   departure=Part.from_json(d["departure"]),
                   departure_state=State.from_json(d["departure_state"]),
                   r_min_au=d["r_min_au"], q3_margin=d["q3_margin"],
                   throttle_bounds=d.get("throttle_bounds"))

    def to_json(self):
        out = {k: getattr(self, k) for k in self.SIMPLE}
        out.update(target=None if self.target is None else self.target.to_json(),
                   departure=self.departure.to_json(),
                   departure_state=self.departure_state.to_json(),
                   r_min_au=self.r_min_au, q3_margin=self.q3_margin)
        # Only a throttled problem names its bounds: an unthrottled solution.json is
        # exactly what it was before throttles existed.
        if self.throttle_bounds is not None:
            out["throttle_bounds"] = self.throttle_bounds
        return out


class _FlatRecord:
    """A record the file holds as one flat object (or null): its fields are its keys."""

    @classmethod
    def from_json(cls, d):
        return None if d is None else cls(**d)

    def to_json(self):
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class DepartureBody(_FlatRecord):
    """Where a dated departure leaves from: the body, its source, the distance from the
    ecliptic the 2-D model drops, and the excess velocity (angle in [-180, 180))."""

    name: str
    source: str
    out_of_plane_km: float
    vinf_km_s: float
    vinf_angle_deg: float


@dataclass(frozen=True)
class TargetBody(_FlatRecord):
    """The body a BodyRendezvous or BodyIntercept flies to, as the flight met it."""

    name: str
    source: str
    kind: str
    out_of_plane_km: Optional[float]
    relative_speed_km_s: Optional[float]


@dataclass(frozen=True)
class ClassLooked(_FlatRecord):
    """One turn count k on the target body that the solve looked at (an entry of
    ``classes.looked_at``): what its closed form gave, and whether it was flown.
    ``tof_days``, ``objective`` and ``ac_mm_s2_required`` (MinAcceleration) are None
    where Ipopt found no point; ``verified`` is None where the class was not flown."""

    revolutions_k: int
    label: str
    status: str
    iterations: int
    objective: Optional[float]
    tof_days: Optional[float]
    ac_mm_s2_required: Optional[float]
    constraint_violation: float
    verified: Optional[bool]
    chosen: bool


@dataclass(frozen=True)
class NearestFeasible(_FlatRecord):
    """The shortest flight found feasible from the same departure, for a fixed-time
    solve that found no point (``nearest_feasible``): its date, time of flight and a_c,
    whether its flight is verified (with its note), the longest time of flight found
    infeasible (the edge lies between the two) and the Ipopt iterations of the walk."""

    departure_date: Optional[str]
    tof_days: float
    ac_mm_s2_required: float
    verified: bool
    note: str
    infeasible_tof_days: float
    iterations: int


@dataclass(frozen=True)
class Polish:
    """solution.json's ``polish``: the polished optimum and its verification, or, when
    the closed form found nothing, only ``note`` (and ``status`` None).

    ``verified`` is True only when Ipopt converged and the flight, its verifier's error
    included, is within ``bounds`` (1 m, 1 mm/s) of both the target and the polished
    NLP's final state.  ``departure_state`` and the calendar fields are the polished
    flight's own: flown from that state (at ``ac_mm_s2_required`` for MinAcceleration)
    the polished schedule is the flight verified.  A version-3 file has none of them.
    """

    status: Optional[str]
    converged: bool
    verified: bool
    note: str
    outcome: Optional[Outcome] = None
    iterations: Optional[int] = None
    seconds: Optional[float] = None
    constraint_violation: Optional[float] = None
    objective: Optional[float] = None
    tof_days: Optional[float] = None
    bounds: Optional[Bounds] = None
    within_bounds_vs_nlp: Optional[bool] = None
    within_bounds_vs_target: Optional[bool] = None
    schedule: Optional[Schedule] = None
    final_state: Optional[State] = None
    verification: Optional[Flight] = None
    departure_state: Optional[State] = None
    departure_date: Optional[str] = None
    arrival_date: Optional[str] = None
    departure_body: Optional[DepartureBody] = None
    target_body: Optional[TargetBody] = None
    ac_mm_s2_required: Optional[float] = None

    #: The keys of the polished flight's own start, dates, bodies and a_c (version 4).
    OWN = ("departure_date", "arrival_date", "ac_mm_s2_required")

    @property
    def ran(self):
        """Whether the polish ran (False: the closed-form solve found no optimum)."""
        return self.status is not None

    @classmethod
    def from_json(cls, d):
        if d is None:
            return None
        if d.get("status") is None:
            return cls(None, bool(d["converged"]), bool(d["verified"]), d["note"])
        return cls(d["status"], d["converged"], d["verified"], d["note"],
                   outcome=Outcome(d["outcome"]), iterations=d["iterations"],
                   seconds=d["seconds"], constraint_violation=d["constraint_violation"],
                   objective=d["objective"], tof_days=d["tof_days"],
                   bounds=Bounds.from_json(d["bounds"]),
                   within_bounds_vs_nlp=d["within_bounds_vs_nlp"],
                   within_bounds_vs_target=d["within_bounds_vs_target"],
                   schedule=Schedule.from_json(d["schedule"]),
                   final_state=State.from_json(d["final_state"]),
                   verification=Flight.from_json(d["verification"]),
                   departure_state=(None if d.get("departure_state") is None
                                    else State.from_json(d["departure_state"])),
                   departure_body=DepartureBody.from_json(d.get("departure_body")),
                   target_body=TargetBody.from_json(d.get("target_body")),
                   **{k: d.get(k) for k in cls.OWN})

    def to_json(self):
        if not self.ran:
            return {"status": None, "converged": False, "verified": False, "note": self.note}
        return {
            "status": self.status, "converged": self.converged,
            "outcome": self.outcome.value, "iterations": self.iterations,
            "seconds": self.seconds, "constraint_violation": self.constraint_violation,
            "objective": self.objective, "tof_days": self.tof_days,
            "bounds": self.bounds.to_json(), "within_bounds_vs_nlp": self.within_bounds_vs_nlp,
            "within_bounds_vs_target": self.within_bounds_vs_target,
            "verified": self.verified, "note": self.note,
            "schedule": self.schedule.to_json(), "final_state": self.final_state.to_json(),
            "verification": self.verification.to_json(),
            **({} if self.departure_state is None
               else {"departure_state": self.departure_state.to_json()}),
            **{k: getattr(self, k) for k in self.OWN if getattr(self, k) is not None},
            **{k: getattr(self, k).to_json() for k in ("departure_body", "target_body")
               if getattr(self, k) is not None},
        }


@dataclass(frozen=True)
class Solution:
    """A solved problem: what ``solution.json`` holds, typed, with reading, writing and
    printing.

    Make one with :meth:`of` (from a pipeline Run), :func:`solve`, or :meth:`load`.
    The fields follow the file's keys (:mod:`esail_opt.app.schema`), with these
    differences of name: ``flight_verified`` is the file's ``verified`` (the closed
    form's flight alone; :attr:`verified` adds the polish's verdict),
    ``rounds`` and ``starts`` are ``refinement.rounds`` and ``refinement.starts``, and
    ``trajectory_*`` are the parts of ``trajectory``.  Fields of the calendar and of
    the polish are None where the file leaves them out.
    """

    schema_version: int
    problem: Settings
    status: str
    converged: bool
    acceptable: bool
    outcome: Outcome
    flight_verified: bool
    verification_note: str
    tolerance: Bounds
    objective: Optional[float]
    objective_meaning: str
    tof_days: float
    iterations: int
    stages: Tuple[Tuple[str, int], ...]
    solve_seconds: float
    constraint_violation: Optional[float]
    min_q3: Optional[float]
    schedule: Schedule
    final_state: State
    verification: Flight
    rounds: Tuple[Round, ...]
    starts: Tuple[StartTried, ...]
    trajectory_closed_form: Samples
    trajectory_cvodes: Optional[Samples]
    trajectory_polished: Optional[Samples] = None
    departure_date: Optional[str] = None
    arrival_date: Optional[str] = None
    departure_body: Optional[DepartureBody] = None
    target_body: Optional[TargetBody] = None
    ac_mm_s2_required: Optional[float] = None
    objective_closed_form: Optional[float] = None
    objective_exact: Optional[float] = None
    tof_days_exact: Optional[float] = None
    polish: Optional[Polish] = None
    classes: Tuple[ClassLooked, ...] = ()
    classes_skipped: Optional[str] = None
    nearest_feasible: Optional[NearestFeasible] = None

    # -- access
    @property
    def verified(self):
        """Converged, and the flight on Eqs. 1-2 meets the tolerance (and, after a
        polish, the polish's 1 m and 1 mm/s as well)."""
        return bool(self.flight_verified) and (self.polish is None or bool(self.polish.verified))

    @property
    def dated(self):
        """Whether the problem is on the calendar (a BodyDeparture)."""
        return self.departure_date is not None

    def __getitem__(self, key):
        """The field ``key`` of solution.json, as :meth:`to_json` writes it: for scripts
        that read the file's names (``sol["departure_date"]``)."""
        return self.to_json()[key]

    # -- the JSON form
    @classmethod
    def of(cls, run):
        """The Solution of a pipeline :class:`~esail_opt.optimisation.pipeline.Run`.

        It is built from the run's JSON form by :meth:`from_json`, the reader of files:
        a fresh Solution and the same one loaded back are then equal by construction,
        to the last digit.
        """
        return cls.from_json(json_ready(_run_data(run)))

    @classmethod
    def from_json(cls, data, source="solution.json"):
        """A Solution from the content of a ``solution.json`` of a readable version.

        Raises
        ------
        InputError
            Another schema version, or a file that lacks a field of its version (one
            line, naming ``source``).
        """
        schema.check(data, source)
        try:
            return cls._from_json(data)
        except (KeyError, TypeError, ValueError) as err:
            raise _bad_file(source, f"has no valid field {err}") from None

    @classmethod
    def _from_json(cls, d):
        traj, refinement = d["trajectory"], d["refinement"]
        return cls(
            schema_version=d["schema_version"], problem=Settings.from_json(d["problem"]),
            status=d["status"], converged=d["converged"], acceptable=d["acceptable"],
            outcome=Outcome(d["outcome"]), flight_verified=d["verified"],
            verification_note=d["verification_note"],
            tolerance=Bounds.from_json(d["tolerance"]), objective=d["objective"],
            objective_meaning=d["objective_meaning"], tof_days=d["tof_days"],
            iterations=d["iterations"],
            stages=tuple((s["status"], s["iterations"]) for s in d["stages"]),
            solve_seconds=d["solve_seconds"], constraint_violation=d["constraint_violation"],
            min_q3=d["min_q3"], schedule=Schedule.from_json(d["schedule"]),
            final_state=State.from_json(d["final_state"]),
            verification=Flight.from_json(d["verification"]),
            rounds=tuple(Round(**r) for r in refinement["rounds"]),
            starts=tuple(StartTried(**s) for s in refinement["starts"]),
            trajectory_closed_form=Samples.from_json(traj["closed_form"]),
            trajectory_cvodes=Samples.from_json(traj["cvodes"]),
            trajectory_polished=Samples.from_json(traj.get("polished")),
            departure_date=d.get("departure_date"), arrival_date=d.get("arrival_date"),
            departure_body=DepartureBody.from_json(d.get("departure_body")),
            target_body=TargetBody.from_json(d.get("target_body")),
            ac_mm_s2_required=d.get("ac_mm_s2_required"),
            objective_closed_form=d.get("objective_closed_form"),
            objective_exact=d.get("objective_exact"), tof_days_exact=d.get("tof_days_exact"),
            polish=Polish.from_json(d.get("polish")),
            # Version 5 added the classes and the nearest feasible flight.
            classes=tuple(ClassLooked.from_json(c)
                          for c in d.get("classes", {}).get("looked_at", ())),
            classes_skipped=d.get("classes", {}).get("not_looked_at"),
            nearest_feasible=NearestFeasible.from_json(d.get("nearest_feasible")),
        )

    def to_json(self):
        """The content of ``solution.json``: a new dict of plain JSON values each call."""
        polished = self.polish is not None and self.polish.ran
        out = {
            "schema_version": self.schema_version, "problem": self.problem.to_json(),
            "status": self.status, "converged": self.converged,
            "acceptable": self.acceptable, "outcome": self.outcome.value,
            "verified": self.flight_verified, "verification_note": self.verification_note,
            "tolerance": self.tolerance.to_json(), "objective": self.objective,
            "objective_meaning": self.objective_meaning, "tof_days": self.tof_days,
            "iterations": self.iterations,
            "stages": [{"status": st, "iterations": it} for st, it in self.stages],
            "solve_seconds": self.solve_seconds,
            "constraint_violation": self.constraint_violation, "min_q3": self.min_q3,
            "schedule": self.schedule.to_json(), "final_state": self.final_state.to_json(),
            "verification": self.verification.to_json(),
            "refinement": {"rounds": [dataclasses.asdict(r) for r in self.rounds],
                           "starts": [dataclasses.asdict(s) for s in self.starts]},
            "trajectory": {
                "closed_form": self.trajectory_closed_form.to_json(),
                "cvodes": (None if self.trajectory_cvodes is None
                           else self.trajectory_cvodes.to_json()),
            },
        }
        if polished:
            out["trajectory"]["polished"] = (None if self.trajectory_polished is None
                                             else self.trajectory_polished.to_json())
        if self.ac_mm_s2_required is not None:
            out["ac_mm_s2_required"] = self.ac_mm_s2_required
        if self.dated:
            out.update(departure_date=self.departure_date, arrival_date=self.arrival_date,
                       departure_body=self.departure_body.to_json())
        if self.target_body is not None:
            out["target_body"] = self.target_body.to_json()
        if polished:
            out.update(objective_closed_form=self.objective_closed_form,
                       objective_exact=self.objective_exact,
                       tof_days_exact=self.tof_days_exact)
        if self.polish is not None:
            out["polish"] = self.polish.to_json()
        if self.classes_skipped is not None:
            out["classes"] = {"looked_at": [c.to_json() for c in self.classes],
                              "not_looked_at": self.classes_skipped}
        if self.nearest_feasible is not None:
            out["nearest_feasible"] = self.nearest_feasible.to_json()
        return out

    # -- files
    @classmethod
    def load(cls, path):
        """Read a ``solution.json`` back; one of another schema version, or one that is
        not a solution file, is refused with a one-line InputError that says so."""
        try:
            data = json.loads(Path(path).read_text())
        except (OSError, ValueError) as err:
            raise InputError(f"{path}: cannot read solution.json ({err})") from None
        return cls.from_json(data, path)

    def schedule_csv(self, polished=False):
        """The schedule as CSV text, one row per segment (same rows as ``schedule``, or
        with ``polished`` as ``polish.schedule``), every number to the digit, so that
        flying the file reproduces the flight that was verified.  (At 10 significant
        digits a polished 2500-day schedule, flown from the CSV, ended 3.5 m from its
        target where the same schedule at full precision ends 8 mm from it.)"""
        schedule = self.polish.schedule if polished else self.schedule
        clocked = len(schedule) and schedule[0].clock_deg is not None
        fields = SCHEDULE_FIELDS + tuple(
            f for f, on in ((CLOCK_FIELD, clocked), (THROTTLE_FIELD, schedule.throttled),
                            (LOCAL_ERROR_FIELD, schedule.local_errors)) if on and len(schedule))
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(fields)
        for row in schedule:
            writer.writerow([repr(float(_nan_for_none(getattr(row, f)))) for f in fields])
        return buf.getvalue()

    def write(self, out_dir, plots=True):
        """Write solution.json, schedule.csv (and schedule_polished.csv after a polish)
        and (with ``plots``) the two PNGs into ``out_dir``, as one set
        (:func:`esail_opt.app.files.publish`): a reader of the folder sees the previous
        run's files or these, never a mix, and files of the user's own stay.  The
        figures are drawn here, one after the other (:func:`esail_opt.app.plots.write_plots`).

        Returns the list of paths written.

        Raises
        ------
        OutputError
            The folder cannot be written (one line; the old set stays as it was).
        FigureError
            A figure could not be drawn: the rest of the set was published all the same
            (the error's ``written``), without that figure.
        """
        out = Path(out_dir)
        failures = []
        with publish(out, family=SOLUTION_FILES) as stage:
            names = ["solution.json", "schedule.csv"]
            write_json(stage / names[0], self.to_json())
            (stage / names[1]).write_text(self.schedule_csv())
            if self.polish is not None and self.polish.ran:
                names.append("schedule_polished.csv")
                (stage / names[-1]).write_text(self.schedule_csv(polished=True))
            if self._write_oem(stage / "trajectory.oem"):
                names.append("trajectory.oem")
            if plots:
                from esail_opt.app import plots as plotting

                drawn, failures = plotting.write_plots(self, stage)
                names += [p.name for p in drawn]
        written = [out / name for name in names]
        if failures:
            raise FigureError(failures, written)
        return written

    def _write_oem(self, path):
        """The CVODES flight of a 3-D solution as ``trajectory.oem`` (``app.oem``);
        False, and nothing written, for a planar one or a failed flight."""
        flight = self.trajectory_cvodes
        if flight is None or flight.three_d is None or not self.dated:
            return False
        states = schema.state_from_fields(
            {k: flight.three_d[k] for k in schema.STATE_KEYS}, "trajectory.cvodes")
        days = np.asarray(flight.t_days, float)
        write_oem(path, self.problem.name, np.full(days.size, dates.jd_from_iso(
            self.departure_date)), states_km_km_s(states), jd2=days)
        return True

    # -- printing
    def summary(self):
        v = self.verification
        lines = [
            f"{self.problem.name}: {self.status} "
            f"({'converged' if self.converged else 'NOT converged'}), "
            f"{self.iterations} iterations, {self.solve_seconds:.2f} s, "
            f"{max(len(self.rounds) - 1, 0)} error-control round(s)",
            f"  tof {self.tof_days:.3f} d (closed form), {len(self.schedule)} segments x "
            f"{self.problem.sub_arcs} sub-arcs",
            # A dated problem's theta counts turns since 2000: the angle reads better.
            "  final (closed form): r {r_au:.6f} au, theta {theta:.3f} deg, a {a_au:.6f} au, "
            "e {e:.5f}".format(theta=self.final_state.theta_deg % 360.0,
                               **self.final_state.to_json()),
        ]
        lines += self._mission_lines()
        if v.error:
            lines.append(f"  verification: {v.error}")
        else:
            cv = v.cvodes_final_state
            lines.append(f"  CVODES: r {cv.r_au:.6f} au, a {cv.a_au:.6f} au, e {cv.e:.5f}; "
                         f"miss vs NLP {v.miss_r_km:.4g} km, {v.miss_v_m_s:.4g} m/s, "
                         f"{v.miss_theta_deg:.4g} deg")
            if v.target_miss_r_km is not None:
                extra = (f", {v.target_miss_v_m_s:.4g} m/s"
                         if v.target_miss_v_m_s is not None else "")
                lines.append(f"  CVODES miss vs target: {v.target_miss_r_km:.4g} km{extra}")
        lines.append(f"  {self.verification_note}")
        lines += self._class_lines()
        lines += self._polish_lines()
        return "\n".join(lines)

    def _class_lines(self):
        """The turn counts looked at, and the nearest feasible flight, if any."""
        lines = []
        if self.classes:
            shown = []
            for c in sorted(self.classes, key=lambda c: c.revolutions_k):
                if c.tof_days is None:
                    shown.append(f"k = {c.revolutions_k} no point ({c.status} after "
                                 f"{c.iterations} iterations)")
                    continue
                value = (f"{c.ac_mm_s2_required:.4g} mm/s^2" if c.ac_mm_s2_required is not None
                         else f"{c.tof_days:.1f} d")
                verdict = {True: ", verified", False: ", NOT verified", None: ""}[c.verified]
                shown.append(f"k = {c.revolutions_k} {value}{verdict}"
                             + (" (chosen)" if c.chosen else ""))
            lines.append(f"  turn counts on the body: {'; '.join(shown)}")
            lines.append(f"  not looked at: {self.classes_skipped}")
        n = self.nearest_feasible
        if n is not None:
            lines.append(f"  nearest feasible: {nearest_feasible_line(n)}")
        return lines

    def _mission_lines(self):
        """The dates, the a_c a MinAcceleration found and what the plane hides at a
        body: the answers a dated or sail-sizing problem was asked for."""
        lines = []
        if self.departure_date is not None:
            lines.append(f"  departs {self.departure_date}, arrives {self.arrival_date} (TDB)")
        if self.ac_mm_s2_required is not None and self.converged:
            lines.append(f"  a_c needed: {self.ac_mm_s2_required:.6g} mm/s^2 (the schedule's "
                         "throttles are fractions of it)")
        elif self.ac_mm_s2_required is not None:
            lines.append(f"  a_c of Ipopt's last iterate: {self.ac_mm_s2_required:.6g} mm/s^2 "
                         "(not converged: no answer)")
        body = self.target_body
        if body is not None and body.out_of_plane_km is not None:
            # A rendezvous's relative speed is its velocity miss, printed below.
            speed = ("" if body.relative_speed_km_s is None or body.kind != "BodyIntercept"
                     else f", met at {body.relative_speed_km_s:.4g} km/s relative speed")
            if self.final_state.cartesian is not None:
                lines.append(f"  {body.name}: flown in 3-D against its unprojected state, "
                             f"{body.out_of_plane_km:.4g} km from it along the ecliptic's "
                             f"normal at arrival{speed}")
            else:
                lines.append(f"  {body.name}: {body.out_of_plane_km:.4g} km from the ecliptic "
                             f"at arrival, which the planar model ignores{speed}")
        return lines

    def _polish_lines(self):
        """Summary lines of the polish, if there was one."""
        p = self.polish
        if p is None:
            return []
        if not p.ran:
            return [f"  polish: {p.note}"]
        lines = [f"  polish: {p.status} ({'converged' if p.converged else 'NOT converged'}), "
                 f"{p.iterations} iterations, {p.seconds:.2f} s; exact tof "
                 f"{p.tof_days:.3f} d (closed form {self.tof_days:.3f} d)"]
        v = p.verification
        if v.error is None:
            # At the polish's scale a km reads better as metres.
            line = (f"  polished CVODES miss vs NLP {1e3 * v.miss_r_km:.3g} m, "
                    f"{1e3 * v.miss_v_m_s:.3g} mm/s")
            if v.target_miss_r_km is not None:
                line += f"; vs target {1e3 * v.target_miss_r_km:.3g} m"
                if v.target_miss_v_m_s is not None:
                    line += f", {1e3 * v.target_miss_v_m_s:.3g} mm/s"
            # Misses this small are only as good as the verifier that measured them.
            if v.verifier_error_r_km is not None:
                line += f" (verifier's own error {1e3 * v.verifier_error_r_km:.2g} m)"
            lines.append(line)
        lines.append(f"  polish: {p.note}")
        return lines

    def __str__(self):
        return self.summary()

    def plot(self, out_dir=None):
        """Draw the trajectory and timeline figures and return them; given ``out_dir``,
        write them there as trajectory.png and timeline.png instead and return their
        paths (raises :class:`~esail_opt.errors.FigureError` if one cannot be drawn,
        after writing the other)."""
        from esail_opt.app import plots as plotting

        if out_dir is None:
            return plotting.trajectory_figure(self), plotting.timeline_figure(self)
        written, failures = plotting.write_plots(self, out_dir)
        if failures:
            raise FigureError(failures, written)
        return written


def nearest_feasible_line(n):
    """One line on a :class:`NearestFeasible`: its date, time of flight and a_c."""
    date = "" if n.departure_date is None else f" departing {n.departure_date}"
    return (f"the shortest flight found feasible{date} takes {n.tof_days:.1f} d at a_c "
            f"{n.ac_mm_s2_required:.4g} mm/s^2 ({'verified' if n.verified else 'NOT verified'}"
            f"; none found at {n.infeasible_tof_days:.1f} d)")


def _nan_for_none(value):
    """A CSV cell's number: the file's null (a NaN the JSON could not hold) as NaN."""
    return math.nan if value is None else value


def solution_of(run):
    """The :class:`Solution` of a pipeline Run (:meth:`Solution.of`)."""
    return Solution.of(run)


def solve(problem, segments=None, progress=None, samples=16, polish=False):
    """Solve ``problem`` through the whole pipeline
    (:func:`esail_opt.optimisation.pipeline.solve`, whose parameters these are) and
    return its :class:`Solution`.

    Raises
    ------
    InputError
        ``segments`` is not an integer >= 1 (before any solve starts).
    """
    return Solution.of(pipeline.solve(problem, segments=segments, progress=progress,
                                      samples=samples, polish=polish))


# ---------------------------------------------------------------- a Run, in boundary units


@functools.lru_cache(maxsize=None)
def _elements_function():
    """Osculating (a, e) of one polar state as a Function, so it maps over columns
    (classical_from_polar itself is written for one state)."""
    x = ca.SX.sym("x", 4)
    a, e = classical_from_polar(x)[:2]
    return ca.Function("elements", [x], [a, e])


def _polar_dict(x):
    """Polar state(s) (4 or 4 x M), canonical -> boundary units, with osculating a and e."""
    x = np.asarray(x, float)
    cols = x.reshape(4, -1)
    a, e = (np.array(v).ravel() for v in _elements_function().map(cols.shape[1])(cols))
    out = {"r_au": cols[0], "theta_deg": np.degrees(cols[1]),
           "vr_km_s": units.speed_to_km_s(cols[2]), "vtheta_km_s": units.speed_to_km_s(cols[3]),
           "a_au": a, "e": e}
    if x.ndim == 1:
        return {k: float(v[0]) for k, v in out.items()}
    return {k: np.asarray(v).tolist() for k, v in out.items()}


def _trajectory(xs, cartesian=None):
    """Samples of a flight; a 3-D flight's Cartesian samples (7 x M, canonical) add the
    state in ``schema.STATE_KEYS`` and the osculating inclination and node, deg."""
    out = _polar_dict(xs[:4])
    out["t_days"] = units.time_to_days(np.asarray(xs[4])).tolist()
    if cartesian is not None:
        out.update(schema.state_fields(cartesian[:6]))
        h = np.cross(cartesian[:3].T, cartesian[3:6].T).T
        out["inclination_deg"] = np.degrees(np.arctan2(np.hypot(h[0], h[1]), h[2])).tolist()
        out["node_deg"] = np.degrees(np.arctan2(h[0], -h[1])).tolist()
    return out


def _state_dict(x, cartesian=None):
    """:func:`_polar_dict` of one state, with its Cartesian fields in three dimensions."""
    out = _polar_dict(x)
    if cartesian is not None:
        out.update(schema.state_fields(np.asarray(cartesian, float)[:6]))
    return out


def _final_state(result):
    """The NLP's final state; a 3-D node adds its Cartesian state."""
    nodes = result.nodes
    return _state_dict(nodes[:4, -1], None if result.delta is None else node_cartesian(nodes[:, -1]))


def _fields(obj):
    """A problem part's kind and fields; a body is given by its name."""
    out = {"kind": type(obj).__name__}
    out.update({k: getattr(obj, k) for k in obj.__dataclass_fields__})
    if "body" in out:
        out["body"] = lookup.describe(out["body"])
    return out


def _target_dict(target):
    return None if target is None else _fields(target)


def _calendar_data(problem, result, check):
    """The dated part of solution.json: departure and arrival dates (ISO 8601, TDB),
    the bodies with their sources, the planes' distances the 2-D model ignores, and
    what a MinAcceleration objective found.  Empty for problems off the calendar."""
    out = {}
    if problem.objective.free_acceleration:
        out["ac_mm_s2_required"] = problem.sail.ac_mm_s2 * result.ac_scale
    if not problem.dated():
        return out
    dep = problem.departure
    start_jd = dates.jd_from_tu(result.epoch)
    tof = float(np.sum(result.durations))
    out["departure_date"] = dates.iso_from_jd(start_jd)
    out["arrival_date"] = dates.iso_from_jd(dates.jd_from_tu(result.epoch + tof))
    z0 = lookup.polar_state(dep.body, start_jd)[1]
    out["departure_body"] = {"name": lookup.name(dep.body), "source": lookup.source(dep.body),
                             "out_of_plane_km": units.length_to_km(abs(z0)),
                             "vinf_km_s": dep.vinf_km_s,
                             # The NLP's angle is unbounded: reported in [-180, 180).
                             "vinf_angle_deg": (math.degrees(result.vinf_angle) + 180) % 360
                             - 180}
    target = problem.target
    if target is not None and getattr(target, "body", None) is not None:
        m = check.misses
        out["target_body"] = {"name": lookup.name(target.body),
                              "source": lookup.source(target.body),
                              "kind": type(target).__name__,
                              "out_of_plane_km": m.get("out_of_plane_km"),
                              "relative_speed_km_s": m.get("relative_speed_km_s")}
    return out


def _schedule(result, throttled=False):
    """Per-segment rows (boundary units) of an NLP result's schedule; with ``throttled``
    each row also carries its ``throttle`` kappa."""
    starts_t = np.r_[0.0, np.cumsum(result.durations)[:-1]]
    starts_th = np.r_[result.x_start[1], result.nodes[1, :-1]]
    rows = [
        {"t_days": units.time_to_days(t), "theta_deg": math.degrees(th),
         "alpha_deg": math.degrees(al), "duration_days": units.time_to_days(dt),
         "dtheta_deg": math.degrees(ln)}
        for t, th, al, dt, ln in zip(starts_t, starts_th, result.alpha, result.durations,
                                     result.lengths)
    ]
    if result.delta is not None:
        # The NLP's clock is unbounded: reported in [-180, 180).
        for row, delta in zip(rows, result.delta):
            row[CLOCK_FIELD] = (math.degrees(delta) + 180) % 360 - 180
    if throttled:
        for row, kappa in zip(rows, result.throttle):
            row[THROTTLE_FIELD] = float(kappa)
    return rows


def _verification_data(check):
    """The ``verification`` object of solution.json (closed form and polish alike)."""
    out = dict(check.misses)
    out["error"] = check.error
    if check.error is None:
        cart = getattr(check, "cartesian", None)
        out["cvodes_final_state"] = _state_dict(check.cvodes[:4, -1],
                                                None if cart is None else cart[:, -1])
        out["cvodes_tof_days"] = units.time_to_days(float(check.cvodes[4, -1]))
    return out


def _polish_data(problem, polished):
    """The ``polish`` object of solution.json from the run's PolishRun."""
    if not polished.ran:
        return {"status": None, "converged": False, "verified": False, "note": polished.note}
    exact, check, bounds = polished.result, polished.check, polished.tolerance
    return {
        "status": exact.status, "converged": exact.converged, "outcome": exact.outcome.value,
        "iterations": exact.iterations, "seconds": exact.solve_seconds,
        "constraint_violation": exact.constraint_violation,
        "objective": exact.objective,
        "tof_days": units.time_to_days(float(np.sum(exact.durations))),
        "bounds": {"position_km": bounds.position_km, "velocity_m_s": bounds.velocity_m_s},
        "within_bounds_vs_nlp": polished.within_nlp,
        "within_bounds_vs_target": polished.within_target,
        "verified": polished.verified, "note": polished.note,
        "schedule": _schedule(exact, problem.throttled()),
        "final_state": _final_state(exact),
        "verification": _verification_data(check),
        # What the polished schedule is flown from and with: a polish may move the
        # departure (a free date, anomaly or excess-velocity angle) and the a_c.
        "departure_state": _departure_state(problem, exact),
        **_calendar_data(problem, exact, check),
    }


def _run_data(run):
    """What ``solution.json`` holds for ``run`` (before :func:`json_ready`)."""
    problem, result, check = run.problem, run.result, run.check
    controlled = run.error_control
    schedule = _schedule(result, problem.throttled())
    if controlled is not None:
        for row, err in zip(schedule, controlled.local_error_km):
            row[LOCAL_ERROR_FIELD] = float(err)
    data = {
        "schema_version": schema.SCHEMA_VERSION,
        "problem": _problem_data(problem, result, run.sub_arcs_requested),
        "status": result.status,
        "converged": result.converged,
        "acceptable": result.outcome is Outcome.ACCEPTABLE,
        "outcome": result.outcome.value,
        "verified": run.verified,
        "verification_note": run.note,
        "tolerance": {"position_km": problem.tolerance.position_km,
                      "velocity_m_s": problem.tolerance.velocity_m_s},
        "objective": result.objective,
        "objective_meaning": problem.objective.meaning,
        "tof_days": units.time_to_days(float(np.sum(result.durations))),
        "iterations": result.iterations,
        "stages": [{"status": st, "iterations": it} for st, it in result.stages],
        "solve_seconds": result.solve_seconds,
        "constraint_violation": result.constraint_violation,
        "min_q3": float(np.min(result.q3)),
        "schedule": schedule,
        "final_state": _final_state(result),
        "verification": _verification_data(check),
        "refinement": {"rounds": ([] if controlled is None
                                  else [dataclasses.asdict(r) for r in controlled.history]),
                       "starts": [dataclasses.asdict(s) for s in run.starts]},
        "trajectory": {
            "closed_form": _trajectory(check.closed_form),
            "cvodes": (_trajectory(check.cvodes, getattr(check, "cartesian", None))
                       if check.error is None else None),
        },
        **_calendar_data(problem, result, check),
    }
    data.update(_classes_data(run))
    polished = run.polish
    if polished is not None:
        if polished.ran:
            exact = polished.result
            data["objective_closed_form"] = polished.closed_form_objective
            data["objective_exact"] = exact.objective
            data["tof_days_exact"] = units.time_to_days(float(np.sum(exact.durations)))
            data["trajectory"]["polished"] = (
                _trajectory(polished.check.cvodes, getattr(polished.check, "cartesian", None))
                if polished.check.error is None else None)
        data["polish"] = _polish_data(problem, polished)
    return data


def _classes_data(run):
    """``classes`` and ``nearest_feasible`` of solution.json for ``run``."""
    problem = run.problem
    acc = problem.objective.free_acceleration
    looked = [{"revolutions_k": c.revolutions_k, "label": c.label, "status": c.status,
               "iterations": c.iterations, "objective": c.objective,
               "tof_days": None if c.tof is None else units.time_to_days(c.tof),
               "ac_mm_s2_required": (problem.sail.ac_mm_s2 * c.ac_scale
                                     if acc and c.ac_scale is not None else None),
               "constraint_violation": c.constraint_violation, "verified": c.verified,
               "chosen": c.chosen} for c in run.classes]
    out = {"classes": {"looked_at": looked, "not_looked_at": run.classes_skipped}}
    near = run.nearest_feasible
    if near is not None:
        flown = near.run
        calendar = _calendar_data(flown.problem, flown.result, flown.check)
        out["nearest_feasible"] = {
            "departure_date": calendar.get("departure_date"),
            "tof_days": near.tof_days,
            "ac_mm_s2_required": calendar.get("ac_mm_s2_required",
                                              flown.problem.sail.ac_mm_s2),
            "verified": flown.verified, "note": flown.note,
            "infeasible_tof_days": near.infeasible_tof_days, "iterations": near.iterations}
    return out


def _departure_state(problem, result):
    """The state the verification flies from; in three dimensions the exact polar
    state inside the departure's plane and its Cartesian ecliptic state."""
    if not problem.three_d():
        return _polar_dict(problem.start_state(result))
    plane = problem.departure.plane_state_at(result.epoch, result.vinf_angle)
    return _state_dict(plane[:4], problem.start_state(result))


def _problem_data(problem, result, sub_arcs_requested):
    """The ``problem`` object of solution.json: the settings as solved (``segments`` is
    the count used, also when a per-revolution rule set it; ``sub_arcs`` the count the
    error control ended with)."""
    seg, dep = problem.segments, problem.departure
    out = {
        "name": problem.name, "description": problem.description,
        "ac_mm_s2": problem.sail.ac_mm_s2, "coefficients": list(problem.sail.coefficients),
        "alpha_bounds_deg": [problem.sail.alpha_min_deg, problem.sail.alpha_max_deg],
        "segments": int(result.alpha.size), "segments_per_revolution": seg.per_revolution,
        "sub_arcs": seg.sub_arcs, "sub_arcs_requested": sub_arcs_requested,
        "equal_segments": seg.equal, "objective": type(problem.objective).__name__,
        "target": _target_dict(problem.target),
        "departure": _fields(dep),
        # The state the verification flies from: for a body, its ephemeris, not the
        # NLP's smooth track of it.
        "departure_state": _departure_state(problem, result),
        "r_min_au": problem.path.r_min_au, "q3_margin": problem.path.q3_margin,
    }
    if problem.throttled():
        # Only a throttled problem names its bounds: an unthrottled solution.json is
        # exactly what it was before throttles existed.
        out["throttle_bounds"] = list(problem.throttle_bounds())
    return out
