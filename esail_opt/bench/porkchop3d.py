"""``esail-opt-bench porkchop3d``: the launch-window scan of ``porkchop`` in three dimensions.

The same patch of the Earth-Venus minimum-a_c porkchop flown in three dimensions
(:data:`PROBLEM`: a pitch and a clock per segment, Venus's unprojected state at arrival)
and solved the same three ways (``porkchop.timed_scans``): the 3-D closed form, RK4
segments of the turning-plane equations (``rk4.rk4_segment_turning``), and every cell
solved cold by ``eo.solve``.  Every cell is verified in three dimensions by CVODES.
"""

from esail_opt.bench.porkchop import timed_scans
from esail_opt.optimisation.problem_file import shipped_problem

#: The shipped 3-D problem whose porkchop this bench scans.
PROBLEM = "earth_venus_min_ac"


def run(out, repeats=1):
    """Time the 3-D scan three ways; writes ``porkchop3d.json`` and returns its path."""
    return timed_scans(out, "porkchop3d", PROBLEM, shipped_problem(PROBLEM))
