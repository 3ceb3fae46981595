"""Benchmarks, and the reference solvers they time.

``BENCHES`` maps a name to ``fn(out_dir, repeats)``, which runs the benchmark, writes its
files under ``out_dir`` and returns the path of its JSON (``esail-opt bench NAME``):

* ``timings``: propagate, solve, polish, lowthrust and sweep, each timed against a
  baseline measured in the same run;
* ``precision``: solve time against verified accuracy for the closed form, RK4 and
  CVODES segments (``bench.rk4`` is the RK4 segment).
"""

# The submodules keep their names here (bench.precision is the module, its bench is
# bench.precision.precision); the timings' functions stay reachable as before the move.
from esail_opt.bench import precision, rk4, timings
from esail_opt.bench.timings import lowthrust, polish_bench, propagate, solve, sweep

BENCHES = {**timings.BENCHES, "precision": precision.precision}

__all__ = ["BENCHES", "lowthrust", "polish_bench", "precision", "propagate", "rk4", "solve",
           "sweep", "timings"]
