"""Loading a problem file: a Python file in ``problems/`` that names one ``Problem`` ``problem``.

A file is loaded by path (:func:`load_problem`), or, for the shipped ones, by name
(:func:`shipped_problem`) from the package data ``esail_opt.problems``.

Every way a file can be wrong ends in one :class:`~esail_opt.errors.InputError` line that
the command line prints: a missing file, an exception raised while it runs (a range
check of :mod:`.problem`, a syntax error, a ``sys.exit()``), no ``problem`` in it, or one
of another type.
"""

import importlib.resources
import runpy
from pathlib import Path

from esail_opt.errors import InputError
from esail_opt.optimisation.problem import Problem

#: The package the shipped problem files install as (``problems/`` in the repository).
SHIPPED_PACKAGE = "esail_opt.problems"


def load_problem(path):
    """Run the file at ``path`` and return its ``problem``.

    Raises
    ------
    InputError
        With one line naming the file and what is wrong.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"problem file {str(path)!r} does not exist")
    try:
        namespace = runpy.run_path(str(path), run_name="problem_file")
    except InputError as err:
        raise InputError(f"{path.name}: {err}") from None
    except SystemExit as err:
        # sys.exit() in a problem file ends nothing but the load: exit 0 would read as
        # "converged and verified" with nothing solved.
        raise InputError(f"{path.name}: the file called sys.exit({err.code!r}) while it was "
                         "loaded; a problem file must define `problem`, not exit") from None
    except Exception as err:  # a user file can fail in any way; report it in one line
        detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise InputError(f"{path.name}: {type(err).__name__}: {detail}") from None
    if "problem" not in namespace:
        raise InputError(f"{path.name}: problem is missing (the file must define "
                         "`problem = esail_opt.Problem(...)`)")
    problem = namespace["problem"]
    if not isinstance(problem, Problem):
        raise InputError(f"{path.name}: problem = {type(problem).__name__} is not an "
                         "esail_opt.Problem")
    return problem


def _shipped_folder():
    """The folder of the shipped problem files, as an ``importlib.resources`` Traversable.

    An installed package (editable or not) has ``esail_opt.problems``.  A source
    checkout imported through ``PYTHONPATH`` without being installed has no such
    module, since only the installer maps ``problems/`` into the package; its files are
    then the checkout's own ``problems/`` folder beside ``esail_opt/``.
    """
    try:
        return importlib.resources.files(SHIPPED_PACKAGE)
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "problems"


def shipped_problem_names():
    """Names of the shipped problem files (without ``.py``), sorted.

    Returns
    -------
    tuple of str
        Every ``NAME.py`` of the shipped folder but the package's ``__init__.py``.
    """
    return tuple(sorted(entry.name[:-3] for entry in _shipped_folder().iterdir()
                        if entry.name.endswith(".py") and not entry.name.startswith("_")))


def shipped_problem(name):
    """Load the shipped problem file ``NAME.py`` and return its ``problem``.

    The file goes through :func:`load_problem`, so a shipped problem is checked exactly
    as a user's file is.

    Parameters
    ----------
    name : str
        One of :func:`shipped_problem_names`.

    Raises
    ------
    InputError
        If no shipped file has that name (one line listing the names), or as
        :func:`load_problem` raises.
    """
    names = shipped_problem_names()
    if name not in names:
        raise InputError(f"shipped problem = {name!r} is not one of: {', '.join(names)}")
    # as_file gives a real path even when the package is imported from a zip archive.
    with importlib.resources.as_file(_shipped_folder() / f"{name}.py") as path:
        return load_problem(path)
