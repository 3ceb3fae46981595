"""The scan engine: a grid of independent members run, journaled and resumed.

A sweep (:mod:`esail_opt.app.sweep`) and a porkchop (:mod:`esail_opt.app.porkchop`)
only describe their members and their outputs, as a :class:`Scan`; this module runs
them.  The members' jobs run on :mod:`esail_opt.runtime.pool` (a local process pool or
Dask, the retries of lost workers, the stop on Ctrl-C or SIGTERM), and every row that
ends is appended at once to the scan's journal in its output folder, so that
``--resume`` runs only the rows the journal lacks.

Contract of a run (:func:`run`):

- everything that can refuse it -- the options (:func:`check_options`), the scheduler
  (reached before anything else), a journal that ``--resume`` cannot continue, or any
  of its rows -- is checked before anything on disk changes: a refused run leaves the
  journal, its torn line included, as it found it;
- a journal row is validated as it is read (its fields' types, finite numbers); a bad
  row is one line naming the file and the line;
- a member's problem file is written into a folder named after the worker's pid, and a
  folder whose worker is gone (it died, or its file called ``os._exit``) is removed by
  the next member and at the end of the run.
"""

import contextlib
import dataclasses
import errno
import hashlib
import json
import logging
import os
import re
import tempfile
import time
import typing
from pathlib import Path

from esail_opt.runtime import processes
from esail_opt.runtime import pool
from esail_opt.runtime.files import atomic_path
from esail_opt.app.record import plain
from esail_opt.errors import InputError, OutputError
from esail_opt.optimisation import transcription
from esail_opt.propagation import compiled

#: Most local worker processes a scan takes (``--workers``).
MAX_WORKERS = 64
#: The start of a member's folder in the temporary folder; the worker's pid follows.
MEMBER_PREFIX = "esail_member_"


# ---------------------------------------------------------------- the options


def worker_setup(cores, quiet):
    """How a local pool's worker computes (the pool's ``setup``): its NLPs' segments
    on its share of the cores (``transcription.share_cores``), and without repeating
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


def header(kind, problem, source, param, values, polish=False, **more):
    """What identifies a scan of ``kind`` (``"sweep"``) in its journal: ``journal``,
    ``problem``, ``source_sha256``, ``param``, ``values``, ``polish``, ``tolerance``,
    then ``more``, in that order (see :class:`Journal`)."""
    return {"journal": f"esail-opt {kind}", "problem": problem.name,
            "source_sha256": source_digest(source), "param": param, "values": values,
            "polish": bool(polish), "tolerance": dataclasses.asdict(problem.tolerance),
            **more}


# ---------------------------------------------------------------- a member's problem


def load_source(source, filename):
    """The problem of a problem file's text ``source`` (named ``filename``), loaded as
    the command line loads a file.

    The file is written into a folder named after this process; folders of processes
    that are gone are removed first, so that a member whose file ended its worker
    (``os._exit``) leaves no folder per try.
    """
    from esail_opt.optimisation.problem_file import load_problem

    remove_orphans()
    with tempfile.TemporaryDirectory(prefix=f"{MEMBER_PREFIX}{os.getpid()}_") as tmp:
        path = Path(tmp) / filename
        path.write_text(source)
        return load_problem(path)


def remove_orphans():
    """Remove the members' folders whose process no longer exists."""
    processes.remove_dead(tempfile.gettempdir(), MEMBER_PREFIX)


# ---------------------------------------------------------------- the journal


def _short(value):
    """A one-line, bounded repr for a journal mismatch message."""
    if isinstance(value, list) and len(value) > 6:
        return f"[{', '.join(map(repr, value[:3]))}, ..., {value[-1]!r}] ({len(value)} values)"
    return repr(value)


