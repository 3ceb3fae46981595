"""Sweeps: one problem file solved over a range of one parameter, on any executor.

``esail-opt sweep PROBLEM.py --param ac_mm_s2=0.2:2:10`` solves ten copies of the
problem, each with ``sail.ac_mm_s2`` replaced, and writes ``sweep.csv``, ``sweep.json``
and ``sweep.png``; with ``--robust RUNS`` each verified member is also flown under the
varying solar wind (:mod:`esail_opt.app.robust`).  The scan engine
(:mod:`esail_opt.app.engine`) runs the members, locally or on Dask, and journals them.
A member that fails is reported in its row (``error`` says why) and never stops the
others; a value that no problem accepts is refused before any member runs.  Only the
names in :data:`SWEEPABLE` can be swept, each mapped to one field of the
:class:`~esail_opt.optimisation.problem.Problem` tree, so a typo cannot send one anywhere.
"""

import dataclasses
import functools
import os
import time
from pathlib import Path
from typing import Optional

from esail_opt.app import engine, report
from esail_opt.app.outputs import csv_text, write_table_set
from esail_opt.runtime.files import check_output_dir
from esail_opt.runtime import pool
from esail_opt.runtime.journal import fields
from esail_opt.runtime.pool import first_line
from esail_opt.errors import InputError, check_range, number_range


@dataclasses.dataclass(frozen=True)
class Sweepable:
    """One parameter a sweep may vary: its dotted field ``path`` inside :class:`Problem`
    (``"sail.ac_mm_s2"``), ``kind`` (``float``, or ``int`` needing whole-number grid
    values) and ``unit`` at the boundary, for the table header and plot axis."""

    path: str
    kind: type
    unit: str


SWEEPABLE = {
    "ac_mm_s2": Sweepable("sail.ac_mm_s2", float, "mm/s^2"),
    "segments": Sweepable("segments.count", int, ""),
    "sub_arcs": Sweepable("segments.sub_arcs", int, ""),
    "target_radius_au": Sweepable("target.radius_au", float, "au"),
    "tof_days": Sweepable("objective.tof_days", float, "days"),
    "departure_a_au": Sweepable("departure.a_au", float, "au"),
    "max_revolutions": Sweepable("max_revolutions", float, "rev"),
}


@dataclasses.dataclass(frozen=True)
class SweepRow:
    """A member's row: its fields, in order, are sweep.csv's columns and the journal's
    keys, and their annotations what a journal row is checked against
    (:class:`esail_opt.runtime.journal.Journal`).  Rows travel as dicts of these fields."""

    index: int
    value: float
    converged: bool
    verified: Optional[bool]
    status: Optional[str]
    tof_days: Optional[float]
    objective: Optional[float]
    target_miss_r_km: Optional[float]
    target_miss_v_m_s: Optional[float]
    iterations: Optional[int]
    tof_days_exact: Optional[float]
    exact_verified: Optional[bool]
    exact_target_miss_km: Optional[float]
    robust_open_p95_km: Optional[float]
    robust_guided_p95_km: Optional[float]
    robust_guided_within: Optional[float]
    robust_verified: Optional[bool]
    seconds: Optional[float]
    error: Optional[str]


CSV_FIELDS = fields(SweepRow)

#: The journal of finished members, in the sweep's output folder.
JOURNAL = "sweep.jsonl"


# ---------------------------------------------------------------- input


def parse_param(text):
    """Parse ``NAME=START:STOP:COUNT`` (``"ac_mm_s2=0.2:2:10"``: COUNT values equally
    spaced from START to STOP, both included; COUNT = 1 needs START = STOP) into (name,
    list of float or int).  InputError, one line naming what is wrong (and, for an
    unknown name, the allowed ones).
    """
    form = "expected NAME=START:STOP:COUNT, e.g. ac_mm_s2=0.2:2:10"
    name, sep, spec = str(text).partition("=")
    name = name.strip()
    if not sep or not name:
        raise InputError(f"param = {text!r}: {form}")
    if name not in SWEEPABLE:
        raise InputError(f"param name = {name!r} is not one of: {', '.join(SWEEPABLE)}")
    if len(spec.split(":")) != 3:
        raise InputError(f"param = {text!r}: {form}")
    grid = number_range("param", spec)
    # 12 significant digits drop linspace's last-bit noise (0.6000000000000001).
    grid = [float(f"{v:.12g}") for v in grid]
    if SWEEPABLE[name].kind is int:
        if any(abs(v - round(v)) > 1e-9 for v in grid):
            raise InputError(f"param {name} is an integer and {spec} does not give whole "
                             "numbers")
        grid = [int(round(v)) for v in grid]
    return name, grid


