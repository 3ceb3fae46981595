"""``esail-opt-bench porkchop3d``: the launch-window scan of ``porkchop`` in three dimensions.

The same 24-cell patch (6 departure dates x 4 times of flight) of the Earth-Venus
minimum-a_c porkchop, flown in three dimensions (:data:`PROBLEM`, ``planar=False``: a
pitch and a clock angle per segment, Venus's unprojected DE421 state at arrival), and
solved the same three ways in one process (``porkchop.timed_scans``):

* the scan as ``esail-opt porkchop`` runs it, on the 3-D closed form
  (``segment_methods.closed_form_segment3d``), error control and verification per cell;
* the same scan on RK4 segments of the turning-plane equations
  (``rk4.rk4_segment_turning``: Eqs. 1-2 and the plane's quaternion, the 3-D NLP's own
  state), at the fewest steps a segment whose first cell verifies;
* every cell solved cold by ``eo.solve``, its turn counts searched as a lone solve's are.

Every cell of every method is verified in three dimensions by CVODES, against
Venus's unprojected state.
"""

from esail_opt.bench.porkchop import timed_scans
from esail_opt.optimisation.problem_file import shipped_problem

#: The shipped 3-D problem whose porkchop this bench scans.
PROBLEM = "earth_venus_min_ac"


def run(out, repeats=1):
    """Time the 3-D scan three ways; writes ``porkchop3d.json`` and returns its path."""
    return timed_scans(out, "porkchop3d", PROBLEM, shipped_problem(PROBLEM))
