"""A solution's figures drawn beside its solve, in processes of their own.

Matplotlib's import and the drawing of the two figures took more of a short solve's
whole run than the solve did, and neither needs the solver's core.  So the command
line starts a :class:`PlotWorker` before it solves: a forked process that imports
matplotlib and :mod:`esail_opt.app.plots` on the other core while the solve runs,
makes the timeline's frame (:func:`esail_opt.app.plots.timeline_frame`), then waits.
Before a polish, it is handed the solution as it stands (:meth:`PlotWorker.draft`) and
draws and renders the timeline's closed form while the polish runs
(:func:`esail_opt.app.plots.timeline_draft`): the second core is idle then, and the
figures after the hand-over are what the command waits for last.
Given the solution, it forks once more per figure but the last, so that the figures
are drawn at the same time, finishes the last (the timeline) itself from its draft, or
without one draws it in two bands at once (:mod:`esail_opt.app.bands`), and reports
back when every file is written.

The worker writes where :meth:`~esail_opt.app.solution.Solution.write` tells it, which
is the staging folder of the set (:func:`esail_opt.app.files.publish`): nothing
reaches the output folder before the whole set does.  Any failure of the worker (it
died, or a figure raised) makes :meth:`PlotWorker.written` draw the figures here
instead, where the same fault, if it is one of the figures', raises as it always has.

Only where ``fork`` is the platform's own way to start a process (Linux): a spawned
worker would import the package again first, and forking is not safe on macOS once
its system libraries have started threads.  Elsewhere the figures are drawn in the
calling process, as without a worker.
"""

import functools
import gc
import multiprocessing
import os
import sys
import threading
from pathlib import Path

from esail_opt.processes import quiet_child


#: The longest wait for the worker to be ready, and then for its figures, seconds: both
#: take a second or two; a worker stuck far beyond that is ended and the figures drawn
#: here.
WAIT_SECONDS = 60.0


def _forks():
    return sys.platform.startswith("linux")


class PlotWorker:
    """A process, started now, that will draw one solution's figures.

    Use it as a context manager around the solve and the write, and give it to
    :meth:`~esail_opt.app.solution.Solution.write`, which calls :meth:`start` before it
    writes the set's other files and :meth:`written` after.
    """

    def __init__(self, throttled=None):
        """``throttled``: whether the problem has a throttle, for the timeline's frame
        (:func:`esail_opt.app.plots.timeline_frame`), which the worker makes while it
        waits; None makes none."""
        self._conn = self._process = self._job = self._drafting = None
        self._ready = False
        if not _forks():
            return
        context = multiprocessing.get_context("fork")
        ours, theirs = context.Pipe()
        # Not a daemon, which multiprocessing forbids to start processes of its own:
        # close() ends it, and it dies with this process (quiet_child).
        process = context.Process(target=_serve, args=(theirs, ours, throttled, os.getpid()),
                                  name="esail-opt figures")
        # Python's advice before a fork without exec: the collector's passes over the
        # objects alive now would write to every page the two processes still share,
        # and copying those pages slowed this process's solve by a tenth of a second.
        gc.freeze()
        try:
            process.start()
        except OSError:  # no fork to be had (memory, a process limit): drawn here
            gc.unfreeze()
            ours.close()
            return
        finally:
            theirs.close()
        self._process, self._conn = process, ours

    @property
    def running(self):
        """Whether a worker process was started (and not ended): it then takes a core
        of its own while the solve runs."""
        return self._process is not None

    def draft(self, solution):
        """Hand the worker the solution before its polish (``solution.solve``'s
        ``before_polish``), to draw and render the timeline's closed form meanwhile
        (one draft at most).

        Sent from a thread: the solution fills more than a pipe holds, and a worker
        still making its frame reads it only then, which the polish need not wait for.
        """
        if self._conn is None or self._drafting is not None:
            return
        self._drafting = threading.Thread(target=self._send_draft, args=(solution,),
                                          name="esail-opt draft", daemon=True)
        self._drafting.start()

    def _send_draft(self, solution):
        try:
            self._conn.send(("draft", solution))
        except OSError:
            pass  # the worker is gone: start() finds it so

    def start(self, solution, out_dir):
        """Hand the worker ``solution`` to draw into ``out_dir``; :meth:`written` waits.
        A worker that is not ready, or has not taken its draft, within
        :data:`WAIT_SECONDS` is ended, and the figures are drawn here."""
        self._job = (solution, Path(out_dir))
        if self._conn is None:
            return
        if self._drafting is not None:
            self._drafting.join(WAIT_SECONDS)
            if self._drafting.is_alive():
                self.close(wait=False)  # written() draws here
                return
        try:
            if not self._ready:
                self._ready = self._conn.poll(WAIT_SECONDS) and self._conn.recv() == "ready"
            if self._ready:
                self._conn.send(("draw", solution, str(out_dir)))
        except (OSError, EOFError):
            self._ready = False
        if not self._ready:
            self.close(wait=False)  # written() draws here

    def written(self):
        """The paths of the figures of the solution given to :meth:`start`, written by
        the worker when it is there and sound, else drawn here now.  Raises what
        drawing them here raises (:func:`esail_opt.app.plots.write_plots`)."""
        reply = None
        if self._conn is not None:
            try:
                reply = self._conn.recv() if self._conn.poll(WAIT_SECONDS) else None
            except (OSError, EOFError):
                reply = None
            self.close(wait=reply is not None)
        if reply is not None and reply[0] == "written":
            return [Path(p) for p in reply[1]]
        from esail_opt.app import plots

        return plots.write_plots(*self._job)

    def close(self, wait=True):
        """End the worker: it ends by itself once its pipe closes, or (without ``wait``,
        or when it does not within seconds) it is killed."""
        if self._drafting is not None and self._drafting.is_alive():
            # A draft still being sent: end the worker first, which fails the send, so
            # that the pipe is not closed under the thread writing to it.
            self._process.kill()
            self._drafting.join()
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        if self._process is not None:
            self._process.join(timeout=5 if wait else 0)
            if self._process.is_alive():
                self._process.kill()  # its figures' processes end with it
                self._process.join()
            self._process = None
            gc.unfreeze()

    def __enter__(self):
        return self

    def __exit__(self, kind, value, traceback):
        # After a failure or an interrupt, what the worker draws has nowhere to go.
        self.close(wait=kind is None)
        return False


