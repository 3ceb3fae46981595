"""Independent jobs on a local process pool or a Dask cluster, surviving lost workers.

:func:`run` runs each job on a :mod:`concurrent.futures` executor, a local process pool or Dask
distributed's on a client of :func:`session`, and hands the caller its result or failure as it ends.
A job whose worker dies is run again on a fresh pool a bounded number of times, without charging the
jobs on healthy workers.  On Ctrl-C, SIGTERM (under the command line's handler) or any error the
workers are stopped within seconds; local workers also end when the parent dies without a word
(SIGKILL).
"""

import contextlib
import logging
import os
import signal
import tempfile
import time
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, CancelledError, wait
from pathlib import Path

from esail_opt.runtime import processes, signals
from esail_opt.errors import InputError

#: Times a job lost with its worker is run again before it is reported failed.
RETRIES = 2
#: Longest wait on the futures between two looks at the pool: a Ctrl-C is acted on within it.
POLL_SECONDS = 0.25
#: Seconds a Dask scheduler may take to answer the first connection (Dask's default: 30 s).
CONNECT_SECONDS = 5.0
#: Seconds without the scheduler (Dask's client reconnecting meanwhile) before the run ends.
SCHEDULER_LOST_SECONDS = 10.0
#: Seconds with no worker, while jobs wait, before the run ends: time for one to (re)start.
NO_WORKER_SECONDS = 30.0


class ClusterLost(RuntimeError):
    """The Dask cluster can no longer run the jobs (its scheduler is gone, or every
    worker); the message is one line.  The jobs that ended were reported already."""


def first_line(err):
    """``Type: first line of the message`` of an exception, for a one-line report."""
    detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
    return f"{type(err).__name__}: {detail}".rstrip(": ")


def run(function, jobs, on_result, on_failure, workers=1, client=None, address=None,
        retries=RETRIES, setup=None, on_partial=None):
    """Run ``function(i, *jobs[i])`` for every index ``i`` of the dict ``jobs``, reporting each as
    it ends; return index -> (losses, cause of the last) for every job charged with a lost worker.
    ``function`` is module-level (pickled by name).  ``on_result(i, value)`` gets each result;
    ``on_failure(i, message)``, one line, each job the executor failed or whose worker was lost more
    than ``retries`` times.  ``workers``, >= 1, is the local pool's size, ignored with ``client``, a
    Dask client from :func:`session` (None: the local pool) whose scheduler ``address`` the messages
    name.  With ``setup = (function, args)``, each local worker calls ``function(cores, *args)`` as
    it starts, ``cores`` its share of the machine's.  ``on_partial(item)`` gets each item a local
    job sent with :func:`send_partial`, in order and before that job's result.

    Raises ClusterLost (one line) when the Dask scheduler, or every worker, is lost for longer than
    :data:`SCHEDULER_LOST_SECONDS` or :data:`NO_WORKER_SECONDS`; KeyboardInterrupt
    (:class:`~esail_opt.errors.Terminated` for SIGTERM) after stopping the workers.
    """
    runner = _Runner(function, jobs, on_result, on_failure, workers, client, retries,
                     address, setup, on_partial)
    runner.run()
    return {i: (n, runner.causes[i]) for i, n in sorted(runner.losses.items())}


@contextlib.contextmanager
def session(scheduler):
    """A Dask client on ``scheduler`` while inside (None without one), Dask's own log lines kept off
    the terminal; InputError on entering if Dask is missing or the scheduler unreachable."""
    if scheduler is None:
        yield None
        return
    with _quiet_dask():
        client = _connect(scheduler)
        try:
            yield client
        finally:
            with contextlib.suppress(Exception):
                client.close(timeout=CONNECT_SECONDS)


#: Prefix of a run's scratch folder, then its pid, so that a killed run's is found and removed.
SCRATCH_PREFIX = "esail_started_"


