"""esail_opt: trajectory optimisation of Electric Solar Wind Sails on the paper's
closed form of fixed-attitude arcs (carried to second order in the thrust), verified on
Eqs. 1-2 with CVODES.

A problem file does ``import esail_opt as eo`` and builds ``problem = eo.Problem(...)``
from the names below (see :mod:`esail_opt.optimisation.problem`); ``eo.solve(problem)``
runs it and returns a :class:`Solution`.
"""

import os

# One BLAS thread for the Ipopt that CasADi bundles, unless the user's environment says
# otherwise.  Its OpenBLAS reads this when it loads, at the first solve, so setting it
# here holds for scripts as for ``esail-opt``: with a second thread the rounding of
# MUMPS's factorisations differs, enough for a warm-started chart to settle in other
# close local optima (a script's Earth-Venus chart differed from the command's by up to
# 3 % a cell), and the factorisations of these NLPs are too small to gain from it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from esail_opt.bodies.keplerian import BENNU, CERES, SmallBody  # noqa: F401
from esail_opt.optimisation.goals import (  # noqa: F401
    BodyIntercept, BodyRendezvous, CircularOrbit, FinalStateExpression, MaxEnergy, MaxRadius,
    MinAcceleration, MinTime, Orbit, Rendezvous,
)
from esail_opt.optimisation.problem import (  # noqa: F401
    BEST_FIT, EXACT, BodyDeparture, ParkingOrbit, PathConstraints, PolarState, Problem, Sail,
    Segments, Tolerance,
)


def __getattr__(name):
    # The application layer (matplotlib, Ipopt) loads only when asked for, so that
    # ``import esail_opt`` in a problem file stays cheap.
    if name in ("solve", "Solution"):
        from esail_opt.app import solution

        return getattr(solution, name)
    raise AttributeError(f"module 'esail_opt' has no attribute {name!r}")
