"""The scan engine: a grid of independent members run, journaled and resumed.

A sweep and a porkchop describe their members as a :class:`Scan`; :func:`run` runs its jobs on
:mod:`esail_opt.runtime.pool` and journals each row as it ends, so that ``--resume`` runs only the
rows the journal lacks.  Whatever can refuse a run is checked before anything on disk changes.
"""

import dataclasses
import hashlib
import logging
import os
import re
import tempfile
import time
from pathlib import Path

from esail_opt.app.record import plain
from esail_opt.errors import InputError
from esail_opt.runtime import pool, processes
from esail_opt.runtime.journal import Journal
from esail_opt.optimisation import transcription
from esail_opt.propagation import compiled

#: Most local worker processes a scan takes (``--workers``).
MAX_WORKERS = 64
#: The start of a member's folder in the temporary folder; the worker's pid follows.
MEMBER_PREFIX = "esail_member_"


# ---------------------------------------------------------------- the options


def worker_setup(cores, quiet):
    """A local pool worker's ``setup``: its NLPs' segments on its share of the ``cores``, silent on
    what the compile cache said in the parent (``quiet``)."""
    transcription.share_cores(cores)
    compiled.said_already(quiet)


def check_workers(workers):
    """``workers`` as an int in [1, :data:`MAX_WORKERS`], or None (InputError if not)."""
    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, (int, float)) \
            or int(workers) != workers or not 1 <= workers <= MAX_WORKERS:
        raise InputError(f"workers = {workers!r} is outside [1, {MAX_WORKERS}]")
    return int(workers)


_ADDRESS = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):([0-9]+)$")


def check_scheduler(address):
    """InputError unless ``address`` is a Dask scheduler's ``tcp://HOST:PORT`` (or
    ``tls://``) with a port in [1, 65535]; checked before any connection is tried."""
    if address is None:
        return None
    form = "expected tcp://HOST:PORT (or tls://HOST:PORT), e.g. tcp://10.0.0.5:8786"
    match = _ADDRESS.match(str(address))
    if match is None:
        raise InputError(f"--scheduler = {address!r}: {form}")
    port = int(match.group(3))
    if not 1 <= port <= 65535:
        raise InputError(f"--scheduler = {address!r}: port {port} is outside [1, 65535]")
    return str(address)


def check_options(workers, scheduler, retries, resume, out_dir):
    """The options every scan shares, checked before anything runs; the pool size
    (None: the caller's default)."""
    workers = check_workers(workers)
    check_scheduler(scheduler)
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise InputError(f"retries = {retries!r} is outside [0, inf)")
    if resume and out_dir is None:
        raise InputError("resume needs out_dir, the folder holding the journal")
    return workers


def source_digest(source):
    """SHA-256 of a problem file's text: a resumed journal must come from this file."""
    return hashlib.sha256(source.encode()).hexdigest()


def invalid_row(row):
    """Why the journal refuses a well-typed row, or None: a verified row needs a time of flight."""
    if row.get("verified") and row.get("tof_days") is None:
        return "verified without a tof_days"
    return None


def header(kind, problem, source, param, values, polish=False, **more):
    """What identifies a scan of ``kind`` (``"sweep"``) in its journal: ``journal``,
    ``problem``, ``source_sha256``, ``param``, ``values``, ``polish``, ``tolerance``,
    then ``more``, in that order (see :class:`~esail_opt.runtime.journal.Journal`)."""
    return {"journal": f"esail-opt {kind}", "problem": problem.name,
            "source_sha256": source_digest(source), "param": param, "values": values,
            "polish": bool(polish), "tolerance": dataclasses.asdict(problem.tolerance),
            **more}


# ---------------------------------------------------------------- a member's problem


def load_source(source, filename):
    """The problem of a problem file's text ``source`` (named ``filename``), loaded as the command
    line loads a file, from a folder named after this process; dead processes' folders are removed
    first (a file may end its worker by ``os._exit``)."""
    from esail_opt.optimisation.problem_file import load_problem

    remove_orphans()
    with tempfile.TemporaryDirectory(prefix=f"{MEMBER_PREFIX}{os.getpid()}_") as tmp:
        path = Path(tmp) / filename
        path.write_text(source)
        return load_problem(path)


def remove_orphans():
    """Remove the members' folders whose process no longer exists."""
    processes.remove_dead(tempfile.gettempdir(), MEMBER_PREFIX)


# ---------------------------------------------------------------- a run


@dataclasses.dataclass(frozen=True)
class Scan:
    """What a scan is, for :func:`run`: its rows, its jobs and its journal.

    ``journal_name`` (``sweep.jsonl``), ``header`` and ``row_type`` (a frozen dataclass)
    are the journal's (:class:`~esail_opt.runtime.journal.Journal`); ``count`` rows;
    ``function(job, *args)``, module-level, returns one row (a dict) or a list, each with
    its ``index``, and never raises for a row; ``jobs``: job index -> (row indices, args);
    ``failed_row(index, message)``: row ``index`` when its job did not end; optional
    ``belongs(index, row)``: whether a journal row is this grid's; optional ``part(job,
    missing)``: the (indices, args) of a job needing only rows ``missing``.
    """

    journal_name: str
    header: dict
    row_type: type
    count: int
    function: object
    jobs: dict
    failed_row: object
    belongs: object = None
    part: object = None

    def todo(self, rows):
        """The jobs (index -> (indices, args)) that rows (a list, None where missing)
        still need, each cut to what it needs by :attr:`part`."""
        out = {}
        for j, (indices, args) in self.jobs.items():
            missing = [i for i in indices if rows[i] is None]
            if missing:
                whole = len(missing) == len(indices) or self.part is None
                out[j] = (indices, args) if whole else self.part(j, missing)
        return out

    def journal(self, out_dir):
        """Its journal in ``out_dir``, or None without a folder."""
        if out_dir is None:
            return None
        return Journal(Path(out_dir) / self.journal_name, plain(self.header), self.row_type,
                       self.count, self.belongs, invalid_row)


