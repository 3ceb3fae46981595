"""Sweeps: one problem file solved over a range of one parameter, on any executor.

``esail-opt sweep PROBLEM.py --param ac_mm_s2=0.2:2:10`` solves ten copies of the
problem, each with ``sail.ac_mm_s2`` replaced, and writes ``sweep.csv``,
``sweep.json`` and ``sweep.png``.  The members run on a :mod:`concurrent.futures`
executor: a local process pool by default, or Dask distributed's executor when a
scheduler address is given -- the same code path either way, so moving a sweep to a
cluster changes one option and no numbers.

Each member is independent and returns a plain dict row.  A member that raises, does
not converge, or converges to a schedule whose CVODES flight misses the problem's
tolerance is reported in its row (``error`` says why); it never stops the others.  Rows
are ordered by parameter value, whatever order the members finish in.

A sweep survives its faults.  Every finished member is appended at once to the journal
``sweep.jsonl`` in the output folder, so ``--resume`` runs only the members it lacks.  A
member whose worker process dies (killed, out of memory, a crash in native code) is run
again on a fresh pool a bounded number of times; the members on healthy workers keep or
redo their work without being charged for it.  Ctrl-C stops the workers within
seconds, keeps the journal and writes nothing else.

Only the names in :data:`SWEEPABLE` can be swept; each maps to one field of the
:class:`~esail_opt.optimisation.problem.Problem` tree, so the mapping is explicit
rather than a free-form attribute path a typo could send anywhere.
"""

import csv
import dataclasses
import hashlib
import io
import json
import math
import os
import signal
import sys
import tempfile
import threading
import time
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, CancelledError, wait
from pathlib import Path

import numpy as np

from esail_opt.errors import InputError
from esail_opt.app.files import atomic_path, json_ready, save_figure, write_json


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

CSV_FIELDS = ("index", "value", "converged", "verified", "status", "tof_days", "objective",
              "target_miss_r_km", "target_miss_v_m_s", "iterations", "tof_days_exact",
              "exact_verified", "exact_target_miss_m", "seconds", "error")

#: The journal of finished members, in the sweep's output folder.
JOURNAL = "sweep.jsonl"
#: Times a member lost with its worker is run again before its row says so.
RETRIES = 2
#: Longest wait on the futures between two looks at the pool: a Ctrl-C is acted on
#: within this, whatever the executor's own waiting does with signals.
POLL_SECONDS = 0.25


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


def _first_line(err):
    """``Type: first line of the message`` of an exception, for a row's ``error``."""
    detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
    return f"{type(err).__name__}: {detail}".rstrip(": ")


def _not_verified(sol, tolerance):
    """Why a converged member is not verified, in one line."""
    note = sol.data.get("verification_note")
    if note:
        return f"not verified: {str(note).strip().splitlines()[0]}"
    check = sol["verification"]
    # Against the target when there is one, else against the NLP's own final state:
    # what Tolerance is defined to bound.
    r, v = check.get("target_miss_r_km"), check.get("target_miss_v_m_s")
    if r is None and v is None:
        r, v = check.get("miss_r_km"), check.get("miss_v_m_s")
    parts = []
    if r is not None:
        parts.append(f"position miss {r:.4g} km (tolerance {tolerance.position_km:g} km)")
    if v is not None:
        parts.append(f"velocity miss {v:.4g} m/s (tolerance {tolerance.velocity_m_s:g} m/s)")
    return "not verified: " + ("; ".join(parts) or "the CVODES flight missed the tolerance")


