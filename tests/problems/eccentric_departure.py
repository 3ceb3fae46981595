"""From an eccentric orbit (a = 1.3 au, e = 0.25, leaving 30 deg past perihelion) to a
circular orbit of 1.9 au at 1 mm/s^2, on 10 segments of 2 sub-arcs."""

import esail_opt as eo

problem = eo.Problem(
    name="eccentric_departure",
    departure=eo.ParkingOrbit(a_au=1.3, e=0.25, nu_deg=30.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=10, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.9),
)
