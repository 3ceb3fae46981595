"""The one place that sets how signals are handled: handlers and masks.  Ctrl-C (SIGINT) and
SIGTERM stop a command the same way (:class:`~esail_opt.errors.Terminated` is SIGTERM as a
KeyboardInterrupt), and every other module asks this one for what it needs.  Python runs
signal handlers in the main thread only, so each of these changes nothing in another thread.
"""

import contextlib
import signal
import threading

from esail_opt.errors import Terminated


def _main_thread():
    return threading.current_thread() is threading.main_thread()


class SignalsHeld:
    """Inside, SIGINT (and SIGTERM, where a Python handler, the command line's, already turns it
    into an exception) is recorded rather than raised; on the way out its exception is raised,
    KeyboardInterrupt or :class:`Terminated`.  For CasADi's C++ (Ipopt, CVODES), which checks
    Python's signals as it runs: an exception raised there fails the evaluation where it
    stands, so Ctrl-C during a CVODES flight would read as a failed flight (exit 1), not an
    interrupt (exit 130).  ``interrupted`` tells a caller that polls (Ipopt's iteration
    callback) to stop early."""

    def __init__(self):
        self.signum = None
        self._saved = {}

    @property
    def interrupted(self):
        return self.signum is not None

    def __enter__(self):
        self.signum = None
        if _main_thread():
            self._saved[signal.SIGINT] = signal.signal(signal.SIGINT, self._record)
            if callable(signal.getsignal(signal.SIGTERM)):
                self._saved[signal.SIGTERM] = signal.signal(signal.SIGTERM, self._record)
        return self

    def _record(self, signum, frame):
        self.signum = signum

    def __exit__(self, kind, value, traceback):
        for signum, handler in self._saved.items():
            signal.signal(signum, handler)
        self._saved = {}
        if self.signum is not None and kind is None:
            raise (KeyboardInterrupt() if self.signum == signal.SIGINT
                   else Terminated(self.signum))
        return False


def _terminate(signum, frame):
    raise Terminated(signum)


@contextlib.contextmanager
def terminate_as_interrupt():
    """Inside, SIGTERM (sent by kill, systemd and batch schedulers) raises
    :class:`Terminated`, so that it cleans up as Ctrl-C does; unless a handler of the
    caller's own is already installed."""
    previous = None
    if _main_thread() and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
        previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def ignoring():
    """Inside, SIGINT and SIGTERM are ignored: a second Ctrl-C, or a SIGTERM after one,
    must not cut a clean-up short and leave workers running."""
    previous = {}
    if _main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, signal.SIG_IGN)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@contextlib.contextmanager
def blocked():
    """Hold SIGINT and SIGTERM until the block ends (they are delivered then), so that
    what it does (a swap of folders and its clean-up) is never cut in the middle."""
    try:
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    except (AttributeError, OSError, ValueError):
        previous = None
    try:
        yield
    finally:
        if previous is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def leave_interrupt_to_parent():
    """In a pool worker: ignore SIGINT, so that Ctrl-C in a terminal (sent to the whole
    process group) reaches only the parent, which decides what stops."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
