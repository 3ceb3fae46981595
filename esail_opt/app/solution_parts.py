"""The records a :class:`~esail_opt.app.solution.Solution` is made of, apart from that
module so that :mod:`esail_opt.app.from_run` builds them without importing the module that
solves: solution -> from_run -> solution_parts."""

import dataclasses
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

from esail_opt.app import schema
from esail_opt.app.record import REST, BadField, Record, if_none, key
from esail_opt.optimisation.pipeline import Outcome

#: What a 3-D flight's samples add besides the Cartesian state: the osculating plane, deg.
PLANE_FIELDS = ("inclination_deg", "node_deg")


@dataclass(frozen=True)
class State(Record):
    """A polar state in boundary units, with its osculating a and e; in three
    dimensions also x_au .. vz_km_s in the ecliptic of J2000 (``schema.STATE_KEYS``)."""

    r_au: Optional[float]
    theta_deg: Optional[float]
    vr_km_s: Optional[float]
    vtheta_km_s: Optional[float]
    a_au: Optional[float]
    e: Optional[float]
    cartesian: Optional[Dict[str, float]] = key(flat=schema.STATE_KEYS, default=None)


@dataclass(frozen=True)
class Samples(Record):
    """A sampled flight, boundary units, one list per quantity (None where NaN); a 3-D
    flight adds its Cartesian samples and osculating plane (``three_d``)."""

    r_au: List[Optional[float]]
    theta_deg: List[Optional[float]]
    vr_km_s: List[Optional[float]]
    vtheta_km_s: List[Optional[float]]
    a_au: List[Optional[float]]
    e: List[Optional[float]]
    t_days: List[Optional[float]]
    three_d: Optional[Dict[str, list]] = key(flat=schema.STATE_KEYS + PLANE_FIELDS,
                                             default=None)

    def __post_init__(self):
        super().__post_init__()
        lengths = {f.name: len(getattr(self, f.name)) for f in dataclasses.fields(self)
                   if f.name != "three_d"}
        lengths.update((k, len(v)) for k, v in (self.three_d or {}).items())
        if len(set(lengths.values())) > 1:
            raise ValueError("its samples differ in number ("
                             + ", ".join(f"{k} {n}" for k, n in lengths.items()) + ")")


@dataclass(frozen=True)
class Segment(Record):
    """One row of a schedule: its start, pitch and length; ``clock_deg`` only in three
    dimensions, ``throttle`` only for a throttled problem, ``local_error_km`` only on an
    error-controlled closed form."""

    t_days: float
    theta_deg: float
    alpha_deg: float
    duration_days: float
    dtheta_deg: float
    clock_deg: Optional[float] = None
    throttle: Optional[float] = None
    local_error_km: Optional[float] = None


#: The columns every schedule has, and the optional ones in the order they follow.
SCHEDULE_FIELDS = tuple(f.name for f in dataclasses.fields(Segment)
                        if f.default is dataclasses.MISSING)
OPTIONAL_COLUMNS = tuple(f.name for f in dataclasses.fields(Segment)
                         if f.default is not dataclasses.MISSING)


@dataclass(frozen=True)
class Schedule(Record):
    """A schedule's rows and which optional columns it carries (a column may hold nulls:
    a segment CVODES could not fly has no local error)."""

    rows: Tuple[Segment, ...]
    throttled: bool
    local_errors: bool

    @property
    def columns(self):
        """The schedule's columns, in the file's order (solution.json and the CSV)."""
        on = {"clock_deg": bool(self.rows) and self.rows[0].clock_deg is not None,
              "throttle": self.throttled, "local_error_km": self.local_errors}
        return SCHEDULE_FIELDS + tuple(c for c in OPTIONAL_COLUMNS if on[c])

    @classmethod
    def from_json(cls, rows):
        if not isinstance(rows, list):
            raise BadField("", f"= {rows!r:.40} is not a list of segments")
        first = rows[0] if rows and isinstance(rows[0], dict) else {}
        return cls(rows=tuple(Segment.from_json(r) for r in rows),
                   throttled="throttle" in first, local_errors="local_error_km" in first)

    def to_json(self):
        columns = self.columns
        return [{k: v for k, v in r.to_json().items() if k in columns} for r in self.rows]

    def __iter__(self):
        return iter(self.rows)

    def __len__(self):
        return len(self.rows)

    def __getitem__(self, i):
        return self.rows[i]


@dataclass(frozen=True)
class Bounds(Record):
    """A position and a velocity bound, km and m/s."""

    position_km: float
    velocity_m_s: float


def _flight_failed(flight, value):
    """A failed flight has no final state, nor an NLP-to-target miss of its own."""
    return flight.error is not None


@dataclass(frozen=True)
class VerificationRecord(Record):
    """The CVODES verification of a schedule: misses against the NLP's final state and the
    target, the verifier's own error, the flown final state; ``extra``, the target's other
    misses by file name (``target_miss_a_km`` and ``target_miss_e`` of an (a, e) target, a
    body's ``relative_speed_km_s``, ``out_of_plane_km`` and, in 3-D, ``normal_miss_km``)."""

    miss_r_km: Optional[float]
    miss_v_m_s: Optional[float]
    miss_theta_deg: Optional[float]
    verifier_error_r_km: Optional[float]
    verifier_error_v_m_s: Optional[float]
    target_miss_r_km: Optional[float]
    target_miss_v_m_s: Optional[float]
    extra: Dict[str, Optional[float]] = key(flat=REST)
    nlp_target_miss_r_km: Optional[float] = key(omit=_flight_failed, default=None)
    error: Optional[str] = None
    cvodes_final_state: Optional[State] = key(omit=_flight_failed, default=None)
    cvodes_tof_days: Optional[float] = key(omit=_flight_failed, default=None)


