"""Launch-window scans: one problem over departure dates, or dates x times of flight.

``esail-opt porkchop PROBLEM.py --depart 2030-01-01:2033-01-01:24`` solves the problem at every
departure date; with ``--tof 200:400:12``, at every (date, time of flight) cell, which with
``MinAcceleration`` is the sail designer's porkchop.  The scan engine (:mod:`esail_opt.app.engine`)
runs jobs of whole dates, each on one NLP (:func:`esail_opt.optimisation.scan.scan`).  Every cell is
verified as a lone solve is; cells where no sail exists are marked by :func:`mark_no_sail`.
"""

import dataclasses
import math
import os
from pathlib import Path
from typing import Optional

import numpy as np

from esail_opt.app import engine
from esail_opt.app.outputs import csv_text, write_table_set
from esail_opt.runtime.files import check_output_dir
from esail_opt.runtime import pool
from esail_opt.runtime.journal import fields
from esail_opt.runtime.pool import first_line
from esail_opt.bodies import dates, lookup
from esail_opt.errors import MAX_RANGE_COUNT, InputError, check_range, number_range
from esail_opt.optimisation import edge, pipeline, scan
from esail_opt.optimisation.problem_file import load_problem
from esail_opt.physics import constants as units



@dataclasses.dataclass(frozen=True)
class PorkchopRow:
    """A cell's row, carried as a dict of these fields: in order, they are the journal's and
    porkchop.json's keys, and their annotations what a journal row is checked against."""

    index: int
    departure_date: str
    tof_days_grid: Optional[float]
    converged: bool
    verified: bool
    no_sail: Optional[bool]  # null in journals written before the edge was walked
    status: Optional[str]
    departure_jd: float
    arrival_date: Optional[str]
    tof_days: Optional[float]
    objective: Optional[float]
    objective_unit: Optional[str]
    target_miss_r_km: Optional[float]
    target_miss_v_m_s: Optional[float]
    relative_speed_km_s: Optional[float]
    out_of_plane_km: Optional[float]
    iterations: Optional[int]
    start: Optional[str]
    seconds: Optional[float]
    error: Optional[str]
    edge_tof_days: Optional[float]
    edge_infeasible_tof_days: Optional[float]
    edge_ac_mm_s2: Optional[float]
    # Not in the CSV, only in porkchop.json and the journal: the flight, to fly it without a solve.
    ac_mm_s2_required: Optional[float]
    departure_state: Optional[dict]
    schedule: Optional[list]


#: The flight's fields (see :class:`PorkchopRow`), and the CSV's columns before them.
FLIGHT_FIELDS = ("ac_mm_s2_required", "departure_state", "schedule")
CSV_FIELDS = fields(PorkchopRow)[:-len(FLIGHT_FIELDS)]
JOURNAL = "porkchop.jsonl"
#: The files a porkchop writes as one set (its journal is kept beside them).
PORKCHOP_FILES = ("porkchop.csv", "porkchop.json", "porkchop.png")


def parse_dates(text, field="depart"):
    """``START:STOP:COUNT`` with ISO 8601 dates -> Julian dates (TDB), ends included."""
    parts = str(text).split(":")
    if len(parts) < 3:
        raise InputError(f"{field} = {text!r}: expected START:STOP:COUNT, e.g. "
                         "2030-01-01:2033-01-01:24")
    count_text = parts[-1]
    rest = ":".join(parts[:-1])
    start, stop = _split_pair(rest, text, field)
    lo = dates.jd_from_iso(start, f"{field} START")
    hi = dates.jd_from_iso(stop, f"{field} STOP")
    count = _count(count_text, text, field)
    if hi < lo:
        raise InputError(f"{field} = {text!r}: STOP comes before START")
    if count == 1 and hi != lo:
        raise InputError(f"{field} = {text!r}: COUNT = 1 needs START = STOP")
    if count > 1 and hi == lo:
        raise InputError(f"{field} = {text!r}: COUNT = {count} needs STOP after START "
                         "(the cells would be one date)")
    return list(np.linspace(lo, hi, count)) if count > 1 else [lo]


