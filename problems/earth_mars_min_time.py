"""Earth to Mars, orbit to orbit, in minimum time: a_c = 1 mm/s^2, circular 1 au to
circular 1.524 au (coplanar, circular approximation of both orbits).

At a_c = 1 mm/s^2 the first-order arc needs short arcs (THEORY.md §5.2: about a tenth of a
radian), so each of the 60 segments is flown as 3 rectified sub-arcs.
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