def _why_not(value, hint):
    """Why the JSON ``value`` cannot fill a field annotated ``hint`` (``int``, ``float``,
    ``bool``, ``str``, ``dict``, ``list``, or one of them Optional: or null), or None.
    A bool is not a number; an int fills a float field."""
    kind = next((t for t in typing.get_args(hint) if t is not type(None)), hint)
    if value is None:
        return None if kind is not hint else "is missing"
    name = "num" if kind is float else kind.__name__  # as the messages have always said
    if isinstance(value, bool) is not (kind is bool) \
            or not isinstance(value, (int, float) if kind is float else kind):
        return f"= {_short(value)} is not a {name}"
    return None


def fields(row_type):
    """The field names of a row's dataclass, in declaration order."""
    return tuple(f.name for f in dataclasses.fields(row_type))


class Journal:
    """A scan's record on disk: a header line, then one JSON row per finished row; of
    two rows of one index, the later holds (a job's end replaces a row it told of).

    Each row is one ``write`` of one whole line to a file opened for appending,
    followed by ``fsync``: a crash or a kill leaves at most a torn last line, which
    :meth:`read` ignores and :meth:`start` cuts off; every row before it is on disk.

    Parameters
    ----------
    path : Path
        The journal file.
    header : dict
        What identifies the scan (``journal``, ``problem``, ``source_sha256``, ``param``,
        ``values``, ``polish``, ``tolerance``, and what else its kind adds); a journal
        is resumed only under the same header, every key of it.
    row_type : type
        The rows' frozen dataclass: a row read is checked against its fields'
        annotations (:func:`_why_not`) and kept as a dict of its fields, in their
        order.
    belongs : callable, optional
        ``belongs(index, row)``: whether a row is this grid's (default: its index is
        in ``range(count)``).
    count : int
        Rows the grid has.
    """

    def __init__(self, path, header, row_type, count, belongs=None):
        self.path = Path(path)
        self.header, self.row_type, self.count = header, row_type, count
        self.belongs = belongs or (lambda i, row: True)
        self.fresh = False  # started afresh, and no row written yet

    def read(self, resume):
        """With ``resume``, the rows the journal holds (index -> row); changes nothing.

        Raises
        ------
        InputError
            With ``resume``: the journal is not this kind's, belongs to another scan,
            or a whole line of it is not UTF-8 JSON or not a valid row (one line naming
            the file and the line).
        """
        if not resume or not self.path.exists():
            return {}
        lines = self._lines()
        self._check_header(lines)
        kept = {}
        for number, line in lines[1:]:
            if line.strip():
                row = self._row(number, line)
                i = row["index"]
                if 0 <= i < self.count and self.belongs(i, row):
                    kept[i] = row  # a later row of a cell replaces an earlier one
        return kept

    def start(self, kept):
        """Make the journal ready for appending, once the run is accepted: with rows
        ``kept``, cut a torn last line off.  Without, the old journal is replaced by
        this one's header only with the first row (:meth:`append`) or at the run's end
        (:meth:`close`): a fresh run stopped before either leaves the old scan's
        journal, which its outputs beside it match, to be resumed."""
        self.fresh = not kept
        if kept:
            raw = self.path.read_bytes()
            whole = raw.rfind(b"\n") + 1
            if whole < len(raw):
                with open(self.path, "r+b") as handle:
                    handle.truncate(whole)
                    os.fsync(handle.fileno())

    def close(self):
        """At a run's end: a fresh journal that no row reached is written (its header),
        so that it, not the old scan's, sits beside the run's outputs."""
        if self.fresh:
            self._replace()

    def _replace(self, row=None):
        # The header replaces any old journal whole, so a stale row is never read as
        # this scan's.
        with atomic_path(self.path) as tmp:
            tmp.write_text(self._line(self.header) + ("" if row is None else self._line(row)))
            with open(tmp, "rb") as handle:
                os.fsync(handle.fileno())
        self.fresh = False

    def open(self, resume):
        """:meth:`read`, then :meth:`start`: the rows kept."""
        kept = self.read(resume)
        self.start(kept)
        return kept

    def append(self, row):
        """Add one finished row, on disk before returning.

        A write that fails part-way (a full disk) is cut back off the file, so the
        journal never keeps half a line that the next row would be glued to.

        Raises
        ------
        OutputError
            The row could not be written (one line; the journal is as it was).
        """
        if self.fresh:
            try:
                self._replace(row)
            except OSError as err:
                raise OutputError(f"cannot write the journal {str(self.path)!r}: "
                                  f"{os.strerror(err.errno) if err.errno else err}") from None
            return
        data = self._line(row).encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            size = os.fstat(fd).st_size
            try:
                written = os.write(fd, data)
                if written != len(data):
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                os.fsync(fd)
            except OSError as err:
                with contextlib.suppress(OSError):
                    os.ftruncate(fd, size)
                raise OutputError(f"cannot append to the journal {str(self.path)!r}: "
                                  f"{os.strerror(err.errno) if err.errno else err}") from None
        finally:
            os.close(fd)

    @staticmethod
    def _line(obj):
        return json.dumps(plain(obj), allow_nan=False) + "\n"

    def _fail(self, number, why):
        raise InputError(f"resume: {self.path} line {number} {why}; delete that line, or "
                         "run without --resume to start fresh")

    def _lines(self):
        """The journal's whole lines as (number, text); a torn last line is left out."""
        raw = self.path.read_bytes()
        lines = []
        for number, chunk in enumerate(raw[:raw.rfind(b"\n") + 1].split(b"\n")[:-1],
                                       start=1):
            try:
                lines.append((number, chunk.decode("utf-8")))
            except UnicodeDecodeError as err:
                self._fail(number, f"is not UTF-8 (byte {err.start + 1})")
        return lines

    def _check_header(self, lines):
        try:
            header = json.loads(lines[0][1]) if lines else None
        except json.JSONDecodeError:
            header = None
        kind = self.header["journal"].split()[-1]  # "sweep" or "porkchop"
        if not isinstance(header, dict) or header.get("journal") != self.header["journal"]:
            raise InputError(f"resume: {self.path} is not a {kind} journal (line 1 is not "
                             "its header); run without --resume to start fresh")
        for key in [*self.header, *(k for k in header if k not in self.header)]:
            if header.get(key) != self.header.get(key):
                what = ("the problem file changed since it was written" if key == "source_sha256"
                        else f"its {key} is {_short(header.get(key))}, not "
                             f"{_short(self.header.get(key))}")
                raise InputError(f"resume: {self.path} belongs to another {kind}: {what}; "
                                 "run without --resume to start fresh")

    def _row(self, number, line):
        """The row of journal line ``number``, every field checked (InputError)."""
        def constant(name):  # NaN and Infinity: never written, so never accepted
            self._fail(number, f"holds {name}, which is not a number")

        try:
            row = json.loads(line, parse_constant=constant)
        except json.JSONDecodeError as err:
            self._fail(number, f"is not JSON ({err.msg}, column {err.colno})")
        if not isinstance(row, dict):
            self._fail(number, "is not a row (a JSON object)")
        for field, hint in typing.get_type_hints(self.row_type).items():
            why = _why_not(row.get(field), hint)
            if why is not None:
                self._fail(number, f"is not a valid row: {field} {why}")
        if row.get("verified") and row.get("tof_days") is None:
            self._fail(number, "is not a valid row: verified without a tof_days")
        return {field: row.get(field) for field in fields(self.row_type)}


