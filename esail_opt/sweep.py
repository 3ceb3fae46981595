"""Sweeps: one problem file solved over a range of one parameter, on any executor.

``esail-opt sweep PROBLEM.py --param ac_mm_s2=0.2:2:10`` solves ten copies of the
problem, each with ``sail.ac_mm_s2`` replaced, and writes ``sweep.csv``,
``sweep.json`` and ``sweep.png``.  The members run on a :mod:`concurrent.futures`
executor: a local process pool by default, or Dask distributed's executor when a
scheduler address is given -- the same code path either way, so moving a sweep to a
cluster changes one option and no numbers.

Each member is independent and returns a plain dict row.  A member that raises or
does not converge is reported in its row (``converged`` False, ``error`` says why);
it never stops the others.  Rows are ordered by parameter value, whatever order the
members finish in.

Only the names in :data:`SWEEPABLE` can be swept; each maps to one field of the
:class:`~esail_opt.optimisation.problem.Problem` tree, so the mapping is explicit
rather than a free-form attribute path a typo could send anywhere.
"""

import csv
import dataclasses
import io
import math
import os
import sys
import tempfile
import time
from concurrent.futures import as_completed
from pathlib import Path

import numpy as np

from esail_opt.errors import InputError
from esail_opt.files import atomic_path, json_ready, save_figure, write_json


@dataclasses.dataclass(frozen=True)
class Sweepable:
    """One parameter a sweep may vary.

    Attributes
    ----------
    path : str
        Dotted field path inside :class:`Problem`, e.g. ``"sail.ac_mm_s2"``.
    kind : type
        ``float`` or ``int``; integer parameters need whole-number grid values.
    unit : str
        Unit at the boundary, for the table header and plot axis.
    """

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

CSV_FIELDS = ("index", "value", "converged", "status", "tof_days", "objective",
              "target_miss_r_km", "target_miss_v_m_s", "iterations", "tof_days_exact",
              "exact_verified", "exact_target_miss_m", "seconds", "error")


# ---------------------------------------------------------------- input


def parse_param(text):
    """Parse ``NAME=START:STOP:COUNT`` into (name, values).

    Parameters
    ----------
    text : str
        E.g. ``"ac_mm_s2=0.2:2:10"``: COUNT values equally spaced from START to STOP,
        both included (COUNT = 1 gives START alone).

    Returns
    -------
    tuple
        (name, list of float or int).

    Raises
    ------
    InputError
        One line naming what is wrong (and, for an unknown name, the allowed ones).
    """
    form = "expected NAME=START:STOP:COUNT, e.g. ac_mm_s2=0.2:2:10"
    name, sep, spec = str(text).partition("=")
    name = name.strip()
    if not sep or not name:
        raise InputError(f"param = {text!r}: {form}")
    if name not in SWEEPABLE:
        raise InputError(f"param name = {name!r} is not one of: {', '.join(SWEEPABLE)}")
    parts = spec.split(":")
    if len(parts) != 3:
        raise InputError(f"param = {text!r}: {form}")
    try:
        start, stop = float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"param = {text!r}: START and STOP must be numbers") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise InputError(f"param = {text!r}: START and STOP must be finite")
    try:
        count = int(parts[2])
    except ValueError:
        raise InputError(f"param = {text!r}: COUNT = {parts[2]!r} is not an integer") from None
    if count < 1:
        raise InputError(f"param COUNT = {count} is outside [1, inf)")
    # linspace rather than repeated addition: the grid ends exactly on STOP, and the
    # same text always gives the same floats.
    grid = [start] if count == 1 else np.linspace(start, stop, count).tolist()
    # 12 significant digits drop linspace's last-bit noise (0.6000000000000001), so a
    # member solves, and its row shows, the value the user meant.
    grid = [float(f"{v:.12g}") for v in grid]
    if SWEEPABLE[name].kind is int:
        if any(abs(v - round(v)) > 1e-9 for v in grid):
            raise InputError(f"param {name} is an integer and {spec} does not give whole "
                             "numbers")
        grid = [int(round(v)) for v in grid]
    return name, grid


