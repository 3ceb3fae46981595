"""``esail-opt-bench porkchop``: a launch-window scan timed three ways in one run.

The scan is a patch of the sail designer's porkchop of the shipped :data:`PROBLEM`
(minimum a_c to meet Venus, 6 departure dates x 4 times of flight = 24 cells), solved

* as ``esail-opt porkchop`` solves it: one closed-form NLP per revolution class, each
  cell warm from its solved neighbour, error control and verification per cell;
* the same scan with RK4 segments of Eqs. 1-2 (what a generic transcription would fly),
  with the fewest steps a segment whose first cell verifies, and the same reuse;
* every cell built and solved cold from the problem's own seed, as a script calling
  ``eo.solve`` once per cell would.

All three run in this process, one after another, on one core (no pool), so their seconds
compare; each method's seconds per cell are its wall time over its verified cells.
"""

import dataclasses
import time

from esail_opt.app.outputs import write_json
from esail_opt.app.porkchop import Grid, cell_problem
from esail_opt.bench.timing import print_table
from esail_opt.bodies import dates
from esail_opt.optimisation import scan
from esail_opt.optimisation.problem_file import shipped_problem
from esail_opt.optimisation.segment_methods import RK4

#: The shipped problem whose porkchop this bench scans.
PROBLEM = "earth_venus_min_ac_planar"
#: A patch of the shipped porkchop at 20-day spacing in both dates and flight times.
DEPARTURES = ("2031-01-01", "2031-04-11", 6)
TOFS_DAYS = (700.0, 760.0, 4)
#: RK4 steps a segment to choose from: the fewest whose first cell verifies, so that RK4
#: is timed at the accuracy the closed form's error control gives.
RK4_STEPS = (4, 8, 16, 32)


def _grid():
    import numpy as np

    lo, hi = (dates.jd_from_iso(d) for d in DEPARTURES[:2])
    return Grid(tuple(np.linspace(lo, hi, DEPARTURES[2])), tuple(np.linspace(*TOFS_DAYS)))


def _rows(grid, problem):
    """The scan's runs as ``esail-opt porkchop`` makes them on one worker: one path
    through the grid, with each cell's grid neighbours."""
    return [([cell_problem(problem, grid, i) for i in job], grid.neighbours(job))
            for job in grid.jobs(1)]


def _scan(rows, method=None):
    started = time.perf_counter()
    cells = [c for row, near in rows for c in scan.scan(row, method=method, neighbours=near)]
    return time.perf_counter() - started, cells


def _rebuild(rows):
    from esail_opt.app.solution import solve

    started = time.perf_counter()
    solutions = [solve(p) for row, _ in rows for p in row]
    return time.perf_counter() - started, solutions


def _warm_up(problem):
    """One untimed closed-form solve of ``problem`` so that the process's one-time costs
    (bodies' tracks, segment Functions) do not fall on the scan timed first (RK4's fall on
    :func:`_rk4_steps`'s trial solves)."""
    solver = scan.CellSolver()
    solver.verified_cell(solver.cold(problem))


def _rk4_steps(problem):
    """The fewest of :data:`RK4_STEPS` whose solve of ``problem`` on RK4 segments
    verifies (the last otherwise); these trial solves are not timed."""
    for steps in RK4_STEPS:
        solver = scan.CellSolver(RK4(steps))
        if solver.verified_cell(solver.cold(problem)).verified:
            return steps
    return RK4_STEPS[-1]


def run(out, repeats=1):
    """Time the planar scan three ways; writes ``porkchop.json`` and returns its path."""
    # The planar porkchop: its RK4 segments are the planar ones.
    problem = dataclasses.replace(shipped_problem(PROBLEM), planar=True)
    return timed_scans(out, "porkchop", PROBLEM, problem)


def timed_scans(out, label, name, problem):
    """Time the scan of ``problem`` over the bench's grid three ways (the closed form, RK4
    segments of Eqs. 1-2 or, in 3-D, of the turning plane's equations, every cell rebuilt);
    writes ``LABEL.json`` under ``out`` and returns its path."""
    from pathlib import Path

    rows = _rows(_grid(), problem)
    n = sum(len(r) for r, _ in rows)
    print(f"bench {label}: {n} cells, closed form ...", flush=True)
    _warm_up(rows[0][0][0])
    cf_seconds, cf_cells = _scan(rows)
    steps = _rk4_steps(rows[0][0][0])
    print(f"bench {label}: RK4 segments, {steps} steps a segment ...", flush=True)
    rk_seconds, rk_cells = _scan(rows, RK4(steps))
    print(f"bench {label}: each cell solved alone ...", flush=True)
    rb_seconds, rb_solutions = _rebuild(rows)
    counts = {"closed_form": sum(c.verified for c in cf_cells),
              "rk4": sum(c.verified for c in rk_cells),
              "rebuild": sum(s.verified for s in rb_solutions)}
    seconds = {"closed_form": cf_seconds, "rk4": rk_seconds, "rebuild": rb_seconds}
    per_cell = {k: (seconds[k] / counts[k] if counts[k] else None) for k in seconds}

    def ratio(a, b):
        return None if per_cell[a] is None or per_cell[b] is None else per_cell[a] / per_cell[b]

    data = {
        "case": {"problem": name, "planar": problem.planar, "departures": list(DEPARTURES),
                 "tofs_days": list(TOFS_DAYS), "rk4_steps": steps},
        "cells": n,
        "verified_cells": counts,
        "seconds": seconds,
        "seconds_per_cell": per_cell,
        "ratio_rebuild_over_closed_form": ratio("rebuild", "closed_form"),
        "ratio_rk4_over_closed_form": ratio("rk4", "closed_form"),
        "ac_mm_s2_closed_form": [c.result.ac_scale * c.problem.sail.ac_mm_s2
                                 if c.verified else None for c in cf_cells],
        "ac_mm_s2_rk4": [c.result.ac_scale * c.problem.sail.ac_mm_s2
                         if c.verified else None for c in rk_cells],
        "ac_mm_s2_rebuild": [s.ac_mm_s2_required if s.verified else None
                             for s in rb_solutions],
    }
    print_table(f"bench {label} (seconds per verified cell)",
                [(k, v if v is not None else "none verified", "s") for k, v in per_cell.items()]
                + [("rebuild / closed form", data["ratio_rebuild_over_closed_form"] or "n/a", ""),
                   ("rk4 / closed form", data["ratio_rk4_over_closed_form"] or "n/a", "")])
    path = Path(out) / f"{label}.json"
    write_json(path, data)
    return path
