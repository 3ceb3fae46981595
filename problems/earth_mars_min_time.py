"""Earth to Mars, orbit to orbit, in minimum time: a_c = 1 mm/s^2, circular 1 au to
circular 1.524 au (coplanar, circular approximation of both orbits).

At a_c = 1 mm/s^2 the closed form needs short arcs, so each of the 60 segments is flown
as 3 rectified second-order sub-arcs (THEORY.md §3.8).  Measured: 3 sub-arcs solved in
0.30 s (74 Ipopt iterations) to fly 199 km from Mars's orbit, 2 in 0.43 s (120) to fly
448 km.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_min_time",
    description="Minimum-time transfer, circular 1 au -> circular 1.524 au, a_c = 1 mm/s^2",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=60, sub_arcs=3, equal=False),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
)