def solve_member(index, name, value, source, filename, polish=False, tol_km=None,
                 tol_m_s=None):
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
    tol_km, tol_m_s : float, optional
        Replace the problem's verification bounds (``Problem.with_tolerance``); None
        keeps the problem file's.

    Returns
    -------
    dict
        The fields of :data:`CSV_FIELDS`: ``converged`` is True only for Ipopt's
        Solve_Succeeded; ``verified`` is the solve's own verdict on whether the CVODES
        flight met the tolerance (None when the solve does not give one);
        ``target_miss_*`` are the CVODES verification's misses against the target;
        ``seconds`` is this member's wall time; ``error`` is None or one line saying
        why the member failed, including "not verified: ..." for a converged member
        whose flight missed the tolerance.  With ``polish``: ``tof_days_exact``,
        ``exact_verified`` (the polished schedule flies to within 1 m and 1 mm/s) and
        ``exact_target_miss_m``; None without.
    """
    from esail_opt.app import solution
    from esail_opt.optimisation.problem_file import load_problem

    row = _empty_row(index, value)
    start = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="esail_sweep_") as tmp:
            path = Path(tmp) / filename
            path.write_text(source)
            problem = load_problem(path)
        problem = variant(problem, name, value).with_tolerance(tol_km, tol_m_s)
        sol = solution.solve(problem, polish=polish)
        check = sol["verification"]
        verified = sol.data.get("verified")
        row.update(converged=sol.converged, status=sol["status"], tof_days=sol["tof_days"],
                   objective=sol["objective"], iterations=sol["iterations"],
                   verified=None if verified is None else bool(verified),
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
        elif verified is not None and not verified:
            row["error"] = _not_verified(sol, problem.tolerance)
    except Exception as err:  # a member may fail in any way; its row says how
        row["error"] = _first_line(err)
    row["seconds"] = time.perf_counter() - start
    return row


def _worker_init():
    """Pool initializer: a worker ignores SIGINT, so that Ctrl-C in a terminal (sent to
    the whole process group) reaches only the parent, which decides what stops."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _pool_member(started, index, *args):
    """:func:`solve_member` in a local pool worker, first leaving ``started/<index>``
    with this worker's pid: when the pool breaks, the parent uses it to tell the member
    whose worker died from the ones whose healthy workers the pool terminated."""
    Path(started, str(index)).write_text(str(os.getpid()))
    return solve_member(index, *args)


# ---------------------------------------------------------------- journal


def _source_digest(source):
    """SHA-256 of the problem file's text: a resumed journal must come from this file."""
    return hashlib.sha256(source.encode()).hexdigest()


def _short(value):
    """A one-line, bounded repr for a journal mismatch message."""
    if isinstance(value, list) and len(value) > 6:
        return f"[{', '.join(map(repr, value[:3]))}, ..., {value[-1]!r}] ({len(value)} values)"
    return repr(value)


class Journal:
    """The sweep's record on disk: a header line, then one JSON row per finished member.

    Each row is one ``write`` of one whole line to a file opened for appending,
    followed by ``fsync``: a crash or a kill leaves at most a torn last line, which
    :meth:`open` ignores, and every row before it is on disk.

    Parameters
    ----------
    path : Path
        The journal file, ``<out_dir>/sweep.jsonl``.
    header : dict
        What identifies the sweep (problem, its file's digest, param, values, polish,
        tolerance); a journal is resumed only under the same header.
    """

    def __init__(self, path, header):
        self.path = Path(path)
        self.header = header

    def open(self, resume):
        """Start the journal, or with ``resume`` read the rows it already holds.

        Returns
        -------
        dict
            Index -> row of the members the journal holds (empty unless ``resume``).

        Raises
        ------
        InputError
            With ``resume``: the journal is not a sweep journal, or belongs to another
            problem, problem file, param grid, polish or tolerance.
        """
        kept = self._read() if resume and self.path.exists() else {}
        if not kept:
            # Fresh start (or nothing to keep): the header replaces any old journal
            # whole, so a stale row can never be read as this sweep's.
            with atomic_path(self.path) as tmp:
                tmp.write_text(self._line(self.header))
        return kept

    def append(self, row):
        """Add one finished member's row, on disk before returning."""
        data = self._line(row).encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)

    @staticmethod
    def _line(obj):
        return json.dumps(json_ready(obj), allow_nan=False) + "\n"

    def _read(self):
        lines = self.path.read_text().splitlines()
        try:
            header = json.loads(lines[0]) if lines else None
        except json.JSONDecodeError:
            header = None
        if not isinstance(header, dict) or header.get("journal") != self.header["journal"]:
            raise InputError(f"resume: {self.path} is not a sweep journal; run without "
                             "--resume to start fresh")
        for key in ("problem", "source_sha256", "param", "values", "polish", "tolerance"):
            if header.get(key) != self.header[key]:
                what = ("the problem file changed since it was written" if key == "source_sha256"
                        else f"its {key} is {_short(header.get(key))}, not "
                             f"{_short(self.header[key])}")
                raise InputError(f"resume: {self.path} belongs to another sweep: {what}; "
                                 "run without --resume to start fresh")
        values = self.header["values"]
        kept = {}
        for line in lines[1:]:
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line torn by a crash mid-append: that member runs again
            if not isinstance(row, dict):
                continue
            i = row.get("index")
            # Index and value both: a row is this grid's only where the grid puts it.
            if (isinstance(i, int) and 0 <= i < len(values) and row.get("value") == values[i]
                    and i not in kept):
                full = _empty_row(i, values[i])
                full.update({k: row[k] for k in CSV_FIELDS if k in row})
                kept[i] = full
        return kept


