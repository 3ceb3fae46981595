"""A user's first try: the fastest spiral from 1 au down to 0.1 au at 1 mm/s^2, on 20
coarse segments of 3 sub-arcs (the closed form's optimum on this mesh alone flew
1.6e7 km from the target)."""

import esail_opt as eo

problem = eo.Problem(
    name="spiral_in_0p1au",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=20, sub_arcs=3),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=0.1),
    path=eo.PathConstraints(r_min_au=0.05),
)