def _split_pair(rest, text, field):
    # Dates (YYYY-MM-DD[THH:MM[:SS]]) hold colons: the second starts at the last ':YYYY-'.
    for i in range(len(rest) - 1, 0, -1):
        if rest[i] == ":" and len(rest) > i + 5 and rest[i + 1:i + 5].isdigit() \
                and rest[i + 5] == "-":
            return rest[:i], rest[i + 1:]
    raise InputError(f"{field} = {text!r}: expected START:STOP:COUNT with ISO 8601 dates")


def _count(text, whole, field):
    try:
        count = int(text)
    except ValueError:
        raise InputError(f"{field} = {whole!r}: COUNT must be a whole number") from None
    if not 1 <= count <= MAX_RANGE_COUNT:
        raise InputError(f"{field} COUNT = {count} is outside [1, {MAX_RANGE_COUNT}]")
    return count


def parse_tofs(text):
    """``START:STOP:COUNT`` in days -> list of times of flight."""
    tofs = number_range("tof", text)
    lo = check_range("tof START", tofs[0], 0, 36525, low_open=True, unit="days")
    check_range("tof STOP", tofs[-1], lo, 36525, unit="days")
    return tofs


@dataclasses.dataclass(frozen=True)
class Grid:
    """A scan's cells: departure dates (Julian, TDB) and, in 2-D, times of flight (days)."""

    departures: tuple
    tofs: tuple = None

    @property
    def shape(self):
        return (len(self.departures),) + ((len(self.tofs),) if self.tofs else ())

    def cell(self, index):
        """(departure jd, tof days or None) of flat cell ``index`` (row-major)."""
        if self.tofs is None:
            return self.departures[index], None
        i, j = divmod(index, len(self.tofs))
        return self.departures[i], self.tofs[j]

    def path(self):
        """Every cell once, each beside the one before: by date, in 2-D every other row reversed."""
        if self.tofs is None:
            return list(range(len(self.departures)))
        m = len(self.tofs)
        return [i * m + (j if i % 2 == 0 else m - 1 - j)
                for i in range(len(self.departures)) for j in range(m)]

    def neighbours(self, indices):
        """For each cell of a run (flat indices), the run positions of its grid neighbours."""
        where = {index: k for k, index in enumerate(indices)}
        shape = self.shape
        out = []
        for index in indices:
            at = np.unravel_index(index, shape)
            near = []
            for axis in range(len(shape)):
                for step in (-1, 1):
                    other = list(at)
                    other[axis] += step
                    if 0 <= other[axis] < shape[axis]:
                        flat = int(np.ravel_multi_index(other, shape))
                        if flat in where:
                            near.append(where[flat])
            out.append(near)
        return out

    def jobs(self, workers):
        """The path cut into one run of neighbouring whole dates per worker, so that one job judges
        each date's cells against that date's edge of the feasible (:func:`mark_no_sail`)."""
        path = self.path()
        column = 1 if self.tofs is None else len(self.tofs)
        dates_per_job = math.ceil(len(self.departures)
                                  / max(1, min(workers, len(self.departures))))
        size = dates_per_job * column
        return [path[i:i + size] for i in range(0, len(path), size)]


def cell_problem(problem, grid, index):
    """``problem`` at the grid's cell ``index``: its date, and its time of flight."""
    jd, tof = grid.cell(index)
    return scan.at_date(problem, jd, tof)