# ---------------------------------------------------------------- executors


def _lost_worker_errors():
    """Exception types that mean "the worker went away", not "the member failed".

    A broken process pool fails every unfinished future with BrokenProcessPool (a
    BrokenExecutor).  Dask reports a member whose workers kept dying as KilledWorker,
    and cancels the futures of a lost client or worker (CancelledError, whose
    subclass FutureCancelledError is Dask's).  The sweep never cancels a future it
    still waits on, so a cancelled one was lost.
    """
    kinds = [BrokenExecutor, CancelledError]
    try:
        from distributed.scheduler import KilledWorker
        kinds.append(KilledWorker)
    except ImportError:
        pass
    try:
        from distributed.client import FutureCancelledError
        kinds.append(FutureCancelledError)
    except ImportError:
        pass
    return tuple(kinds)


def _connect(scheduler):
    """A Dask client on ``scheduler`` (one line of InputError if it cannot be)."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise InputError("--scheduler needs Dask: pip install 'esail_opt[dask]'") from None
    try:
        return Client(scheduler, timeout=30)
    except (OSError, TimeoutError) as err:
        raise InputError(f"scheduler {scheduler!r} cannot be reached: {err}") from None


def _new_pool(workers):
    """A fresh local process pool whose workers ignore SIGINT."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    # spawn, not fork: the parent has CasADi and maybe threads loaded, and a forked
    # child of a threaded process can deadlock; spawn costs one import per worker.
    return ProcessPoolExecutor(max_workers=workers,
                               mp_context=multiprocessing.get_context("spawn"),
                               initializer=_worker_init)


def _pool_processes(pool, known):
    """Add the pool's worker processes (pid -> Process) to ``known``.

    ProcessPoolExecutor has no public list of its workers; its ``_processes`` has been
    there since Python 3.2.  Without it the sweep still works, but cannot attribute a
    break to one member or kill running solves on an interrupt.
    """
    try:
        known.update(dict(getattr(pool, "_processes", None) or {}))
    except RuntimeError:  # the pool's thread changed it while we copied; next poll
        pass
    return known


def _stop_pool(pool, processes):
    """Stop a pool now: cancel what has not started, terminate running solves."""
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes.values():
        if proc.is_alive():
            proc.terminate()
    for proc in processes.values():
        proc.join(timeout=2)
        if proc.is_alive():  # SIGTERM not honoured within 2 s: no more waiting
            proc.kill()
            proc.join(timeout=1)


def _ended(code):
    """How a worker process ended, in words, from its exit code."""
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"ended by {signal.Signals(-code).name}"
        except ValueError:
            return f"ended by signal {-code}"
    return f"exited with status {code}"


def _blame(lost, started_dir, processes):
    """Which of the members lost in one pool break to charge with the loss, and why.

    When one worker dies, the pool fails every unfinished future and terminates its
    other workers (SIGTERM).  A member that had started (``started_dir/<index>`` holds
    its worker's pid) on a worker that ended any other way is the one whose worker
    died.  If no member can be singled out, every started member is charged; if none
    had started, every lost member is -- so the retries stay bounded either way.

    Returns
    -------
    dict
        Index -> one-line cause, for the members charged.
    """
    started = {}
    for i in lost:
        try:
            started[i] = int(Path(started_dir, str(i)).read_text())
        except (OSError, ValueError):
            pass
    culprits = {}
    for i, pid in started.items():
        proc = processes.get(pid)
        code = proc.exitcode if proc is not None else None
        if code is not None and code != -signal.SIGTERM:
            culprits[i] = f"worker pid {pid} {_ended(code)}"
    if culprits:
        return culprits
    cause = "a worker of the process pool died"
    return {i: f"{cause} (worker pid {pid})" for i, pid in started.items()} or \
        dict.fromkeys(lost, cause)


# ---------------------------------------------------------------- the family


def default_out_dir(problem_file, param):
    """``results/<problem name>_sweep_<NAME>``: the command line's default folder.

    Raises
    ------
    InputError
        Bad ``param`` or an unreadable problem file.
    """
    from esail_opt.optimisation.problem_file import load_problem

    name, _ = parse_param(param)
    return Path("results") / f"{load_problem(problem_file).name}_sweep_{name}"


