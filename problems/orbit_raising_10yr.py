"""The paper's orbit-raising scenario (Figs. 5-7) with the pitch left free: a_c = 0.1 mm/s^2
from the circular 1 au orbit for 10 years, maximising the final osculating semimajor axis.

MaxEnergy maximises v^2/2 - 1/r, which for a bound orbit is maximising a = -1/(2E).
The paper flies a fixed alpha = 45 deg; ``tests/test_optimisation_slow.py`` checks that
this schedule beats it on the CVODES-verified final a.
"""

import esail_opt as eo

problem = eo.Problem(
    name="orbit_raising_10yr",
    description="Maximum final semimajor axis after 10 years from 1 au, a_c = 0.1 mm/s^2",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=0.1),
    segments=eo.Segments(count=60, sub_arcs=2),
    objective=eo.MaxEnergy(tof_days=10 * 365.25),
    target=None,
)