def _serve(conn, parent_end, throttled, parent):
    """The worker: import the plots, make the timeline's frame, wait for one solution
    (drawing its timeline's draft if one comes first), draw its figures, report."""
    parent_end.close()  # so that the parent's end closing reads as EOF
    quiet_child(parent)
    from esail_opt.app import plots

    frame = None if throttled is None else plots.timeline_frame(throttled)
    draft = None
    try:
        conn.send("ready")
        message = conn.recv()
        if message[0] == "draft":
            try:
                draft = plots.timeline_draft(message[1], frame=frame)
            except Exception:  # the timeline is then drawn whole, and meets it there
                draft = None
            frame = None  # drawn into, or left half-drawn: either way not reusable
            message = conn.recv()
        _, solution, out = message
    except (OSError, EOFError):
        return
    figures = [(name, functools.partial(draw, frame=frame)
                if draw is plots.timeline_figure else draw) for name, draw in plots.FIGURES]
    try:
        reply = ("written", [str(p) for p in _draw_all(plots, figures, solution, Path(out),
                                                       draft)])
    except Exception as err:  # the parent draws again, and meets it itself
        reply = ("failed", repr(err))
    try:
        conn.send(reply)
    except OSError:
        pass  # the parent stopped waiting (its run failed or was interrupted)


def _draw_all(plots, figures, solution, out, draft=None):
    """Every figure of ``figures`` (:data:`esail_opt.app.plots.FIGURES`), each but the
    last in a forked process of its own, the last (the timeline) here: finished from
    ``draft`` when that is this solution's, else drawn with its frame in two bands at
    once (:mod:`esail_opt.app.bands`: the others are written by then); raises if any of
    them failed."""
    context = multiprocessing.get_context("fork")
    figures = [(out / name, draw) for name, draw in figures]
    gc.freeze()  # as before the worker's own fork (PlotWorker)
    others = []
    for path, draw in figures[:-1]:
        ours, theirs = context.Pipe(duplex=False)
        child = context.Process(target=_draw_one,
                                args=(solution, path, draw, theirs, os.getpid()), daemon=True)
        child.start()
        theirs.close()
        others.append((child, ours))
    path, draw = figures[-1]
    if draft is not None and draft.fits(solution):
        failures = [_failure(plots, solution, path, draft=draft)]
    else:
        failures = [_failure(plots, solution, path, draw, banded=True)]
    for child, ours in others:
        try:
            failure = ours.recv()
        except EOFError:
            failure = "a figure's process ended without a word"
        child.join()
        failures.append(failure)
    failures = [f for f in failures if f is not None]
    if failures:
        raise RuntimeError("; ".join(failures))
    return [path for path, _ in figures]


def _failure(plots, solution, path, draw=None, banded=False, draft=None):
    """Draw and write one figure (the timeline, finished from ``draft``, when one is
    given): None, or what went wrong, in words."""
    try:
        if draft is not None:
            plots.write_pixels(draft.pixels(solution), path)
        else:
            plots.write_figure(draw(solution), path, banded=banded)
    except Exception as err:
        return repr(err)
    return None


def _draw_one(solution, path, draw, conn, parent):
    """A figure's process: draw and write it, then send None, or what went wrong."""
    from esail_opt.app import plots

    quiet_child(parent)
    failure = _failure(plots, solution, path, draw)
    try:
        conn.send(failure)
    except OSError:
        pass