def _row(index, grid, cell=None, error=None):
    jd, tof = grid.cell(index)
    row = dict.fromkeys(fields(PorkchopRow))
    row.update(index=index, departure_date=dates.iso_from_jd(jd), departure_jd=jd,
               tof_days_grid=tof, converged=False, verified=False, no_sail=False,
               error=error)
    if cell is None:
        return row
    result = cell.result
    factor, unit = cell.problem.objective.shown_as()
    row.update(converged=result.converged, verified=bool(cell.verified), status=result.status,
               iterations=result.iterations, start=cell.start, seconds=cell.seconds,
               target_miss_r_km=cell.misses.get("target_miss_r_km"),
               target_miss_v_m_s=cell.misses.get("target_miss_v_m_s"),
               relative_speed_km_s=cell.misses.get("relative_speed_km_s"),
               out_of_plane_km=cell.misses.get("out_of_plane_km"))
    if cell.solved:
        tof_tu = float(np.sum(result.durations))
        row.update(tof_days=units.time_to_days(tof_tu), objective=cell.objective * factor,
                   objective_unit=unit.strip(),
                   arrival_date=dates.iso_from_jd(dates.jd_from_tu(result.epoch + tof_tu)),
                   **_flight(cell))
    if not cell.verified and error is None:
        row["error"] = cell.note
    return row


def _flight(cell):
    """A solved cell's :data:`FLIGHT_FIELDS`, in solution.json's units and keys."""
    from esail_opt.app.from_run import departure_state, schedule

    problem, result = cell.problem, cell.result
    out = {"departure_state": departure_state(problem, result).to_json(),
           "schedule": schedule(problem, result).to_json()}
    if problem.objective.free_acceleration:
        out["ac_mm_s2_required"] = _ac_mm_s2(problem, result)
    return out


def _ac_mm_s2(problem, result):
    """The a_c a solved ``problem`` flies at, mm/s^2 (None unless it is free)."""
    if not problem.objective.free_acceleration:
        return None
    return problem.sail.ac_mm_s2 * result.ac_scale


def solve_job(job, indices, source, filename, tol_km=None, tol_m_s=None, departures=(),
              tofs=None, cells_out=None):
    """Solve a run of neighbouring cells on one NLP: their rows, marked by :func:`mark_no_sail`.
    Never raises for a cell: its row holds the failure.  With ``cells_out``, each verified cell's
    solution folder is written there (:func:`write_cell`)."""
    grid = Grid(tuple(departures), None if tofs is None else tuple(tofs))
    try:
        problem = engine.load_source(source, filename).with_tolerance(tol_km, tol_m_s)
        problems = [cell_problem(problem, grid, i) for i in indices]
        # Sent as the forward pass ends each; the rows after the repair pass are journaled.
        cells = scan.scan(problems, neighbours=grid.neighbours(indices),
                          on_cell=lambda k, cell: pool.send_partial(_row(indices[k], grid, cell)))
        rows = [_row(i, grid, c) for i, c in zip(indices, cells)]
    except Exception as err:  # the job's cells all say why
        return [_row(i, grid, error=first_line(err)) for i in indices]
    mark_no_sail(problems, cells, rows)
    for cell, row in zip(cells, rows):
        if cells_out is not None and row["verified"]:
            try:
                write_cell(cell, row, cells_out)
            except Exception as err:  # the cell flies; only its folder is missing
                row["error"] = f"cell folder not written: {first_line(err)}"
    return rows


