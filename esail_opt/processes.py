"""Processes of our own: whether another one is still there, a child that ends with its
parent, and one job run beside the caller's own work in a forked child.

Stale temporary folders are named after the process that made them, and are removed
only once it is gone (:func:`alive`).  Pool workers and forked children end when their
parent does, however it ended (:func:`die_with_parent`).
"""

import contextlib
import ctypes
import os
import pickle
import signal
import sys
import threading
import time

#: Seconds between two looks of a child at its parent's pid.
PARENT_POLL_SECONDS = 1.0
#: prctl's option that has the kernel signal a process when its parent ends.
_PR_SET_PDEATHSIG = 1


def alive(pid):
    """Whether a process ``pid`` exists on this machine (this one's own always does)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, under another user
        return True
    return True


def die_with_parent(parent):
    """End this process when process ``parent`` ends.

    On Linux the kernel sends SIGKILL at once (``prctl(PR_SET_PDEATHSIG)``; it fires
    when the thread that started this process ends, which for a pool is the parent's
    main thread, or the parent itself).  Everywhere a daemon thread also checks every
    :data:`PARENT_POLL_SECONDS` that the parent is still this process's parent: an
    orphan is re-parented, so a changed ``getppid()`` means the parent is gone.
    """
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent:  # the parent died before the prctl took hold
        os._exit(1)

    def watch():
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_SECONDS)
        os._exit(1)

    threading.Thread(target=watch, name="esail-parent-watch", daemon=True).start()


@contextlib.contextmanager
def beside(job):
    """Run ``job()`` in a forked child while the body of the ``with`` runs here.

    The two share nothing but what existed at the fork, so this suits work that only
    reads what the caller holds and writes files of its own (two figures of one
    solution).  Leaving the block waits for the child; an exception ``job`` raised is
    raised here (as a RuntimeError with its first line if it does not pickle).  An
    exception in the body, Ctrl-C or SIGTERM included, kills the child first.  Where
    the platform cannot fork, ``job`` runs here after the body.
    """
    if not hasattr(os, "fork"):
        yield
        job()
        return
    parent = os.getpid()
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: its own signals, no cleanup of the parent's
        os.close(read)
        code = 0
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            die_with_parent(parent)
            job()
        except BaseException as err:  # reported to the parent, whatever it was
            code = 1
            try:
                message = pickle.dumps(err)
            except Exception:
                message = pickle.dumps(RuntimeError(str(err).splitlines()[0] if str(err)
                                                    else type(err).__name__))
            with os.fdopen(write, "wb") as pipe:
                pipe.write(message)
        os._exit(code)
    os.close(write)
    try:
        yield
    except BaseException:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        os.close(read)
        raise
    with os.fdopen(read, "rb") as pipe:
        message = pipe.read()
    _, status = os.waitpid(pid, 0)
    if message:
        raise pickle.loads(message)
    if status != 0:
        raise RuntimeError(f"a forked child ended with status {status}")