@dataclass(frozen=True)
class Part(Record):
    """A problem part (departure or target) as solved: its kind and its fields, which
    depend on the kind (``part.a_au`` of a ParkingOrbit, ``part.body`` of a
    BodyDeparture; a body is given as its description)."""

    kind: str
    fields: Dict[str, object] = key(flat=REST)

    def __getattr__(self, name):
        try:
            return self.__dict__["fields"][name]
        except KeyError:
            raise AttributeError(f"{type(self).__name__} has no field {name!r}") from None


@dataclass(frozen=True)
class Settings(Record):
    """The problem as solved (``problem``): ``segments`` the count used, also when set per
    revolution; ``sub_arcs`` the count the error control ended with; ``departure_state`` the
    state the schedule is flown from; ``throttle_bounds`` only for a throttled sail."""

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
    throttle_bounds: Optional[List[float]] = key(omit=if_none, default=None)


@dataclass(frozen=True)
class DepartureBody(Record):
    """Where a dated departure leaves from: the body, its source, the distance from the
    ecliptic the 2-D model drops, and the excess velocity (angle in [-180, 180))."""

    name: str
    source: str
    out_of_plane_km: float
    vinf_km_s: float
    vinf_angle_deg: float


@dataclass(frozen=True)
class TargetBody(Record):
    """The body a BodyRendezvous or BodyIntercept flies to, as met: its distance from the
    ecliptic, and in 3-D the flight's miss along the ecliptic's normal."""

    name: str
    source: str
    kind: str
    out_of_plane_km: Optional[float]
    relative_speed_km_s: Optional[float]
    normal_miss_km: Optional[float] = None


@dataclass(frozen=True)
class ClassLooked(Record):
    """A turn count k on the target body the solve looked at (``classes.looked_at``):
    ``tof_days``, ``objective`` and ``ac_mm_s2_required`` (MinAcceleration) None where Ipopt
    found no point, ``verified`` where not flown; ``projected`` (written when true): the
    projected model's values, not lifted into 3-D."""

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
    projected: bool = key(omit=lambda record, value: not value, default=False)


@dataclass(frozen=True)
class NearestFeasible(Record):
    """For a fixed-time solve that found no point, the shortest flight found feasible from
    the same departure: the edge lies between ``infeasible_tof_days`` and ``tof_days``, and
    ``iterations`` are Ipopt's over the walk."""

    departure_date: Optional[str]
    tof_days: float
    ac_mm_s2_required: float
    verified: bool
    note: str
    infeasible_tof_days: float
    iterations: int


@dataclass(frozen=True)
class Stage(Record):
    """One stage of the closed-form solve: Ipopt's status and iterations."""

    status: str
    iterations: int


def _not_ran(polish, value):
    """A polish that did not run has only its status, verdict and note."""
    return not polish.ran


@dataclass(frozen=True, kw_only=True)
class Polish(Record):
    """solution.json's ``polish``: the polished optimum and its verification, or, when the
    closed form found nothing, only ``note`` (``status`` None).  ``verified``: Ipopt
    converged and the flight, its verifier's error included, is within ``bounds`` (1 m,
    1 mm/s) of the target and the polished NLP's final state.  ``departure_state`` and the
    calendar fields are the polished flight's own: flown from that state (at
    ``ac_mm_s2_required`` for MinAcceleration), the polished schedule is the flight verified."""

    status: Optional[str]
    converged: bool
    outcome: Optional[Outcome] = key(omit=_not_ran, default=None)
    iterations: Optional[int] = key(omit=_not_ran, default=None)
    seconds: Optional[float] = key(omit=_not_ran, default=None)
    constraint_violation: Optional[float] = key(omit=_not_ran, default=None)
    objective: Optional[float] = key(omit=_not_ran, default=None)
    tof_days: Optional[float] = key(omit=_not_ran, default=None)
    bounds: Optional[Bounds] = key(omit=_not_ran, default=None)
    within_bounds_vs_nlp: Optional[bool] = key(omit=_not_ran, default=None)
    within_bounds_vs_target: Optional[bool] = key(omit=_not_ran, default=None)
    verified: bool
    note: str
    schedule: Optional[Schedule] = key(omit=_not_ran, default=None)
    final_state: Optional[State] = key(omit=_not_ran, default=None)
    verification: Optional[VerificationRecord] = key(omit=_not_ran, default=None)
    departure_state: Optional[State] = key(omit=if_none, default=None)
    departure_date: Optional[str] = key(omit=if_none, default=None)
    departure_epoch_days: Optional[float] = key(omit=if_none, default=None)
    arrival_date: Optional[str] = key(omit=if_none, default=None)
    time_scale: Optional[str] = key(omit=if_none, default=None)
    ac_mm_s2_required: Optional[float] = key(omit=if_none, default=None)
    departure_body: Optional[DepartureBody] = key(omit=if_none, default=None)
    target_body: Optional[TargetBody] = key(omit=if_none, default=None)

    @property
    def ran(self):
        """Whether the polish ran (False: the closed-form solve found no optimum)."""
        return self.status is not None
