"""esail_opt: trajectory optimisation of Electric Solar Wind Sails on the paper's closed
form of fixed-attitude arcs (to second order in the thrust), verified on Eqs. 1-2 with CVODES.

A problem file does ``import esail_opt as eo``, builds ``problem = eo.Problem(...)`` from the
names below (:mod:`esail_opt.optimisation.problem`); ``eo.solve(problem)`` returns a
:class:`Solution`.
"""

import os

# One BLAS thread for the bundled Ipopt, for scripts as for ``esail-opt``, unless the
# environment says otherwise: a second changes the rounding of MUMPS's factorisations, enough
# to move a warm-started chart to other local optima, and these NLPs are too small to gain.
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
    # Loaded lazily (matplotlib, Ipopt), so that ``import esail_opt`` stays cheap.
    if name in ("solve", "Solution"):
        from esail_opt.app import solution

        return getattr(solution, name)
    raise AttributeError(f"module 'esail_opt' has no attribute {name!r}")
