"""Processes of our own: whether another one is still there (:func:`alive`), so that a stale
temporary folder named after its maker is removed only once it is gone, and a child that
ends with its parent, however the parent ended (:func:`die_with_parent`).
"""

import contextlib
import ctypes
import os
import re
import shutil
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


def remove_dead(folder, prefix):
    """Remove the entries of ``folder`` named ``prefix`` then the pid of the process that
    made them, where that process no longer exists (a run killed outright leaves them).
    An entry whose process is alive, or whose name carries no pid there, is left."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    for entry in entries:
        pid = re.match(r"\d+", entry.name[len(prefix):]) if entry.name.startswith(prefix) else None
        if pid and not alive(int(pid.group())):
            shutil.rmtree(entry.path, ignore_errors=True)


def die_with_parent(parent):
    """End this process when process ``parent`` ends: on Linux the kernel sends SIGKILL at once
    (``prctl(PR_SET_PDEATHSIG)``, which fires when the thread that started this process ends:
    for a pool, the parent's main thread); everywhere, a daemon thread checks every
    :data:`PARENT_POLL_SECONDS` that ``getppid()`` is still ``parent``, since an orphan is
    re-parented."""
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