# ---------------------------------------------------------------- a run


@dataclasses.dataclass(frozen=True)
class Scan:
    """What a scan is, for :func:`run`: its rows, its jobs and its journal.

    Attributes
    ----------
    journal_name : str
        The journal's file name in the output folder (``sweep.jsonl``).
    header : dict
        What identifies the scan in its journal (see :class:`Journal`).
    row_type : type
        The rows' frozen dataclass (see :class:`Journal`).
    count : int
        The rows of the grid.
    function : callable
        A module-level function ``function(job, *args)`` returning one row (a dict) or
        a list of rows, each with its ``index``; it never raises for a row.
    jobs : dict
        Job index -> (indices of its rows, args).
    failed_row : callable
        ``failed_row(index, message)``: the row of a row whose job did not end.
    belongs : callable, optional
        ``belongs(index, row)``: whether a journal row is this grid's.
    part : callable, optional
        ``part(job, missing)``: the (indices, args) of a job that needs only its rows
        ``missing`` (a resumed job that had journaled some); by default the whole job.
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
        return Journal(Path(out_dir) / self.journal_name, self.header, self.row_type,
                       self.count, self.belongs)


@dataclasses.dataclass
class Outcome:
    """What a scan's run gave: ``rows`` in grid order, the indices ``resumed`` from the
    journal and ``solved`` in this run (in finishing order), ``lost`` (job index ->
    (losses, cause)), the run's ``seconds``, its ``executor`` in words and the
    ``journal``'s path (or None)."""

    rows: list
    resumed: list
    solved: list
    lost: dict
    seconds: float
    executor: str
    journal: object