def check_applicable(problem, name):
    """Raise InputError unless ``problem`` has the field that ``name`` sweeps.

    E.g. ``target_radius_au`` on a problem with an (a, e) target, or ``tof_days`` on a
    minimum-time problem: that is a mistake in the command, not a failed member.
    """
    obj = problem
    for attr in SWEEPABLE[name].path.split("."):
        if obj is None or attr not in getattr(obj, "__dataclass_fields__", {}):
            holder = type(obj).__name__ if obj is not None else "None"
            raise InputError(f"param {name} ({SWEEPABLE[name].path}) does not apply to "
                             f"{problem.name}: its {holder} has no {attr}")
        obj = getattr(obj, attr)


def variant(problem, name, value):
    """The problem with the field that ``name`` maps to set to ``value``.

    Rebuilding each dataclass on the path re-runs its range checks, so an invalid value
    raises InputError here, inside the member, where it becomes that member's row.
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
    row = dict.fromkeys(CSV_FIELDS)
    row.update(index=index, value=value, converged=False)
    return row


def solve_member(index, name, value, source, filename, polish=False):
    """Solve one member of the family and return its row; never raises.

    The problem file travels as text so that a worker on another machine (Dask) needs
    nothing on its disk but the package; it is written to a private temporary folder
    and loaded as the command line would.

    Parameters
    ----------
    index : int
        Position of ``value`` in the grid (rows are sorted on it).
    name : str
        Key of :data:`SWEEPABLE`.
    value : float or int
    source : str
        Text of the problem file.
    filename : str
        Its file name, so load errors read as they would for ``esail-opt solve``.
    polish : bool
        Also polish the member on exact CVODES arcs (``solution.solve(polish=True)``).

    Returns
    -------
    dict
        The fields of :data:`CSV_FIELDS`: ``converged`` is True only for Ipopt's
        Solve_Succeeded; ``target_miss_*`` are the CVODES verification's misses
        against the target; ``seconds`` is this member's wall time; ``error`` is None
        or one line saying why the member failed.  With ``polish``:
        ``tof_days_exact``, ``exact_verified`` (the polished schedule flies to within
        1 m and 1 mm/s) and ``exact_target_miss_m``; None without.
    """
    from esail_opt import solution
    from esail_opt.optimisation.problem_file import load_problem

    row = _empty_row(index, value)
    start = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="esail_sweep_") as tmp:
            path = Path(tmp) / filename
            path.write_text(source)
            problem = load_problem(path)
        sol = solution.solve(variant(problem, name, value), polish=polish)
        check = sol["verification"]
        row.update(converged=sol.converged, status=sol["status"], tof_days=sol["tof_days"],
                   objective=sol["objective"], iterations=sol["iterations"],
                   target_miss_r_km=check.get("target_miss_r_km"),
                   target_miss_v_m_s=check.get("target_miss_v_m_s"))
        exact = sol.data.get("polish")
        if exact is not None:
            row.update(tof_days_exact=exact.get("tof_days"), exact_verified=exact["verified"],
                       exact_target_miss_m=(exact.get("verification") or {}).get(
                           "target_miss_r_m"))
        if not sol.converged:
            row["error"] = f"not converged: Ipopt {sol['status']}"
        elif check.get("error"):
            row["error"] = f"verification: {check['error']}"
    except Exception as err:  # a member may fail in any way; its row says how
        detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
        row["error"] = f"{type(err).__name__}: {detail}".rstrip(": ")
    row["seconds"] = time.perf_counter() - start
    return row


# ---------------------------------------------------------------- the family


def _executor(workers, scheduler):
    """The executor and a closer for it: a local process pool or Dask's.

    Returns
    -------
    tuple
        (executor, description, close) with ``close()`` releasing everything.
    """
    if scheduler is None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # spawn, not fork: the parent has CasADi and maybe threads loaded, and a forked
        # child of a threaded process can deadlock; spawn costs one import per worker.
        pool = ProcessPoolExecutor(max_workers=workers,
                                   mp_context=multiprocessing.get_context("spawn"))
        return pool, f"process pool, {workers} workers", lambda: pool.shutdown(wait=True)
    try:
        from dask.distributed import Client
    except ImportError:
        raise InputError("--scheduler needs Dask: pip install 'esail_opt[dask]'") from None
    try:
        client = Client(scheduler, timeout=30)
    except (OSError, TimeoutError) as err:
        raise InputError(f"scheduler {scheduler!r} cannot be reached: {err}") from None
    executor = client.get_executor()

    def close():
        executor.shutdown(wait=True)
        client.close()

    return executor, f"dask distributed at {scheduler}", close


def run(problem_file, param, workers=None, scheduler=None, progress=None, polish=False):
    """Solve the family of ``problem_file`` over ``param`` and return the table.

    Parameters
    ----------
    problem_file : str or Path
        A problem file defining ``problem``.
    param : str
        ``NAME=START:STOP:COUNT`` (see :func:`parse_param`).
    workers : int, optional
        Process-pool size, >= 1 (default: min(COUNT, CPUs)); ignored with
        ``scheduler``, whose cluster decides.
    scheduler : str, optional
        Address of a Dask distributed scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    progress : callable, optional
        ``progress(row, done, total)`` after each finished member.
    polish : bool
        Polish every member on exact CVODES arcs as well (see :func:`solve_member`).

    Returns
    -------
    dict
        ``problem``, ``problem_file``, ``param``, ``field``, ``unit``, ``values``,
        ``executor``, ``wall_seconds``, ``failed`` (count) and ``rows`` (one per value,
        in grid order).

    Raises
    ------
    InputError
        Bad ``param`` or ``workers``, an unreadable problem file, a parameter the
        problem does not have, or an unreachable scheduler -- all before any solve.
    """
    from esail_opt.optimisation.problem_file import load_problem

    name, values = parse_param(param)
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise InputError(f"workers = {workers!r} is outside [1, inf)")
    workers = int(workers) if workers is not None else min(len(values), os.cpu_count() or 1)
    # Loaded here too, so a broken file or an inapplicable parameter is one line at
    # once instead of COUNT identical failed rows.
    problem = load_problem(problem_file)
    check_applicable(problem, name)
    source = Path(problem_file).read_text()
    filename = Path(problem_file).name

    executor, described, close = _executor(workers, scheduler)
    rows = [None] * len(values)
    start = time.perf_counter()
    try:
        futures = [executor.submit(solve_member, i, name, v, source, filename, polish)
                   for i, v in enumerate(values)]
        for done, future in enumerate(as_completed(futures), 1):
            try:
                row = future.result()
            except Exception as err:  # a lost worker: solve_member itself never raises
                i = futures.index(future)
                row = _empty_row(i, values[i])
                row["error"] = f"{type(err).__name__}: {err}".splitlines()[0]
            rows[row["index"]] = row
            if progress:
                progress(row, done, len(values))
    finally:
        close()
    spec = SWEEPABLE[name]
    return {"problem": problem.name, "problem_file": str(problem_file), "param": name,
            "field": spec.path, "unit": spec.unit, "values": values, "executor": described,
            "wall_seconds": time.perf_counter() - start, "polished": polish,
            "failed": sum(1 for r in rows if r["error"] is not None), "rows": rows}


# ---------------------------------------------------------------- output


def table_csv(result):
    """The rows as CSV text (floats to 10 significant digits, empty for missing)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_FIELDS, lineterminator="\n")
    writer.writeheader()
    for row in result["rows"]:
        writer.writerow({k: ("" if row[k] is None else
                             f"{row[k]:.10g}" if isinstance(row[k], float) else row[k])
                         for k in CSV_FIELDS})
    return buf.getvalue().replace("value", result["param"], 1)


