"""Earth to Venus, orbit to orbit, in minimum time: a_c = 1 mm/s^2, circular 1 au to
circular 0.723 au.  The seeding propagation pitches at -45 deg (inward spiral)."""

import esail_opt as eo

problem = eo.Problem(
    name="earth_venus_min_time",
    description="Minimum-time transfer, circular 1 au -> circular 0.723 au, a_c = 1 mm/s^2",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=30, sub_arcs=1, equal=False),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=0.723),
)