class _Rows:
    """The scan's rows, filled in as its jobs end, each journaled at once, and reported
    as soon as a job tells of them (:func:`esail_opt.runtime.pool.tell`).  A verified
    row a job tells of is journaled at once too, so that an interrupted job keeps it;
    the job's end replaces it."""

    def __init__(self, scan, kept, journal, progress):
        self.scan, self.journal, self.progress = scan, journal, progress
        self.rows = [kept.get(i) for i in range(scan.count)]
        self.resumed = sorted(kept)
        self.solved = []  # indices ended in this run, in finishing order
        self.filled = set(kept)  # indices with a row
        self.journaled = set(kept)  # indices whose row the journal holds
        self.told = {}  # index -> the row a job told of before it ended
        self.early = set()  # indices whose told row the journal holds
        self.todo = scan.todo(self.rows)  # the jobs this run runs

    def news(self, row):
        """A row its job told of before ending: reported, and journaled if verified
        (kept by an interrupted run; one that failed may yet be judged otherwise, so a
        resumed run solves it again); not reported again unless the job's end changes
        it."""
        i = row["index"]
        if i in self.told:
            return
        self.told[i] = row
        if self.journal is not None and row.get("verified"):
            self.journal.append(row)
            self.journaled.add(i)
            self.early.add(i)
        self._report(row)

    def finished(self, job, value):
        for row in value if isinstance(value, list) else [value]:
            i = row["index"]
            if self.journal is not None and not (i in self.early and self.told[i] == row):
                self.journal.append(row)
                self.journaled.add(i)
            self._end(i, row)

    def unfinished(self, job, message):
        # Not journaled: it did not finish, so a resumed scan runs it again (all but
        # the verified rows it told of, which the journal holds).
        for i in self.todo[job][0]:
            self._end(i, self.told[i] if i in self.early else self.scan.failed_row(i, message))

    def _end(self, i, row):
        self.rows[i] = row
        self.solved.append(i)
        self.filled.add(i)
        if self.told.get(i) != row:
            self._report(row)

    def _report(self, row):
        if self.progress:
            self.progress(row, len(self.filled | set(self.told)), self.scan.count)


def run(scan, out_dir=None, resume=False, workers=1, scheduler=None,
        retries=pool.RETRIES, progress=None):
    """Run the jobs of ``scan`` that the journal lacks; their rows, journaled.

    ``out_dir`` is the journal's folder (already checked; None keeps no journal);
    ``resume`` keeps the rows the journal holds, else it starts afresh; ``workers`` is
    the local pool's size, ``scheduler`` a Dask scheduler's address (checked by
    :func:`check_scheduler`), ``retries`` the times a job lost with its worker runs
    again, and ``progress(row, done, total)`` is called as each row ends (or as its job
    tells of it, and again at the job's end if that changed it).  Returns an
    :class:`Outcome`.

    Raises
    ------
    InputError
        A journal ``resume`` cannot continue, or an unreachable scheduler: before the
        journal changes.
    esail_opt.runtime.pool.ClusterLost
        The Dask cluster was lost (one line saying what the journal keeps).
    KeyboardInterrupt
        After stopping the workers; the journal holds every row that ended.
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
                            setup=(worker_setup, (quiet,)), on_news=rows.news)
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
    return Outcome(rows.rows, rows.resumed, rows.solved, lost,
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