def check_applicable(problem, name):
    """Raise InputError unless ``problem`` has the field that ``name`` sweeps (not
    ``tof_days`` on a minimum-time problem, say): the command's mistake, not a member's.
    """
    obj = problem
    for attr in SWEEPABLE[name].path.split("."):
        if obj is None or attr not in getattr(obj, "__dataclass_fields__", {}):
            holder = type(obj).__name__ if obj is not None else "None"
            raise InputError(f"param {name} ({SWEEPABLE[name].path}) does not apply to "
                             f"{problem.name}: its {holder} has no {attr}")
        obj = getattr(obj, attr)


def variant(problem, name, value):
    """The problem with the field that ``name`` maps to set to ``value``; InputError for
    a value out of its range (each dataclass on the path re-runs its checks).
    """
    if name == "segments":
        # A fixed count replaces a per-revolution rule, exactly as --segments does.
        return problem.with_segments(value)

    def replace(obj, attrs):
        if len(attrs) == 1:
            return dataclasses.replace(obj, **{attrs[0]: value})
        return dataclasses.replace(obj, **{attrs[0]: replace(getattr(obj, attrs[0]),
                                                             attrs[1:])})

    return replace(problem, SWEEPABLE[name].path.split("."))


# ---------------------------------------------------------------- one member


def _empty_row(index, value):
    """A row with nothing solved yet: every result field None, not converged."""
    return {**dict.fromkeys(CSV_FIELDS), "index": index, "value": value, "converged": False}


def solve_member(index, name, value, source, filename, polish=False, tol_km=None,
                 tol_m_s=None, robust_runs=0):
    """Solve member ``index`` of the grid (``name``, a key of :data:`SWEEPABLE`, set to
    ``value``) and return its row; never raises.

    The problem file travels as its text ``source`` (named ``filename``), so a Dask
    worker needs nothing on its disk but the package.  ``polish``: also polish on Eqs.
    1-2; ``tol_km``, ``tol_m_s``: bounds replacing the file's (None keeps them);
    ``robust_runs`` > 0: fly a verified member's schedule that many times under the
    varying solar wind (:func:`esail_opt.app.robust.run`), open loop and guided.

    The row has the fields of :data:`CSV_FIELDS`: ``converged``, Ipopt's Solve_Succeeded
    only; ``verified``, the CVODES flight's verdict against the tolerance;
    ``target_miss_*``, its misses; ``seconds``, wall time; ``error``, None or one line
    why the member failed (not converged, not verified...); with ``polish``, the
    polished ``tof_days_exact``, ``exact_verified`` (1 m, 1 mm/s) and
    ``exact_target_miss_km``; with ``robust_runs``, the p95 arrival misses open loop and
    guided, the guided fraction within tolerance and whether the Monte Carlo's CVODES
    checks agreed (``robust_verified``).
    """
    from esail_opt.app import solution

    row = _empty_row(index, value)
    start = time.perf_counter()
    try:
        problem = engine.load_source(source, filename)
        problem = variant(problem, name, value).with_tolerance(tol_km, tol_m_s)
        sol = solution.solve(problem, polish=polish)
        _fill(row, sol)
        if robust_runs and row["error"] is None:
            _fly(row, sol, robust_runs)
    except Exception as err:  # a member may fail in any way; its row says how
        row["error"] = first_line(err)
    row["seconds"] = time.perf_counter() - start
    return row


def _fill(row, sol):
    """Put a member's solution ``sol`` into its ``row``, with why it failed if it did."""
    check = sol.verification
    verified = sol.flight_verified
    row.update(converged=sol.converged, status=sol.status, tof_days=sol.tof_days,
               objective=sol.objective, iterations=sol.iterations, verified=bool(verified),
               target_miss_r_km=check.target_miss_r_km,
               target_miss_v_m_s=check.target_miss_v_m_s)
    exact = sol.polish
    if exact is not None:
        row.update(tof_days_exact=exact.tof_days, exact_verified=exact.verified,
                   exact_target_miss_km=(None if exact.verification is None
                                         else exact.verification.target_miss_r_km))
    if not sol.converged:
        row["error"] = f"not converged: Ipopt {sol.status}"
        if sol.nearest_feasible is not None:
            # What the member alone would have said: the walk to the edge of the feasible.
            row["error"] += f"; {report.nearest_feasible_line(sol.nearest_feasible)}"
    elif check.error:
        row["error"] = f"verification: {check.error}"
    elif not verified:
        # The verification's note names the bound missed and by how much.
        row["error"] = f"not verified: {sol.verification_note.strip().splitlines()[0]}"