def mark_no_sail(problems, cells, rows):
    """Mark the rows (in place) of the cells where no sail exists, date by date.  A cell has no sail
    when its own solve found no point (not a flight that missed) and the date's edge of the
    feasible, a verified flight, is longer.  The edge is walked once per date
    (:func:`esail_opt.optimisation.pipeline.nearest_feasible`) down from the shortest verified cell,
    else up from the longest cell with no point; an edge flight that does not verify leaves the
    shortest verified cell as the edge.  Every row of a walked date carries the edge
    (``edge_tof_days``, ``edge_ac_mm_s2``, ``edge_infeasible_tof_days``); a walk that fails leaves
    its rows unmarked, with the reason in the error of its cells with no point."""
    dates_of = {}
    for k, problem in enumerate(problems):
        dates_of.setdefault(problem.departure.date, []).append(k)
    for members in dates_of.values():
        lost = [k for k in members if not cells[k].solved]
        if not lost or not edge.walks(problems[lost[0]]):
            continue
        try:
            found = _edge([problems[k] for k in members], [cells[k] for k in members])
        except Exception as err:  # the cells stay failed solves, and say why
            for k in lost:
                rows[k]["error"] = f"{rows[k]['error']}; no edge: {first_line(err)}"
            continue
        if found is None:
            continue
        flight = found.flight
        for k in members:
            rows[k].update(edge_tof_days=found.tof_days,
                           edge_ac_mm_s2=_ac_mm_s2(flight.problem, flight.result),
                           edge_infeasible_tof_days=found.infeasible_tof_days)
            if k in lost and _tof(problems[k]) < found.tof_days:
                rows[k].update(no_sail=True, error=(
                    f"no sail: the shortest flight found feasible from this date is "
                    f"{found.tof_days:.1f} d (none found at {found.infeasible_tof_days:.1f} d)"))


def _tof(problem):
    return problem.objective.tof_days


def _edge(problems, cells):
    """The verified ``edge.Edge`` of one date's cells (see :func:`mark_no_sail`), or None: no cell
    with no point below the shortest verified one, or no verified flight found."""
    verified = [c for c in cells if c.verified]
    shortest = min(verified, key=lambda c: _tof(c.problem), default=None)
    below = [p for p, c in zip(problems, cells) if not c.solved
             and (shortest is None or _tof(p) < _tof(shortest.problem))]
    if not below:
        return None
    try:
        found = pipeline.nearest_feasible(max(below, key=_tof), start=shortest)
    except edge.NoLongerPoint:
        return None
    # Walked up from a cell with no point, the flight may not verify: no edge then.
    return found if found.verified else None


def cell_folder(row):
    """The name of a cell's solution folder: its index, date and time of flight."""
    tof = "" if row["tof_days_grid"] is None else f"_{row['tof_days_grid']:g}d"
    return f"cell_{row['index']:04d}_{row['departure_date'][:10]}{tof}"


def write_cell(cell, row, folder):
    """Write a verified cell's solution folder into ``folder``/:func:`cell_folder`, as
    ``esail-opt solve --no-plots`` would; the cell is within tolerance already."""
    from esail_opt.app.solution import Solution

    run = pipeline.run_from_optimum(cell.problem, cell.result, cell.transcription)
    return Solution.of(run).write(Path(folder) / cell_folder(row), plots=False)


def check(problem, grid):
    """InputError unless ``problem`` can be scanned over ``grid``."""
    if not problem.dated():
        raise InputError(f"departure = {type(problem.departure).__name__}: a porkchop scans "
                         "departure dates and needs departure = BodyDeparture(...)")
    if grid.tofs is not None and not problem.objective.fixed_time:
        raise InputError(f"objective = {type(problem.objective).__name__}: --tof needs a "
                         "fixed-time objective (e.g. MinAcceleration(tof_days=...))")
    longest = None if grid.tofs is None else max(grid.tofs)
    for jd in grid.departures:
        # Dates outside the ephemeris, and flights that would end past it, fail here.
        scan.at_date(problem, jd, longest)


def run(problem_file, depart, tof=None, workers=None, scheduler=None, progress=None,
        out_dir=None, resume=False, tol_km=None, tol_m_s=None, retries=pool.RETRIES,
        cells_out=None):
    """Scan ``problem_file`` over ``depart`` (and ``tof``) on the scan engine
    (:func:`esail_opt.app.engine.run`); the table as a dict.  ``cells_out``, a folder on the local
    pool's machine, receives each verified cell's solution folder.  Raises InputError on bad input
    (problem, grid, options, journal, scheduler) before any solve and before the journal changes."""
    request = _request(problem_file, depart, tof, workers, scheduler, retries, resume,
                       out_dir, tol_km, tol_m_s, cells_out)
    outcome = engine.run(_scan(request), out_dir=out_dir, resume=resume,
                         workers=request.workers, scheduler=scheduler, retries=retries,
                         progress=progress)
    return _table(request, outcome)