class _Runner:
    """One :func:`run`: the current round's executor, its futures and the losses.  A broken local
    pool is replaced by a fresh one (a new round), in whose own ``started`` folder a worker leaves
    its pid under its job's index, so that a break is charged to the job whose worker died."""

    def __init__(self, function, jobs, on_result, on_failure, workers, client, retries,
                 address=None, setup=None, on_partial=None):
        self.function, self.jobs = function, jobs
        self.setup = setup
        self.address = address
        self.unhealthy = {}  # what is wrong with the cluster -> since when (monotonic)
        self.on_result, self.on_failure, self.on_partial = on_result, on_failure, on_partial
        self.partials = None  # the local pool's queue of partial results, this round
        self.workers, self.client, self.retries = workers, client, retries
        self.lost_errors = _lost_worker_errors()
        self.losses, self.causes = {}, {}
        self.executor = self.started = None
        self.processes = {}  # pid -> Process of the local pool's workers, this round
        self.active = {}  # future -> job index
        self.rounds = 0

    def run(self):
        """Run every job to its end (a result or a failure), then shut down."""
        todo = sorted(self.jobs)
        # A run killed by SIGKILL had no time to remove its scratch folder.
        processes.remove_dead(tempfile.gettempdir(), SCRATCH_PREFIX)
        # The folder outlives the try: on an interrupt the workers stop before it goes away.
        with tempfile.TemporaryDirectory(prefix=f"{SCRATCH_PREFIX}{os.getpid()}_") as scratch:
            try:
                while todo or self.active:
                    unsubmitted = self._submit(todo, scratch) if todo else []
                    todo = self._step(unsubmitted)
            except BaseException:
                self._abort()
                raise
        if self.executor is not None:
            self.executor.shutdown(wait=True)
        if self.client is not None:
            self.client.close(timeout=CONNECT_SECONDS)

    def _submit(self, todo, scratch):
        """Submit ``todo`` (opening a round if needed); return the jobs not submitted."""
        if self.executor is None:
            self.rounds += 1
            self.started = Path(scratch, str(self.rounds))
            self.started.mkdir()
            self.processes = {}
            # pure=False: a job run again is a new task, not Dask's remembered failure.
            if self.client is not None:
                self.executor = self.client.get_executor(pure=False)
            else:
                # A queue per round: a worker killed writing to it may leave its lock held.
                self.partials = _partials_queue() if self.on_partial is not None else None
                self.executor = _new_pool(self.workers, self.setup, self.partials)
        submitted = []
        try:
            for i in todo:
                args = (i, *self.jobs[i])
                future = (self.executor.submit(self.function, *args) if self.client is not None
                          else self.executor.submit(_pool_member, str(self.started),
                                                    self.function, *args))
                self.active[future] = i
                submitted.append(i)
        except self.lost_errors:
            if self.client is not None:
                raise
            # The pool broke while fed: the jobs not submitted are lost in the same break.
        except Exception as err:
            # A client that gave up on its scheduler refuses work at once (ClosedClientError).
            if self.client is None or _client_status(self.client) == "running":
                raise
            raise ClusterLost(self._scheduler_lost("its client closed")) from err
        return [i for i in todo if i not in submitted]

    def _step(self, unsubmitted):
        """Wait briefly, settle what ended; return the jobs to submit again."""
        if self.client is None:
            _pool_processes(self.executor, self.processes)
        else:
            self._watch_cluster()
        done, _ = wait(list(self.active), timeout=POLL_SECONDS, return_when=FIRST_COMPLETED)
        self._pass_partials()  # a job's partials were sent before it returned: they go first
        broken = self.client is None and (unsubmitted or any(
            isinstance(f.exception(), BrokenExecutor) for f in done if not f.cancelled()))
        if broken:
            return self._recover(unsubmitted)
        again = []
        for future in done:
            i = self.active.pop(future)
            lost = self._settle(future, i)
            if lost is not None and self._charge(i, first_line(lost)):
                again.append(i)  # Dask lost its worker: submit it again
        return again

    def _pass_partials(self):
        """Hand the partial results the local pool's jobs sent to ``on_partial``."""
        while self.partials is not None and not self.partials.empty():
            self.on_partial(self.partials.get())

    def _settle(self, future, i):
        """Report an ended future; return its lost-worker exception instead, if that."""
        try:
            value = future.result()
        except self.lost_errors as err:
            return err
        except Exception as err:  # the executor failed the job
            self.on_failure(i, first_line(err))
            return None
        self.on_result(i, value)
        return None

    def _recover(self, unsubmitted):
        """One worker died and took the pool with it: wait for the pool to fail every
        other future and end its workers, blame one job; return the jobs to run again."""
        _pool_processes(self.executor, self.processes)
        self.executor.shutdown(wait=True)
        self.executor = None
        lost = []
        for future, i in list(self.active.items()):
            del self.active[future]
            # A future not done cannot happen once the pool has shut down.
            if not future.done() or self._settle(future, i) is not None:
                lost.append(i)
        lost += unsubmitted
        blamed = _blame(lost, self.started, self.processes)
        return sorted(i for i in lost if i not in blamed or self._charge(i, blamed[i]))

    def _watch_cluster(self):
        """Raise ClusterLost once the Dask cluster has been unable to run anything for
        longer than its bound: no scheduler, or no worker while jobs wait."""
        now = time.monotonic()
        status = _client_status(self.client)
        problems = {}
        if status in ("closing", "closed"):
            raise ClusterLost(self._scheduler_lost("its client closed"))
        if status != "running":
            problems["scheduler"] = (SCHEDULER_LOST_SECONDS, self._scheduler_lost())
        elif self.active:
            try:
                workers = self.client.scheduler_info().get("workers", {})
            except Exception:  # a client between states: judged at the next look
                workers = {None: None}
            if not workers:
                problems["workers"] = (NO_WORKER_SECONDS,
                                       f"no Dask worker left at {self.address} for "
                                       f"{NO_WORKER_SECONDS:g} s")
        self.unhealthy = {k: self.unhealthy.get(k, now) for k in problems}
        for key, (bound, message) in problems.items():
            if now - self.unhealthy[key] >= bound:
                raise ClusterLost(message)

    def _scheduler_lost(self, why=None):
        why = why or f"no connection for {SCHEDULER_LOST_SECONDS:g} s"
        return f"lost the Dask scheduler at {self.address} ({why})"

    def _charge(self, i, cause):
        """Count one lost worker against job ``i``; True if it may run again."""
        self.losses[i] = self.losses.get(i, 0) + 1
        self.causes[i] = cause
        if self.losses[i] <= self.retries:
            return True
        self.on_failure(i, f"worker lost {self.losses[i]} times: {cause}")
        return False

    def _abort(self):
        """Stop everything after an interrupt or an error, without waiting for jobs."""
        with signals.ignoring():
            if self.client is None:
                for future in self.active:
                    future.cancel()
            if self.executor is not None and self.client is None:
                _pool_processes(self.executor, self.processes)
                _stop_pool(self.executor, self.processes)
            elif self.executor is not None:
                # Dask: cancels its futures on the cluster (if it is still there).
                with contextlib.suppress(Exception):
                    self.executor.shutdown(wait=False)
            if self.client is not None:
                with contextlib.suppress(Exception):
                    self.client.close(timeout=2)