def _fly(row, sol, runs):
    """The Monte Carlo of a member's verified schedule into its ``row``."""
    from esail_opt.app import robust

    flown = robust.run(sol, robust.Request(runs=runs))
    guided = flown.guided[0]
    row.update(robust_open_p95_km=flown.open_loop.percentiles()["p95"]["miss_km"],
               robust_guided_p95_km=guided.percentiles()["p95"]["miss_km"],
               robust_guided_within=guided.within(flown.tolerance),
               robust_verified=flown.verified)
    if not flown.verified:
        row["error"] = "robust: a flight re-flown on CVODES did not land where the closed " \
                       "form said"


# ---------------------------------------------------------------- the family


def default_out_dir(problem_file, param):
    """``results/<problem name>_sweep_<NAME>``: the command line's default folder.
    InputError for a bad ``param``, an unreadable problem file or a problem name that
    makes no safe folder name; OutputError if the folder cannot be created or written.
    """
    from esail_opt.optimisation.problem_file import load_problem

    name, _ = parse_param(param)
    folder = f"{load_problem(problem_file).name}_sweep_{name}"
    return check_output_dir(Path("results") / folder, name=folder)


def run(problem_file, param, workers=None, scheduler=None, progress=None, polish=False,
        out_dir=None, resume=False, tol_km=None, tol_m_s=None, retries=pool.RETRIES,
        robust_runs=0):
    """Solve the family of ``problem_file`` over ``param`` (:func:`parse_param`) on the
    scan engine (:func:`esail_opt.app.engine.run`, whose contract covers ``out_dir``'s
    journal, ``resume``, ``retries``, ``scheduler`` and KeyboardInterrupt) and return the
    table.  ``workers`` in [1, 64] (default min(COUNT, CPUs)); ``progress(row, done,
    total)`` after each member; ``polish``, ``tol_km``, ``tol_m_s`` and ``robust_runs``
    (only a dated 3-D rendezvous takes it) as for :func:`solve_member`.

    The table: ``problem``, ``robust_runs``, ``problem_file``, ``param``, ``field``,
    ``unit``, ``objective_meaning``, ``objective_shown_as`` ([factor, unit] of the
    objective column), ``values``, ``executor``, ``wall_seconds``, ``polished``,
    ``tolerance``, ``failed`` (rows with an error), ``rows`` (in grid order), ``journal``
    (its path or None), ``resumed`` and ``solved`` (indices) and ``lost`` (``{"index",
    "value", "losses", "cause"}`` per member charged with a lost worker).

    Raises, before any solve and before the journal changes, InputError for bad input
    of any kind (a journal ``resume`` cannot continue, an unreachable scheduler) and
    OutputError if ``out_dir`` cannot be written; ``pool.ClusterLost`` (one line saying
    what the journal keeps) if the Dask cluster was lost.
    """
    request = _check(problem_file, param, workers, scheduler, retries, resume, out_dir,
                     polish, tol_km, tol_m_s, robust_runs)
    outcome = engine.run(_scan(request), out_dir=out_dir, resume=resume,
                         workers=request.workers, scheduler=scheduler, retries=retries,
                         progress=progress)
    return _result(request, outcome)


@dataclasses.dataclass(frozen=True)
class _Request:
    """A checked sweep request: the grid (``name``, ``values``), the pool's ``workers``,
    the file's ``problem`` with the request's tolerance, its text ``source``, and what
    every member is passed on."""

    problem_file: str
    name: str
    values: list
    workers: int
    problem: object
    source: str
    polish: bool
    tol_km: object
    tol_m_s: object
    robust_runs: int

    def member(self, i):
        """The arguments of :func:`solve_member` after its index, for member ``i``."""
        return (self.name, self.values[i], self.source, Path(self.problem_file).name,
                self.polish, self.tol_km, self.tol_m_s, self.robust_runs)


