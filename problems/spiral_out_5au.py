"""Spiralling out: the largest solar distance a low-performance E-sail (a_c = 0.1 mm/s^2)
reaches in 5 years from the circular 1 au orbit, sail always on, pitch free.

The final state is free; the objective is the final radius r(5 years) itself
(``MaxRadius``), not the semimajor axis, so the optimum may end near an aphelion.
``tests/test_lowthrust.py`` compares it with the best constant pitch flown the same
5 years on Eqs. 1-2.  The segments are given per revolution; the count follows from
the +45 deg seeding propagation over the 5 years.
"""

import esail_opt as eo

problem = eo.Problem(
    name="spiral_out_5au",
    description="Maximum final radius after 5 years from circular 1 au, a_c = 0.1 mm/s^2",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=0.1),
    segments=eo.Segments(per_revolution=16, sub_arcs=2),
    objective=eo.MaxRadius(tof_days=5 * 365.25),
    target=None,
)
