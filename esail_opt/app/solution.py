"""A solved problem in the boundary's units: the typed record of ``solution.json``.

Each key of the file is spelled once, on its field (:mod:`esail_opt.app.schema`
documents them), and a Solution built from a Run holds the same plain values a file read
back gives, so both print, plot and write alike.  Older readable versions
(:data:`esail_opt.app.schema.READABLE`) read with the keys they lack None or empty.
"""

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Tuple

from esail_opt.app import from_run, report, schema, solution_files
from esail_opt.app.record import BadField, Record, if_none, key, read
from esail_opt.app.solution_parts import (Bounds, ClassLooked, DepartureBody, NearestFeasible,
                                          Polish, Samples, Schedule, Settings, Stage, State,
                                          TargetBody, VerificationRecord)
from esail_opt.errors import InputError
from esail_opt.optimisation import pipeline
from esail_opt.optimisation.pipeline import Outcome, Round, StartTried
from esail_opt.optimisation.verify import sampled


def _not_polished(sol, value):
    """Keys that only a solve whose polish ran has."""
    return not sol.polished


def _no_classes(sol, value):
    """A file before version 5 names no classes."""
    return sol.classes_skipped is None


@dataclass(frozen=True, kw_only=True)
class Solution(Record):
    """A solved problem: what ``solution.json`` holds, typed, with reading, writing and
    printing.

    Make one with :meth:`of` (from a pipeline Run), :func:`solve`, or :meth:`load`.
    The fields follow the file's keys (:mod:`esail_opt.app.schema`), each key written on
    its field where the names differ; ``flight_verified`` (the file's ``verified``) is the
    closed form's flight alone, :attr:`verified` adds the polish's verdict.  Fields of the
    calendar and of the polish are None where the file leaves them out.
    """

    schema_version: int
    problem: Settings
    status: str
    converged: bool
    acceptable: bool
    outcome: Outcome
    flight_verified: bool = key("verified")
    verification_note: str
    tolerance: Bounds
    objective: Optional[float]
    objective_meaning: str
    tof_days: float
    iterations: int
    stages: Tuple[Stage, ...]
    solve_seconds: float
    constraint_violation: Optional[float]
    min_q3: Optional[float]
    schedule: Schedule
    final_state: State
    verification: VerificationRecord
    rounds: Tuple[Round, ...] = key("refinement.rounds")
    starts: Tuple[StartTried, ...] = key("refinement.starts")
    trajectory_closed_form: Samples = key("trajectory.closed_form")
    trajectory_cvodes: Optional[Samples] = key("trajectory.cvodes")
    trajectory_polished: Optional[Samples] = key("trajectory.polished", omit=_not_polished,
                                                 default=None)
    ac_mm_s2_required: Optional[float] = key(omit=if_none, default=None)
    departure_date: Optional[str] = key(omit=if_none, default=None)
    departure_epoch_days: Optional[float] = key(omit=if_none, default=None)
    arrival_date: Optional[str] = key(omit=if_none, default=None)
    time_scale: Optional[str] = key(omit=if_none, default=None)
    departure_body: Optional[DepartureBody] = key(omit=if_none, default=None)
    target_body: Optional[TargetBody] = key(omit=if_none, default=None)
    objective_closed_form: Optional[float] = key(omit=_not_polished, default=None)
    objective_exact: Optional[float] = key(omit=_not_polished, default=None)
    tof_days_exact: Optional[float] = key(omit=_not_polished, default=None)
    polish: Optional[Polish] = key(omit=if_none, default=None)
    classes: Tuple[ClassLooked, ...] = key("classes.looked_at", omit=_no_classes, default=())
    classes_skipped: Optional[str] = key("classes.not_looked_at", omit=_no_classes,
                                         default=None)
    nearest_feasible: Optional[NearestFeasible] = key(omit=if_none, default=None)

    @property
    def verified(self):
        """Converged, and the flight on Eqs. 1-2 meets the tolerance (and, after a
        polish, the polish's 1 m and 1 mm/s as well)."""
        return bool(self.flight_verified) and (self.polish is None or bool(self.polish.verified))

    @property
    def polished(self):
        """Whether a polish ran (and the file has its keys)."""
        return self.polish is not None and self.polish.ran

    @property
    def dated(self):
        """Whether the problem is on the calendar (a BodyDeparture)."""
        return self.departure_date is not None

    def __getitem__(self, name):
        """The field ``name`` of solution.json, as :meth:`to_json` writes it: for scripts
        that read the file's names (``sol["departure_date"]``)."""
        return self.to_json()[name]

    @classmethod
    def of(cls, run):
        """The Solution of a pipeline :class:`~esail_opt.optimisation.pipeline.Run`, its
        schedules drawn for the files and figures (``verify.sampled``): the closed form's
        with the defects it was solved with, and the polish's."""
        defects = None if run.error_control is None else run.error_control.defects
        polished = run.polish
        return cls(schema_version=schema.SCHEMA_VERSION, **from_run.solution_fields(
            run, sampled(run.problem, run.result, defects),
            sampled(run.problem, polished.result) if polished and polished.ran else None))

    @classmethod
    def from_json(cls, data, source="solution.json"):
        """A Solution from the content of a ``solution.json`` of a readable version;
        InputError (one line, naming ``source``) for another version or a missing field.
        """
        schema.check(data, source)
        try:
            return read(cls, schema.upgrade(data))
        except BadField as err:
            raise InputError(f"{source}: solution.json's field {err}; solve the problem "
                             "again to rewrite it") from None

    @classmethod
    def load(cls, path):
        """Read a ``solution.json`` back; one of another schema version, or one that is
        not a solution file, is refused with a one-line InputError that says so."""
        def constant(name):  # NaN and Infinity: never written, so never read
            raise ValueError(f"it holds {name}, which is not a number")

        try:
            data = json.loads(Path(path).read_text(), parse_constant=constant)
        except (OSError, ValueError) as err:
            raise InputError(f"{path}: cannot read solution.json ({err})") from None
        return cls.from_json(data, path)

    # The folder and the terminal summary are jobs of their own modules.
    write = solution_files.write
    schedule_csv = solution_files.schedule_csv
    plot = solution_files.plot
    summary = __str__ = report.summary


def solve(problem, segments=None, progress=None, polish=False):
    """Solve ``problem`` through the whole pipeline
    (:func:`esail_opt.optimisation.pipeline.solve`, whose parameters these are): its
    :class:`Solution`.  InputError, before any solve, if ``segments`` is not an integer
    >= 1.
    """
    return solve_with_nearest(problem, segments, progress, polish)[0]


def solve_with_nearest(problem, segments=None, progress=None, polish=False):
    """As :func:`solve`, and also the :class:`Solution` of the nearest feasible flight
    (the shortest time of flight that flies from the same departure) when the asked
    one found no point, else None: a whole answer to write beside the failed one."""
    run = pipeline.solve(problem, segments=segments, progress=progress, polish=polish)
    near = run.nearest_feasible
    return Solution.of(run), None if near is None else Solution.of(near.flight)