@dataclasses.dataclass(frozen=True)
class _Request:
    """A checked porkchop request: the problem, its grid, and the jobs' runs of cells."""

    problem_file: str
    problem: object
    source: str
    grid: Grid
    jobs: list
    workers: int
    param: str
    tol_km: object
    tol_m_s: object
    cells_out: object = None


def _request(problem_file, depart, tof, workers, scheduler, retries, resume, out_dir,
             tol_km, tol_m_s, cells_out=None):
    """The request of :func:`run`, checked before anything runs (InputError if bad)."""
    grid = Grid(tuple(parse_dates(depart)), None if tof is None else tuple(parse_tofs(tof)))
    workers = engine.check_options(workers, scheduler, retries, resume, out_dir)
    problem = load_problem(problem_file).with_tolerance(tol_km, tol_m_s)
    check(problem, grid)
    if out_dir is not None:
        check_output_dir(out_dir, files=PORKCHOP_FILES)
    if cells_out is not None:
        check_output_dir(cells_out)
    if cells_out is not None and scheduler is not None:
        raise InputError("--cells-out writes on this machine: it needs the local pool, "
                         "not --scheduler")
    jobs = grid.jobs(workers or os.cpu_count() or 1)
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    return _Request(str(problem_file), problem, Path(problem_file).read_text(), grid, jobs,
                    workers, f"depart={depart} tof={tof}", tol_km, tol_m_s,
                    None if cells_out is None else str(Path(cells_out).resolve()))