@dataclasses.dataclass
class ScanRun:
    """What a scan's run gave: ``rows`` in grid order, the indices ``resumed`` from the journal and
    ``solved`` in this run (in finishing order), ``lost`` (job index -> (losses, cause)), the run's
    ``seconds``, its ``executor`` in words and the ``journal``'s path (or None)."""

    rows: list
    resumed: list
    solved: list
    lost: dict
    seconds: float
    executor: str
    journal: object


class _Rows:
    """The scan's rows, journaled as its jobs end and reported as soon as a job sends them
    early (:func:`esail_opt.runtime.pool.send_partial`); a verified row sent early is journaled then
    too, so that an interrupted job keeps it."""

    def __init__(self, scan, kept, journal, progress):
        self.scan, self.journal, self.progress = scan, journal, progress
        self.rows = [kept.get(i) for i in range(scan.count)]
        self.resumed = sorted(kept)
        self.solved = []  # indices ended in this run, in finishing order
        self.filled = set(kept)  # indices with a row
        self.journaled = set(kept)  # indices whose row the journal holds
        self.partials = {}  # index -> the row a job sent before it ended
        self.journaled_early = set()  # indices whose early row the journal holds
        self.todo = scan.todo(self.rows)  # the jobs this run runs

    def partial(self, row):
        """A row its job sent before ending: reported, and journaled if verified (a failed one a
        resumed run solves again); reported again only if the job's end changes it."""
        i = row["index"]
        if i in self.partials:
            return
        self.partials[i] = row
        if self.journal is not None and row.get("verified"):
            self.journal.append(plain(row))
            self.journaled.add(i)
            self.journaled_early.add(i)
        self._report(row)

    def finished(self, job, value):
        for row in value if isinstance(value, list) else [value]:
            i = row["index"]
            early = i in self.journaled_early and self.partials[i] == row
            if self.journal is not None and not early:
                self.journal.append(plain(row))
                self.journaled.add(i)
            self._end(i, row)

    def unfinished(self, job, message):
        # Not journaled, so a resumed scan runs it again.
        for i in self.todo[job][0]:
            early = i in self.journaled_early
            self._end(i, self.partials[i] if early else self.scan.failed_row(i, message))

    def _end(self, i, row):
        self.rows[i] = row
        self.solved.append(i)
        self.filled.add(i)
        if self.partials.get(i) != row:
            self._report(row)

    def _report(self, row):
        if self.progress:
            self.progress(row, len(self.filled | set(self.partials)), self.scan.count)


def run(scan, out_dir=None, resume=False, workers=1, scheduler=None,
        retries=pool.RETRIES, progress=None):
    """Run the jobs of ``scan`` that the journal in ``out_dir`` (checked; None: no journal) lacks,
    keeping its rows with ``resume``; a :class:`ScanRun`.  ``workers``: the local pool's size;
    ``scheduler``: a Dask address (:func:`check_scheduler`); ``retries``: reruns of a job lost with
    its worker; ``progress(row, done, total)`` as each row ends or is sent early (again if changed).

    Raises InputError, before the journal changes, for a journal ``resume`` cannot continue or an
    unreachable scheduler; ``pool.ClusterLost`` (one line saying what the journal keeps);
    KeyboardInterrupt after stopping the workers.
    """
    journal = scan.journal(out_dir)
    kept = journal.read(resume) if journal is not None else {}
    rows = _Rows(scan, kept, journal, progress)
    todo = rows.todo
    executor = (f"dask distributed at {scheduler}" if scheduler is not None
                else f"process pool, {workers} worker{'' if workers == 1 else 's'}")
    start = time.perf_counter()
    with pool.session(scheduler) as client:
        if journal is not None:
            journal.start(kept)  # the run is accepted: only now does the journal change
        # Said once here, not once per worker.
        quiet = compiled.check_cache() if client is None else ()
        try:
            lost = pool.run(scan.function, {j: job[1] for j, job in todo.items()},
                            rows.finished, rows.unfinished, workers=workers,
                            client=client, address=scheduler, retries=retries,
                            setup=(worker_setup, (quiet,)), on_partial=rows.partial)
        except pool.ClusterLost as err:
            raise pool.ClusterLost(f"{err}; {_kept(rows, journal)}") from None
        except KeyboardInterrupt:
            if journal is not None:  # said before the command's own "interrupted" line
                logging.getLogger("esail_opt").warning("esail-opt: %s", _kept(rows, journal))
            raise
        finally:
            if client is None:
                remove_orphans()
        if journal is not None:
            journal.close()
    return ScanRun(rows.rows, rows.resumed, rows.solved, lost,
                   time.perf_counter() - start, executor,
                   None if journal is None else journal.path)


def _kept(rows, journal):
    """What a run cut short by a lost cluster keeps, in words."""
    count = rows.scan.count
    if journal is None:
        return f"{len(rows.filled)} of {count} rows had finished"
    left = count - len(rows.journaled)
    if not left:
        return (f"the journal {journal.path} keeps all {count} rows; run again with "
                "--resume to write the outputs from it")
    return (f"the journal {journal.path} keeps {len(rows.journaled)} of the {count} rows; "
            f"run again with --resume for the other {left}")
