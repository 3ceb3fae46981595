"""Loading a problem file: a Python file in ``problems/`` that names one ``Problem`` ``problem``.

Every way a file can be wrong ends in one :class:`~esail_opt.errors.InputError` line that
the command line prints: a missing file, an exception raised while it runs (a range
check of :mod:`.problem`, a syntax error, a ``sys.exit()``), no ``problem`` in it, or one
of another type.
"""

import runpy
from pathlib import Path

from esail_opt.errors import InputError
from esail_opt.optimisation.problem import Problem


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
