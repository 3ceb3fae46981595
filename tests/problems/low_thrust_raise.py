"""A low-performance sail: 0.1 mm/s^2 from 1 au to 1.25 au in minimum time, with only
four segments per revolution of 2 sub-arcs each."""

import esail_opt as eo

problem = eo.Problem(
    name="low_thrust_raise",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=0.1),
    segments=eo.Segments(per_revolution=4, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.25),
)