def _check(problem_file, param, workers, scheduler, retries, resume, out_dir, polish,
           tol_km, tol_m_s, robust_runs):
    """The request of :func:`run`, checked before anything runs (InputError if bad)."""
    from esail_opt.optimisation.problem_file import load_problem

    name, values = parse_param(param)
    workers = engine.check_options(workers, scheduler, retries, resume, out_dir)
    workers = workers or min(len(values), os.cpu_count() or 1)
    # Loaded here too, so a bad file is one line instead of COUNT failed rows.
    problem = load_problem(problem_file).with_tolerance(tol_km, tol_m_s)
    check_applicable(problem, name)
    if check_range("--robust", robust_runs, 0, 10 ** 6):
        from esail_opt.app.robust import check_problem

        check_problem(problem)
    for value in values:  # a value no problem takes is the command's mistake
        try:
            variant(problem, name, value)
        except InputError as err:
            raise InputError(f"param {name}: {err}") from None
    if out_dir is not None:  # a sweep that cannot be written must not solve first
        check_output_dir(out_dir, files=SWEEP_FILES)
    return _Request(str(problem_file), name, values, workers, problem,
                    Path(problem_file).read_text(), polish, tol_km, tol_m_s, int(robust_runs))


def _scan(request):
    """The sweep as the engine runs it: one job per member."""
    values = request.values
    # robust_runs only where flown, so a journal written without it still resumes.
    robust = {"robust_runs": request.robust_runs} if request.robust_runs else {}
    return engine.Scan(
        journal_name=JOURNAL, row_type=SweepRow,
        header=engine.header("sweep", request.problem, request.source, request.name, values,
                             request.polish, **robust),
        count=len(values), function=solve_member,
        jobs={i: ([i], request.member(i)) for i in range(len(values))},
        failed_row=lambda i, message: {**_empty_row(i, values[i]), "error": message},
        belongs=functools.partial(belongs, values))


def belongs(values, i, row):
    """Whether a journal row is member ``i`` of the grid ``values``: its value is."""
    return row.get("value") == values[i]


def _result(request, outcome):
    """The table :func:`run` returns."""
    spec = SWEEPABLE[request.name]
    return {"problem": request.problem.name, "problem_file": request.problem_file,
            "robust_runs": request.robust_runs,
            "param": request.name, "field": spec.path, "unit": spec.unit,
            "objective_meaning": request.problem.objective.meaning,
            # What the objective column's canonical numbers are in a user's units.
            "objective_shown_as": list(request.problem.objective.shown_as()),
            "values": request.values, "executor": outcome.executor,
            "wall_seconds": outcome.seconds, "polished": request.polish,
            "tolerance": dataclasses.asdict(request.problem.tolerance),
            "failed": sum(1 for r in outcome.rows if r["error"] is not None),
            "rows": outcome.rows,
            "journal": None if outcome.journal is None else str(outcome.journal),
            "resumed": outcome.resumed, "solved": outcome.solved,
            "lost": [{"index": i, "value": request.values[i], "losses": n, "cause": cause}
                     for i, (n, cause) in outcome.lost.items()]}


# ---------------------------------------------------------------- output


def table_csv(result):
    """The rows as CSV text (floats to 10 significant digits, empty for missing), the
    parameter's column named after it (``tof_days_asked`` beside the flown ``tof_days``),
    the objective in a user's unit (days, mm/s^2) with ``objective_unit`` beside it;
    sweep.json keeps the canonical objective."""
    factor, unit = result.get("objective_shown_as") or (1.0, "")
    unit = unit.strip() or result.get("objective_meaning", "")
    param = result["param"]
    column = f"{param}_asked" if param in CSV_FIELDS else param
    rows = [dict(r, objective=None if r["objective"] is None else r["objective"] * factor,
                 objective_unit=unit, **{column: r["value"]}) for r in result["rows"]]
    at = CSV_FIELDS.index("objective") + 1
    fields = CSV_FIELDS[:at] + ("objective_unit",) + CSV_FIELDS[at:]
    return csv_text(rows, tuple(column if f == "value" else f for f in fields))


