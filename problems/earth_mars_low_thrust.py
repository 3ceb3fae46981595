"""Earth to Mars, orbit to orbit, in minimum time with a low-performance E-sail:
a_c = 0.1 mm/s^2, circular 1 au to circular 1.524 au (coplanar), sail always on.

The transfer is a spiral of about 6.5 revolutions lasting some nine years; nobody knows
the number of turns before solving, so the segments are given per revolution and their
count follows from the constant-pitch (+45 deg) seeding propagation, stopped where it
reaches 1.524 au.  At a~_c = 0.017 a second-order closed-form arc may span a large
angle, so a segment of a sixteenth of a turn is one arc.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_low_thrust",
    description="Minimum-time transfer, circular 1 au -> circular 1.524 au, a_c = 0.1 mm/s^2",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=0.1),
    segments=eo.Segments(per_revolution=16, sub_arcs=1),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
)
