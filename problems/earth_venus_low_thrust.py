"""Earth to Venus, orbit to orbit, in minimum time with a low-performance E-sail:
a_c = 0.1 mm/s^2, circular 1 au to circular 0.723 au, sail always on.

An inward spiral of about seven revolutions; the segments are given per revolution and
their count follows from the constant-pitch (-45 deg) seeding propagation, stopped where
it reaches 0.723 au.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_venus_low_thrust",
    description="Minimum-time transfer, circular 1 au -> circular 0.723 au, a_c = 0.1 mm/s^2",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=0.1),
    segments=eo.Segments(per_revolution=16, sub_arcs=1),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=0.723),
)
