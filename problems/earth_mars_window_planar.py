"""Earth-Mars minimum-time rendezvous in the ecliptic projection: `earth_mars_window.py`
flown as the model before three dimensions flew it, each body's DE421 state projected on
the ecliptic, one pitch angle per segment (``planar=True``).  It is the comparison for
the 3-D answer, which must also climb 1.85 deg out of Earth's plane to meet Mars."""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_window_planar",
    description="Minimum-time rendezvous with Mars (DE421) in the ecliptic projection, "
                "a_c = 1 mm/s^2, departure free in 2030-2033",
    departure=eo.BodyDeparture(body="earth", window=("2030-01-01", "2033-01-01")),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=40, sub_arcs=3, equal=False),
    objective=eo.MinTime(),
    target=eo.BodyRendezvous(body="mars"),
    planar=True,
)