def figure(result):
    """Time of flight, objective and verified target miss against the parameter; failed
    members in red."""
    import matplotlib

    matplotlib.use("Agg")  # files only: never needs a display
    import matplotlib.pyplot as plt

    rows = result["rows"]
    label = result["param"] + (f" [{result['unit']}]" if result["unit"] else "")
    fig, axes = plt.subplots(3, 1, figsize=(6.4, 8.0), sharex=True)
    panels = ((axes[0], "tof_days", "time of flight [days]", "linear"),
              (axes[1], "objective", "objective", "linear"),
              # The closed form is first order: how far its schedule, flown on Eqs. 1-2,
              # ends from the target belongs beside the optimum it claims.
              (axes[2], "target_miss_r_km", "verified target miss [km]", "log"))
    for ax, key, ylabel, scale in panels:
        good = [(r["value"], r[key]) for r in rows if r["error"] is None and r[key] is not None]
        bad = [(r["value"], r[key]) for r in rows if r["error"] is not None]
        if good:
            ax.plot(*zip(*good), "o-", color="C0",
                    label="converged (closed form)" if result.get("polished") else "converged")
        exact_key = {"tof_days": "tof_days_exact", "target_miss_r_km": "exact_target_miss_m"}
        if result.get("polished") and key in exact_key:
            # The polished schedule's numbers beside the closed form's (metres to km).
            scale_by = 1e-3 if key == "target_miss_r_km" else 1.0
            exact = [(r["value"], scale_by * r[exact_key[key]]) for r in rows
                     if r["error"] is None and r[exact_key[key]] is not None]
            if exact:
                ax.plot(*zip(*exact), "s--", color="C2", ms=5,
                        label="polished (exact; hollow: not verified)")
                hollow = [(r["value"], scale_by * r[exact_key[key]]) for r in rows
                          if r["error"] is None and r[exact_key[key]] is not None
                          and not r["exact_verified"]]
                if hollow:
                    ax.plot(*zip(*hollow), "s", mfc="white", color="C2", ms=7)
        shown = [(v, y) for v, y in bad if y is not None]
        if shown:
            ax.plot(*zip(*shown), "x", color="C3", ms=9, mew=2, label="not converged")
        # A member with no number at all still gets a mark, on the bottom edge.
        missing = [v for v, y in bad if y is None]
        if missing:
            ax.plot(missing, [0.02] * len(missing), "v", color="C3", ms=9,
                    transform=ax.get_xaxis_transform(), label="failed (no solution)")
        if scale == "log" and (good or shown):
            ax.set_yscale("log")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    if result.get("polished"):
        axes[2].legend(fontsize=8)
    axes[-1].set_xlabel(label)
    axes[0].set_title(f"{result['problem']}: sweep of {result['field']} "
                      f"({len(rows) - result['failed']}/{len(rows)} ok)")
    fig.tight_layout()
    return fig


def write(result, out_dir):
    """Write sweep.csv, sweep.json and sweep.png into ``out_dir``, each atomically."""
    out = Path(out_dir)
    paths = [out / "sweep.csv", out / "sweep.json", out / "sweep.png"]
    with atomic_path(paths[0]) as tmp:
        tmp.write_text(table_csv(result))
    write_json(paths[1], json_ready(result))
    save_figure(figure(result), paths[2])
    return paths



def progress_line(row, done, total, name, stream=None):
    """One line per finished member, for the command line (default on stderr)."""
    if row["error"] is None:
        what = f"converged, tof {row['tof_days']:.3f} d"
        if row.get("tof_days_exact") is not None:
            what += (f", exact {row['tof_days_exact']:.3f} d "
                     f"({'verified' if row['exact_verified'] else 'NOT verified'})")
    else:
        what = f"FAILED ({row['error']})"
    seconds = f" in {row['seconds']:.1f} s" if row["seconds"] is not None else ""
    print(f"esail-opt sweep: [{done}/{total}] {name} = {row['value']:g}: {what}{seconds}",
          file=stream or sys.stderr, flush=True)
