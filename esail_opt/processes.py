"""Whether another process is still there: stale temporary folders are named after the
process that made them, and are removed only once it is gone."""

import os


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
