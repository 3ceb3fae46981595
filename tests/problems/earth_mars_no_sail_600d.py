"""The least a_c to meet Mars (DE421) 600 days after leaving Earth on 2035-06-01: no sail
does it.  The E-sail's thrust never points more than 19.5 deg from the outward radial,
and an independent walk in the time of flight (a_c held at 5 mm/s^2, from a solved
transfer) found the shortest feasible flight from that date between 635 and 640 days."""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_no_sail_600d",
    description="Minimum a_c, Earth 2035-06-01 -> Mars (DE421) in 600 d: infeasible",
    departure=eo.BodyDeparture(body="earth", date="2035-06-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    objective=eo.MinAcceleration(tof_days=600.0),
    target=eo.BodyRendezvous(body="mars"),
)
