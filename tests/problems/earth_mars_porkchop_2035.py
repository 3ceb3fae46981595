"""The least a_c to meet Mars (DE421) after leaving Earth in 2035, the kind of
problems/earth_mars_2035.py at a fixed time of flight, seeded at 1 mm/s^2: a porkchop over
departure dates and times of flight replaces the date and the time of flight.

It flies in the ecliptic projection (``planar=True``): the independent walk that the
porkchop's edge is checked against was made on that model."""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_porkchop_2035",
    description="Minimum a_c, Earth 2035 -> Mars (DE421), per departure date and flight time",
    departure=eo.BodyDeparture(body="earth", date="2035-06-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    objective=eo.MinAcceleration(tof_days=650.0),
    target=eo.BodyRendezvous(body="mars"),
    planar=True,
)
