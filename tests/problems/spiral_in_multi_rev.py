"""Inward spiral over several revolutions: 1 au to 0.5 au at 0.3 mm/s^2 in minimum time,
on 16 coarse segments of 2 sub-arcs."""

import esail_opt as eo

problem = eo.Problem(
    name="spiral_in_multi_rev",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=0.3),
    segments=eo.Segments(count=16, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=0.5),
)