def run(problem_file, param, workers=None, scheduler=None, progress=None, polish=False,
        out_dir=None, resume=False, tol_km=None, tol_m_s=None, retries=RETRIES):
    """Solve the family of ``problem_file`` over ``param`` and return the table.

    Members are journaled to ``out_dir/sweep.jsonl`` as they finish.  A member whose
    worker dies is run again on a fresh pool, up to ``retries`` times; the others keep
    their rows.  On KeyboardInterrupt the pool is stopped at once (pending members
    cancelled, running solves terminated), the journal keeps what finished, and the
    interrupt propagates.

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
        ``progress(row, done, total)`` after each member finished in this run.
    polish : bool
        Polish every member on exact CVODES arcs as well (see :func:`solve_member`).
    out_dir : str or Path, optional
        The sweep's output folder, for the journal; None keeps no journal.
    resume : bool
        Keep the members the journal in ``out_dir`` already holds and run only the
        others (all of them if there is no journal).  Without it an existing journal
        is replaced.
    tol_km, tol_m_s : float, optional
        Verification bounds for every member, in [1e-3, 1e8] km and [1e-6, 1e5] m/s
        (default: the problem file's).
    retries : int
        Times a member lost with its worker is run again, >= 0.

    Returns
    -------
    dict
        ``problem``, ``problem_file``, ``param``, ``field``, ``unit``, ``values``,
        ``executor``, ``wall_seconds``, ``polished``, ``tolerance``, ``failed`` (count
        of rows with an error), ``rows`` (one per value, in grid order), ``journal``
        (its path or None), ``resumed`` (indices taken from the journal), ``solved``
        (indices that finished in this run, in finishing order) and ``lost``
        (``{"index", "value", "losses", "cause"}`` per member charged with a lost
        worker).

    Raises
    ------
    InputError
        Bad ``param``, ``workers``, tolerance or ``retries``, an unreadable problem
        file, a parameter the problem does not have, a journal of another sweep under
        ``resume``, or an unreachable scheduler -- all before any solve.
    KeyboardInterrupt
        After stopping the workers; the journal holds every member that finished.
    """
    from esail_opt.optimisation.problem_file import load_problem

    name, values = parse_param(param)
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise InputError(f"workers = {workers!r} is outside [1, inf)")
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise InputError(f"retries = {retries!r} is outside [0, inf)")
    if resume and out_dir is None:
        raise InputError("resume needs out_dir, the folder holding the journal")
    workers = int(workers) if workers is not None else min(len(values), os.cpu_count() or 1)
    # Loaded here too, so a broken file, an inapplicable parameter or a bad tolerance
    # is one line at once instead of COUNT identical failed rows.
    problem = load_problem(problem_file).with_tolerance(tol_km, tol_m_s)
    check_applicable(problem, name)
    source = Path(problem_file).read_text()
    filename = Path(problem_file).name
    tolerance = dataclasses.asdict(problem.tolerance)

    journal = None
    rows = [None] * len(values)
    if out_dir is not None:
        journal = Journal(Path(out_dir) / JOURNAL, {
            "journal": "esail-opt sweep", "problem": problem.name,
            "source_sha256": _source_digest(source), "param": name, "values": values,
            "polish": bool(polish), "tolerance": tolerance})
        for i, row in journal.open(resume).items():
            rows[i] = row
    resumed = [i for i, row in enumerate(rows) if row is not None]

    client = _connect(scheduler) if scheduler is not None else None
    described = (f"dask distributed at {scheduler}" if client is not None
                 else f"process pool, {workers} workers")
    lost_errors = _lost_worker_errors()
    state = {"done": len(resumed), "solved": [], "losses": {}, "causes": {}}
    start = time.perf_counter()

    def finish(i, row, journaled=True):
        rows[i] = row
        if journaled and journal is not None:
            journal.append(row)
        state["done"] += 1
        state["solved"].append(i)
        if progress:
            progress(row, state["done"], len(values))

    def charge(i, cause):
        """Count one lost worker against member ``i``; True if it may run again."""
        state["losses"][i] = state["losses"].get(i, 0) + 1
        state["causes"][i] = cause
        if state["losses"][i] <= retries:
            return True
        row = _empty_row(i, values[i])
        row["error"] = f"worker lost {state['losses'][i]} times: {cause}"
        # Not journaled: it did not finish, so a resumed sweep runs it again.
        finish(i, row, journaled=False)
        return False

    def submit(executor, started, i):
        member = (i, name, values[i], source, filename, polish, tol_km, tol_m_s)
        if client is not None:
            return executor.submit(solve_member, *member)
        return executor.submit(_pool_member, str(started), *member)

    def settle(future, i):
        """Handle one finished future; return True if member ``i`` must run again."""
        try:
            row = future.result()
        except lost_errors as err:
            return charge(i, _first_line(err))
        except Exception as err:  # solve_member never raises: the executor failed it
            row = _empty_row(i, values[i])
            row["error"] = _first_line(err)
            finish(i, row, journaled=False)
            return False
        finish(i, row)
        return False

    todo = [i for i in range(len(values)) if rows[i] is None]
    executor = started = None
    processes = {}
    active = {}
    # The scratch folder outlives the try below: on an interrupt the workers are
    # stopped before the folder they write into goes away.
    with tempfile.TemporaryDirectory(prefix="esail_sweep_started_") as scratch:
        try:
            rounds = 0
            while todo or active:
                if todo:
                    if executor is None:
                        rounds += 1
                        started = Path(scratch, str(rounds))
                        started.mkdir()
                        processes = {}
                        # pure=False: a member run again must be a new task, not
                        # Dask's remembered failure of the same arguments.
                        executor = (client.get_executor(pure=False) if client is not None
                                    else _new_pool(workers))
                    submitted = []
                    try:
                        for i in todo:
                            active[submit(executor, started, i)] = i
                            submitted.append(i)
                    except lost_errors:
                        if client is not None:
                            raise
                        # The pool broke while being fed: the members not yet submitted
                        # are lost in the same break (handled below).
                    unsubmitted = [i for i in todo if i not in submitted]
                    todo = []
                else:
                    unsubmitted = []
                if client is None:
                    _pool_processes(executor, processes)
                done, _ = wait(list(active), timeout=POLL_SECONDS, return_when=FIRST_COMPLETED)
                broken = client is None and (unsubmitted or any(
                    isinstance(f.exception(), BrokenExecutor) for f in done
                    if not f.cancelled()))
                if not broken:
                    for future in done:
                        i = active.pop(future)
                        if settle(future, i):
                            todo.append(i)  # Dask lost its worker: submit it again
                    continue
                # One worker died and took the pool with it: wait for the pool to fail
                # every other future and end its workers, then blame one member.
                _pool_processes(executor, processes)
                executor.shutdown(wait=True)
                executor = None
                lost = []
                for future, i in list(active.items()):
                    del active[future]
                    if not future.done():  # cannot happen once the pool has shut down
                        lost.append(i)
                        continue
                    try:
                        row = future.result()
                    except lost_errors:
                        lost.append(i)
                        continue
                    except Exception as err:
                        row = _empty_row(i, values[i])
                        row["error"] = _first_line(err)
                        finish(i, row, journaled=False)
                        continue
                    finish(i, row)
                lost += unsubmitted
                blamed = _blame(lost, started, processes)
                for i in lost:
                    if i not in blamed or charge(i, blamed[i]):
                        todo.append(i)
                todo.sort()
        except BaseException:
            _abort(executor, client, processes, active)
            raise
    if executor is not None:
        executor.shutdown(wait=True)
    if client is not None:
        client.close()
    spec = SWEEPABLE[name]
    return {"problem": problem.name, "problem_file": str(problem_file), "param": name,
            "field": spec.path, "unit": spec.unit, "values": values, "executor": described,
            "wall_seconds": time.perf_counter() - start, "polished": polish,
            "tolerance": tolerance,
            "failed": sum(1 for r in rows if r["error"] is not None), "rows": rows,
            "journal": str(journal.path) if journal is not None else None,
            "resumed": resumed, "solved": state["solved"],
            "lost": [{"index": i, "value": values[i], "losses": n, "cause": state["causes"][i]}
                     for i, n in sorted(state["losses"].items())]}


def _abort(executor, client, processes, active):
    """Stop everything after an interrupt or an error, without waiting for solves."""
    # A second Ctrl-C must not cut the cleanup short and leave workers running.
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        for future in active:
            future.cancel()
        if executor is not None and client is None:
            _pool_processes(executor, processes)
            _stop_pool(executor, processes)
        elif executor is not None:
            executor.shutdown(wait=False)  # Dask: cancels its futures on the cluster
        if client is not None:
            client.close()
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


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
            ax.plot(*zip(*shown), "x", color="C3", ms=9, mew=2,
                    label="not converged or not verified")
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
        if row.get("verified"):
            what += ", verified"
        if row.get("tof_days_exact") is not None:
            what += (f", exact {row['tof_days_exact']:.3f} d "
                     f"({'verified' if row['exact_verified'] else 'NOT verified'})")
    else:
        what = f"FAILED ({row['error']})"
    seconds = f" in {row['seconds']:.1f} s" if row["seconds"] is not None else ""
    print(f"esail-opt sweep: [{done}/{total}] {name} = {row['value']:g}: {what}{seconds}",
          file=stream or sys.stderr, flush=True)
