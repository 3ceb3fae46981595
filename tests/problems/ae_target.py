"""To an orbit given by its size and shape only, a = 1.4 au and e = 0.15 (apse line
free), from 1 au at 1 mm/s^2, on 10 segments of 2 sub-arcs."""

import esail_opt as eo

problem = eo.Problem(
    name="ae_target",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=10, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.Orbit(a_au=1.4, e=0.15),
)