def _scan(request):
    """The porkchop as the engine runs it: one job per run of neighbouring cells."""
    grid = request.grid
    common = (request.source, Path(request.problem_file).name, request.tol_km,
              request.tol_m_s, [float(v) for v in grid.departures],
              None if grid.tofs is None else list(grid.tofs), request.cells_out)
    column = 1 if grid.tofs is None else len(grid.tofs)

    def part(j, missing):
        # Whole dates, judged together against their edge (mark_no_sail).
        dates_missing = {i // column for i in missing}
        cells = [i for i in request.jobs[j] if i // column in dates_missing]
        return cells, (cells, *common)

    return engine.Scan(
        journal_name=JOURNAL, row_type=PorkchopRow,
        header=engine.header("porkchop", request.problem, request.source, request.param,
                             [float(v) for v in grid.departures] + list(grid.tofs or [])),
        count=int(np.prod(grid.shape)), function=solve_job,
        jobs={j: (job, (job, *common)) for j, job in enumerate(request.jobs)},
        failed_row=lambda i, message: _row(i, grid, error=message), part=part)


def _table(request, outcome):
    """The table :func:`run` returns."""
    problem, grid, rows = request.problem, request.grid, outcome.rows
    verified = [r for r in rows if r["verified"]]
    return {"problem": problem.name, "problem_file": request.problem_file,
            "objective": type(problem.objective).__name__,
            "objective_unit": next((r["objective_unit"] for r in rows if r["objective_unit"]),
                                   None),
            "target": _target_name(problem),
            # What "verified" held each cell to, as sweep.json records it.
            "tolerance": {"position_km": problem.tolerance.position_km,
                          "velocity_m_s": problem.tolerance.velocity_m_s},
            "departures": [dates.iso_from_jd(jd) for jd in grid.departures],
            "tofs_days": None if grid.tofs is None else list(grid.tofs),
            "shape": list(grid.shape), "cells": len(rows), "verified_cells": len(verified),
            "not_verified": len(rows) - len(verified),
            "no_sail_cells": sum(bool(r.get("no_sail")) for r in rows),
            "edge": edge_line(rows),
            "best": min(verified, key=lambda r: r["objective"]) if verified else None,
            "executor": outcome.executor, "wall_seconds": outcome.seconds,
            "resumed": outcome.resumed, "rows": rows,
            "journal": None if outcome.journal is None else str(outcome.journal)}


def best_at_border(result):
    """Where the best cell lies on the scanned grid's border, in words ("the last
    departure date", "the shortest time of flight", ...), or None inside it or with no
    best: there the optimum may lie outside the range scanned."""
    best = result["best"]
    if best is None:
        return None
    dates_count, tofs_count = (*result["shape"], 1)[:2]  # a fixed time: one column
    i, j = divmod(best["index"], tofs_count)
    said = []
    if dates_count > 1 and i in (0, dates_count - 1):
        said.append(f"the {'first' if i == 0 else 'last'} departure date")
    if tofs_count > 1 and j in (0, tofs_count - 1):
        said.append(f"the {'shortest' if j == 0 else 'longest'} time of flight")
    return " and ".join(said) or None


def edge_line(rows):
    """The edge of the feasible per departure date, from the rows that carry it: one
    dict per date walked (``departure_date``, ``tof_days``, ``ac_mm_s2_required``,
    ``infeasible_tof_days``), in date order."""
    out = {}
    for row in rows:
        if row.get("edge_tof_days") is not None:
            out.setdefault(row["departure_jd"], {
                "departure_date": row["departure_date"], "tof_days": row["edge_tof_days"],
                "ac_mm_s2_required": row.get("edge_ac_mm_s2"),
                "infeasible_tof_days": row.get("edge_infeasible_tof_days")})
    return [out[jd] for jd in sorted(out)]


def _target_name(problem):
    body = getattr(problem.target, "body", None)
    return None if body is None else lookup.name(body)


def table_csv(result):
    """The rows as CSV text, every number as Python writes it."""
    return csv_text(result["rows"], CSV_FIELDS, digits=None)


#: The legend's words for the chart's marks.
NO_SAIL_LABEL = "no sail (shorter than the edge)"
EDGE_LABEL = "edge: shortest feasible flight"
FAILED_LABEL = "not verified"
VERIFIED_LABEL = "verified"
ARRIVAL_LABEL = "arrival date"


def figure(result):
    """The porkchop, drawn from ``result`` alone, for a grid of any shape.  Dates x flight times:
    the objective's contours, lines of constant arrival date and the edge of the feasible
    (:func:`edge_line`).  One date: the objective against the time of flight, the edge a vertical
    line; else against the date.  Without contours, values are written beside the verified cells (in
    one dimension, only if three or fewer).  Crosses mark cells not verified, hollow squares cells
    with no sail, a star the best."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.add_subplot()
    rows = result["rows"]
    edge = {e["departure_date"]: e["tof_days"] for e in result.get("edge") or edge_line(rows)}
    marks = {"date": np.array([_day(r["departure_date"]) for r in rows]),
             "tof": _floats(r["tof_days_grid"] for r in rows),
             "value": _floats(r["objective"] for r in rows),
             # The edge of each cell's date, NaN where none was walked.
             "edge": _floats(edge.get(r["departure_date"]) for r in rows),
             "ok": np.array([bool(r["verified"]) for r in rows], bool),
             "no_sail": np.array([bool(r.get("no_sail")) for r in rows], bool)}
    unit = result["objective_unit"] or ""
    label = {"MinTime": "time of flight [d]", "MinAcceleration": f"required a_c [{unit}]"}.get(
        result["objective"], f"{result['objective']} [{unit}]")
    dates_n, tofs_n = (list(result["shape"]) + [1])[:2]
    two_d = dates_n > 1 and tofs_n > 1
    across = "tof" if dates_n == 1 and tofs_n > 1 else "date"
    if two_d:
        contoured, y = _dates_tofs_chart(fig, ax, result["shape"], marks, label), marks["tof"]
        dots = {"ls": "", "ms": 4, "mfc": "k", "mec": "w", "mew": 0.6}
    else:
        contoured, y, dots = False, _line_chart(ax, marks, across, label), {"ms": 5}
    x, ok, no_sail = marks[across], marks["ok"], marks["no_sail"]
    for mask, style, name in ((ok, dict(marker="o", **dots), VERIFIED_LABEL),
                              (~ok & ~no_sail, dict(ls="", marker="x", color="C3", ms=8),
                               FAILED_LABEL),
                              (no_sail, dict(ls="", marker="s", mfc="none", mec="0.3", ms=7),
                               NO_SAIL_LABEL)):
        if mask.any():
            ax.plot(x[mask], y[mask], label=name, **style)
    if not contoured and (two_d or ok.sum() <= 3):
        x0, x1 = ax.get_xlim()
        for xv, yv, value in zip(x[ok], y[ok], marks["value"][ok]):
            side = 1 if xv <= (x0 + x1) / 2 else -1  # towards the middle: inside the axes
            ax.annotate(f"{value:.4g} {unit}".strip(), (xv, yv), xytext=(12 * side, 0),
                        textcoords="offset points", ha="left" if side > 0 else "right",
                        va="center", fontsize=9)
    best = result["best"]
    if best is not None:
        ax.plot([best["tof_days_grid"] if across == "tof" else _day(best["departure_date"])],
                [best["tof_days_grid"] if two_d else best["objective"]], "*", color="gold",
                mec="k", ms=16, label="best", zorder=5)
    if across == "date":
        _date_axis(ax.xaxis)
    ax.set_xlabel("departure date (TDB)" if across == "date" else "time of flight [d]")
    target = result["target"] or "target"
    # Without a grid of flight times, a fixed-time problem's every cell flies its own.
    fixed = {round(r["tof_days"], 6) for r in rows if r["tof_days"] is not None}
    tof = (result["tofs_days"][0] if result["tofs_days"] and tofs_n == 1 else
           fixed.pop() if not result["tofs_days"] and result["objective"] != "MinTime"
           and len(fixed) == 1 else None)
    where = [f"leaving {result['departures'][0][:10]}" if dates_n == 1 else "",
             "" if tof is None else f"in {tof:g} d"]
    count = int(no_sail.sum())
    ax.set_title(f"{result['problem']}: to {target}" + "".join(f", {w}" for w in where if w)
                 + f"\n{result['verified_cells']}/{result['cells']} cells verified"
                 + (f", {count} with no sail" if count else ""),
                 parse_math=False)  # names as written
    ax.grid(alpha=0.3)
    fig.legend(loc="outside lower center", ncols=4, fontsize=8)
    return fig


def _floats(values):
    return np.array([np.nan if v is None else v for v in values], float)


def _day(iso):
    """An ISO 8601 date as a matplotlib date number (days)."""
    from datetime import datetime

    import matplotlib.dates as mdates

    return mdates.date2num(datetime.fromisoformat(iso))


def _date_axis(axis):
    """Calendar dates, ISO style, at ticks that suit the span: years, months, days or hours."""
    import matplotlib.dates as mdates

    locator = mdates.AutoDateLocator(minticks=3, maxticks=6)
    formatter = mdates.AutoDateFormatter(locator)
    formatter.scaled = {mdates.DAYS_PER_YEAR: "%Y", mdates.DAYS_PER_MONTH: "%Y-%m",
                        1.0: "%Y-%m-%d", 1 / mdates.HOURS_PER_DAY: "%Y-%m-%d %H:%M"}
    axis.set_major_locator(locator)
    axis.set_major_formatter(formatter)


def _fit(set_lim, values, least, pad=0.06):
    """Limits around the finite ``values``, padded by ``pad`` of their span (``least`` each side for
    a single value), so that the marks at the ends sit inside."""
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if values.size:
        lo, hi = values.min(), values.max()
        step = pad * (hi - lo) if hi > lo else least
        set_lim(lo - step, hi + step)


def _halo(texts, colour):
    """Outline ``texts`` in ``colour``, so that they read on any fill and on white."""
    from matplotlib import patheffects

    for text in texts:
        text.set_path_effects([patheffects.withStroke(linewidth=2, foreground=colour)])


def _line_chart(ax, marks, across, label):
    """One dimension: the objective against the date or the time of flight (with one date, its edge
    of the feasible too); returns each cell's height, cells with no value at the top."""
    x, value, edge = marks[across], marks["value"], marks["edge"][:1]
    top = np.nanmax(value) if np.isfinite(value).any() else 0.0
    y = np.where(np.isfinite(value) & ~marks["no_sail"], value, top)
    if across == "tof" and np.isfinite(edge).all():
        ax.axvline(edge[0], color="C1", lw=1.5, label=EDGE_LABEL)
    _fit(ax.set_xlim, np.r_[x, edge] if across == "tof" else x,
         10.0 if across == "date" else 5.0)
    _fit(ax.set_ylim, y, 0.1 * abs(top) or 1.0)
    ax.set_ylabel(label)
    return y


def _dates_tofs_chart(fig, ax, shape, marks, label):
    """Two dimensions: the axes over dates and flight times, the objective's contours
    (whether drawn is returned: four verified cells and more, not all one value), the
    edge of the feasible and lines of constant arrival date."""
    x, tofs = marks["date"].reshape(shape)[:, 0], marks["tof"].reshape(shape)[0]
    # NaN where no edge was walked: the line breaks rather than join unknown dates.
    edge = marks["edge"].reshape(shape)[:, 0]
    _fit(ax.set_xlim, x, 10.0)
    _fit(ax.set_ylim, np.r_[tofs, edge], 5.0)
    z = np.where(marks["ok"], marks["value"], np.nan).reshape(shape).T
    contoured = np.isfinite(z).sum() >= 4 and np.nanmax(z) > np.nanmin(z)
    if contoured:
        cs = ax.contourf(x, tofs, z, levels=12, cmap="viridis")
        lines = ax.contour(x, tofs, z, levels=cs.levels[::2], colors="w", linewidths=0.6)
        _halo(ax.clabel(lines, fmt="%.2g", fontsize=7, use_clabeltext=True), "0.2")
        fig.colorbar(cs, ax=ax, label=label)
    _arrival_lines(ax)
    if np.isfinite(edge).any():
        ax.plot(x, edge, "o-", color="C1", ms=4, lw=1.5, label=EDGE_LABEL)
    ax.set_ylabel("time of flight [d]")
    return contoured


def _arrival_lines(ax):
    """Dashed lines of constant arrival date (departure + time of flight) across the
    axes, at dates that match their span, each labelled with its ISO month (or day)."""
    import matplotlib.dates as mdates

    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    xx, yy = np.meshgrid(np.linspace(x0, x1, 20), np.linspace(y0, y1, 20))
    levels = [t for t in mdates.AutoDateLocator(minticks=3, maxticks=6).tick_values(
        *mdates.num2date([x0 + y0, x1 + y1])) if x0 + y0 < t < x1 + y1]
    if not levels:
        return
    names = {t: f"arr {mdates.num2date(t):%Y-%m}" if mdates.num2date(t).day == 1
             else f"arr {mdates.num2date(t):%Y-%m-%d}" for t in levels}
    lines = ax.contour(xx, yy, xx + yy, levels=levels, colors="0.25", linestyles="--",
                       linewidths=0.7)
    _halo(ax.clabel(lines, fmt=names, fontsize=7, use_clabeltext=True), "w")
    ax.plot([], [], "--", color="0.25", lw=0.7, label=ARRIVAL_LABEL)


def write(result, out_dir, plots=True):
    """Write porkchop.csv, porkchop.json and (with ``plots``) porkchop.png into ``out_dir`` as one
    set (:func:`~esail_opt.app.outputs.write_table_set`); returns the paths."""
    return write_table_set(out_dir, PORKCHOP_FILES, table_csv(result), result,
                           figure(result) if plots else None)
