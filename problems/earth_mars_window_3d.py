"""Earth-Mars minimum-time rendezvous in three dimensions: the window problem flown
between DE421's unprojected states, with a pitch and a clock angle per segment, so that
the sail climbs out of Earth's plane to meet Mars in its own (1.85 deg off the ecliptic).
`earth_mars_window.py` is the same transfer in the ecliptic projection."""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_window_3d",
    description="Minimum-time rendezvous with Mars (DE421) in 3-D, a_c = 1 mm/s^2, "
                "departure free in 2030-2033",
    departure=eo.BodyDeparture(body="earth", window=("2030-01-01", "2033-01-01")),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=40, sub_arcs=3, equal=False),
    objective=eo.MinTime(),
    target=eo.BodyRendezvous(body="mars"),
    planar=False,
)