# ---------------------------------------------------------------- in the workers


#: In a local pool's worker, the queue :func:`send_partial` writes to (None elsewhere).
_PARTIALS = None


def send_partial(item):
    """Send ``item`` (picklable) to the ``on_partial`` of the :func:`run` whose local pool
    runs this job, at once; nothing outside such a job (on Dask, in the parent)."""
    if _PARTIALS is not None:
        _PARTIALS.put(item)


def _worker_init(cores, parent=None, setup=None, partials=None):
    """Pool initializer: leave Ctrl-C to the parent, run the caller's ``setup`` on ``cores``, this
    worker's share, and end when ``parent`` does, however it ended."""
    global _PARTIALS
    signals.leave_interrupt_to_parent()
    _PARTIALS = partials
    if setup is not None:
        function, args = setup
        function(cores, *args)
    if parent is not None:
        processes.die_with_parent(parent)


def _pool_member(started, function, index, *args):
    """``function(index, *args)`` in a local pool worker, first leaving ``started/<index>`` with
    this worker's pid, by which a broken pool's job whose worker died is told from the rest."""
    Path(started, str(index)).write_text(str(os.getpid()))
    return function(index, *args)


# ---------------------------------------------------------------- executors


def _client_status(client):
    """A Dask client's state: "running", "connecting", "closing", "closed", ..."""
    return str(getattr(client, "status", "running"))


