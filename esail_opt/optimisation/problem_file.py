"""Loading a problem file: a Python file in ``problems/`` that names one ``Problem`` ``problem``.

Loaded by path (:func:`load_problem`) or, for the shipped ones, by name
(:func:`shipped_problem`).  Every way a file can be wrong (missing, raising anything but
``KeyboardInterrupt``, ending its process, no ``problem`` or one of another type) ends in
one :class:`~esail_opt.errors.InputError` line.
"""

import contextlib
import dataclasses
import importlib.resources
import os
import re
import runpy
import signal
import sys
import threading
from pathlib import Path

from esail_opt.errors import InputError
from esail_opt.optimisation import problem as problem_parts
from esail_opt.optimisation.problem import Problem

#: The package the shipped problem files install as (``problems/`` in the repository).
SHIPPED_PACKAGE = "esail_opt.problems"


def load_problem(path):
    """Run the file at ``path`` and return its ``problem``.

    Where the process may fork (no other thread: a forked threaded process can deadlock),
    the file first runs in a child (:func:`_check_in_child`) so that one ending its process
    is bad input, then here.  Raises InputError (one line naming the file and the fault),
    or KeyboardInterrupt on Ctrl-C, SIGTERM (:class:`~esail_opt.errors.Terminated`) or
    the file's own.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"problem file {str(path)!r} is a folder (a Python file that "
                         "defines `problem` is expected)")
    if not path.is_file():
        raise InputError(f"problem file {str(path)!r} does not exist")
    if hasattr(os, "fork") and threading.active_count() == 1:
        _check_in_child(path)
    return _run(path)


def _run(path):
    """Run the file in this process and return its checked ``problem``."""
    try:
        namespace = runpy.run_path(str(path), run_name="problem_file")
    except KeyboardInterrupt:
        raise
    except InputError as err:
        raise InputError(f"{path.name}: {err}") from None
    except SystemExit as err:
        # sys.exit() in a problem file ends nothing but the load: exit 0 would read as
        # "converged and verified" with nothing solved.
        raise InputError(f"{path.name}: the file called sys.exit({err.code!r}) while it was "
                         "loaded; a problem file must define `problem`, not exit") from None
    except BaseException as err:  # a user file can fail in any way; report it in one line
        detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise InputError(f"{path.name}: {type(err).__name__}"
                         + (f": {detail}" if detail else "") + _fields_hint(detail)) from None
    if "problem" not in namespace:
        raise InputError(f"{path.name}: problem is missing (the file must define "
                         "`problem = esail_opt.Problem(...)`)")
    problem = namespace["problem"]
    if not isinstance(problem, Problem):
        raise InputError(f"{path.name}: problem = {type(problem).__name__} is not an "
                         "esail_opt.Problem")
    return problem


def _fields_hint(detail):
    """For a misspelt keyword of one of the problem's parts ("Sail.__init__() got an
    unexpected keyword argument 'acc_mm_s2'"), the fields that part takes; else ""."""
    found = re.match(r"(\w+)\.__init__\(\) got an unexpected keyword argument", detail)
    part = found and getattr(problem_parts, found.group(1), None)
    if not dataclasses.is_dataclass(part):
        return ""
    return f"; {part.__name__} takes " + ", ".join(f.name for f in dataclasses.fields(part)
                                                    if f.init)


#: What the forked child writes on its pipe: the file returned control (whether or not
#: it raised), or it was interrupted.  Nothing at all means the file ended the child.
_RETURNED, _INTERRUPTED = b"returned", b"interrupted"


def _check_in_child(path):
    """Run the file in a forked child: InputError if it ended the child's process
    (``os._exit``, a kill, a crash), KeyboardInterrupt if the child was interrupted."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()  # so that the child holds no copy of unwritten output
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child ends in _child
        os.close(read)
        _child(path, write)
    os.close(write)
    try:
        with os.fdopen(read, "rb") as pipe:
            report = pipe.read()
        status = os.waitpid(pid, 0)[1]
        pid = None
    finally:
        if pid is not None:  # interrupted here while the child ran
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
    if report == _RETURNED:
        return
    if report == _INTERRUPTED:
        raise KeyboardInterrupt
    code = os.waitstatus_to_exitcode(status)
    how = f"exit status {code}" if code >= 0 else f"killed by {signal.Signals(-code).name}"
    raise InputError(f"{path.name}: the file ended the process that loaded it ({how}) "
                     "before it defined `problem`; a problem file must define `problem`, "
                     "not exit")


def _child(path, fd):
    """The forked child: run the file, say on ``fd`` that it returned, and end without
    clean-up (the atexit handlers and buffered output are the parent's)."""
    try:
        quiet = os.open(os.devnull, os.O_WRONLY)
        os.dup2(quiet, 1)
        os.dup2(quiet, 2)
        # sys.stdout may not write to fd 1 (a test's capture, an embedding host).
        sys.stdout = sys.stderr = open(quiet, "w", closefd=False)
        try:
            runpy.run_path(str(path), run_name="problem_file")
            report = _RETURNED
        except KeyboardInterrupt:
            report = _INTERRUPTED
        except BaseException:  # the parent runs the file again and words the error
            report = _RETURNED
        os.write(fd, report)
    finally:
        os._exit(0)


def _shipped_folder():
    """The shipped problem files' folder (a Traversable): ``esail_opt.problems`` once
    installed, else, since only the installer maps it there, ``problems/`` beside
    ``esail_opt/``."""
    try:
        return importlib.resources.files(SHIPPED_PACKAGE)
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "problems"


def shipped_problem_names():
    """Names of the shipped problem files (without ``.py``), a sorted tuple."""
    return tuple(sorted(entry.name[:-3] for entry in _shipped_folder().iterdir()
                        if entry.name.endswith(".py") and not entry.name.startswith("_")))


def shipped_problem(name):
    """:func:`load_problem` of the shipped file ``name``.py; InputError listing the
    names (:func:`shipped_problem_names`) if there is no such file."""
    names = shipped_problem_names()
    if name not in names:
        raise InputError(f"shipped problem = {name!r} is not one of: {', '.join(names)}")
    # as_file gives a real path even when the package is imported from a zip archive.
    with importlib.resources.as_file(_shipped_folder() / f"{name}.py") as path:
        return load_problem(path)