def figure(result, axes=None):
    """The Figure of :func:`run`'s table against the parameter: the objective (the time
    of flight too, when it is neither the objective nor the parameter) and the flown
    target miss against the tolerance, and with a Monte Carlo the p95 arrival misses;
    on ``axes`` (top to bottom) or a new Figure.  A member that converged but was not
    verified is a red cross at its value; one with no value (not converged, or failed)
    a red mark on the panel's bottom edge."""
    factor, unit = result.get("objective_shown_as") or (1.0, "")
    unit = unit.strip()
    named = {"mm/s^2": "a_c needed", "d": "time of flight"}.get(unit, "objective")
    panels = ((("tof_days", "time of flight [days]", "linear"),)
              if unit != "d" and result["param"] != "tof_days" else ())
    panels += (("objective", f"{named} [{unit}]" if unit else "objective (canonical)",
                "linear"),
               # The closed form is approximate: its flown miss belongs beside its optimum.
               ("target_miss_r_km", "flown target miss [km]", "log"))
    windy = bool(result.get("robust_runs"))
    fresh = axes is None
    if fresh:
        from matplotlib.figure import Figure

        count = len(panels) + windy
        axes = Figure(figsize=(6.4, 1.2 + 2.4 * count)).subplots(count, 1, sharex=True)
    for ax, (key, ylabel, scale) in zip(axes, panels):
        _panel(ax, result, key, scale, factor if key == "objective" else 1.0)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    misses = axes[len(panels) - 1]
    tolerance = (result.get("tolerance") or {}).get("position_km")
    if tolerance is not None:
        misses.axhline(tolerance, color="tab:red", lw=1, label="tolerance")
    axes[0].legend(fontsize=8)
    if result.get("polished") or tolerance is not None:
        misses.legend(fontsize=8)
    if windy:
        _wind_panel(axes[len(panels)], result)
    axes[-1].set_xlabel(result["param"] + (f" [{result['unit']}]" if result["unit"] else ""))
    rows = result["rows"]
    axes[0].set_title(f"{result['problem']}: sweep of {result['field']} "
                      f"({len(rows) - result['failed']}/{len(rows)} ok)")
    fig = axes[0].figure
    if fresh:
        fig.tight_layout()
    return fig


def _wind_panel(ax, result):
    """The Monte Carlo's 95th percentile arrival misses of each member, open loop and
    guided, against the position tolerance."""
    for key, colour, label in (("robust_open_p95_km", "tab:gray", "open loop"),
                               ("robust_guided_p95_km", "tab:blue", "guided")):
        points = [(r["value"], r[key]) for r in result["rows"] if r[key] is not None]
        if points:
            ax.plot(*zip(*points), "o-", color=colour, label=f"{label}, p95")
    ax.axhline(result["tolerance"]["position_km"], color="tab:red", lw=1,
               label="tolerance")
    ax.set_yscale("log")
    ax.set_ylabel(f"arrival miss under wind [km]\n({result['robust_runs']} flights a kind)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


#: The polished counterpart of a panel's closed-form column (in the panel's unit).
_EXACT = {"tof_days": "tof_days_exact", "target_miss_r_km": "exact_target_miss_km"}


def _panel(ax, result, key, scale, factor=1.0):
    """One panel: column ``key`` (times ``factor``) of the verified members, then of those
    that converged without being verified, then a mark for each with no value."""
    rows = result["rows"]

    def value(r):
        return None if r[key] is None else factor * r[key]

    good = [(r["value"], value(r)) for r in rows if r["error"] is None and r[key] is not None]
    unverified = [(r["value"], value(r)) for r in rows
                  if r["error"] is not None and r["converged"] and r[key] is not None]
    missing = [r["value"] for r in rows
               if r["error"] is not None and not (r["converged"] and r[key] is not None)]
    if good:
        ax.plot(*zip(*good), "o-", color="C0",
                label="verified (closed form)" if result.get("polished") else "verified")
    if result.get("polished") and key in _EXACT:
        _exact_points(ax, rows, _EXACT[key])
    if unverified:
        ax.plot(*zip(*unverified), "x", color="C3", ms=9, mew=2,
                label="converged, not verified")
    if missing:
        # A value Ipopt stopped at is no answer: the member is marked, not plotted.
        ax.plot(missing, [0.02] * len(missing), "v", color="C3", ms=9,
                transform=ax.get_xaxis_transform(), label="no answer (not converged)")
    if scale == "log" and (good or unverified):
        ax.set_yscale("log")


def _exact_points(ax, rows, key):
    """The polished schedules' numbers beside the closed form's; hollow where the
    polish is not verified."""
    points = [(r["value"], r[key], r["exact_verified"]) for r in rows
              if r["error"] is None and r[key] is not None]
    if not points:
        return
    ax.plot([p[0] for p in points], [p[1] for p in points], "s--", color="C2", ms=5,
            label="polished (exact; hollow: not verified)")
    hollow = [p for p in points if not p[2]]
    if hollow:
        ax.plot([p[0] for p in hollow], [p[1] for p in hollow], "s", mfc="white",
                color="C2", ms=7)


#: Every file :func:`write` puts in the sweep's folder, replaced as one set (the
#: journal and anything else there stay).
SWEEP_FILES = ("sweep.csv", "sweep.json", "sweep.png")


def write(result, out_dir):
    """Write sweep.csv, sweep.json and sweep.png into ``out_dir`` as one set
    (:func:`~esail_opt.app.outputs.write_table_set`); the journal stays beside them.
    OutputError if the folder cannot be written."""
    return write_table_set(out_dir, SWEEP_FILES, table_csv(result), result, figure(result))