def _lost_worker_errors():
    """Exception types that mean "the worker went away", not "the job failed": BrokenExecutor
    for a broken local pool, Dask's KilledWorker for a job whose workers kept dying, and
    CancelledError (with Dask's FutureCancelledError) for the futures of a lost client or
    worker, since the runner never cancels a future it still waits on."""
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
        return Client(scheduler, timeout=CONNECT_SECONDS)
    except (OSError, TimeoutError) as err:
        detail = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise InputError(f"scheduler {scheduler!r} cannot be reached within "
                         f"{CONNECT_SECONDS:g} s: {detail}") from None
    except ValueError as err:  # a malformed address
        raise InputError(f"scheduler {scheduler!r}: {err}") from None


@contextlib.contextmanager
def _quiet_dask():
    """Keep Dask's own log lines (reconnection attempts, a lost connection's tracebacks) off the
    terminal during a run, which reports the cluster's state in one line (:class:`ClusterLost`)."""
    with contextlib.suppress(ImportError):
        import distributed.client  # noqa: F401 -- its loggers exist once imported
    # Each logger by name, since Dask's configuration gives children levels of their own;
    # concurrent.futures logs Dask's callbacks on futures cancelled after the client closed.
    names = [name for name in list(logging.root.manager.loggerDict)
             if name == "distributed" or name.startswith("distributed.")]
    loggers = [logging.getLogger(name) for name in
               (*names, "distributed", "tornado", "asyncio", "concurrent.futures")]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


def _partials_queue():
    """A queue the local pool's workers can :func:`send_partial` on."""
    import multiprocessing

    return multiprocessing.get_context("spawn").SimpleQueue()


def _new_pool(workers, setup=None, partials=None):
    """A fresh local process pool whose workers ignore SIGINT and send partials on ``partials``."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    # spawn, not fork: a forked child of a process with threads (CasADi's) can deadlock.
    cores = os.cpu_count() or 1
    return ProcessPoolExecutor(max_workers=workers,
                               mp_context=multiprocessing.get_context("spawn"),
                               initializer=_worker_init,
                               initargs=(max(1, cores // workers), os.getpid(), setup,
                                         partials))


def _pool_processes(pool, known):
    """Add the pool's worker processes (pid -> Process) to ``known``, from ProcessPoolExecutor's
    private ``_processes``; without it the runner still works, but cannot blame one job for a
    break or kill running jobs on an interrupt."""
    try:
        known.update(dict(getattr(pool, "_processes", None) or {}))
    except RuntimeError:  # the pool's thread changed it while we copied; next poll
        pass
    return known


def _stop_pool(pool, processes):
    """Stop a pool now: cancel what has not started, terminate running jobs."""
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
    """Which jobs lost in one pool break to charge: index -> one-line cause.  The pool terminates
    its other workers (SIGTERM) when one dies, so a started job (``started_dir/<index>`` holds its
    worker's pid) whose worker ended any other way is the culprit; failing one, every started job is
    charged, and if none had started, every lost job, so retries stay bounded."""
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
