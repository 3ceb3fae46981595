"""Minimum a_c for a 650-day Earth-Venus rendezvous in the ecliptic projection:
`earth_venus_min_ac.py` with ``planar=True``, the comparison that never pays for turning
the orbital plane onto Venus's (3.39 deg off the ecliptic)."""

import esail_opt as eo

problem = eo.Problem(
    name="earth_venus_min_ac_planar",
    description="Minimum a_c for a rendezvous with Venus (DE421) in the ecliptic "
                "projection, departing 2031-01-01, 650 days, throttle free",
    departure=eo.BodyDeparture(body="earth", date="2031-01-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=24, sub_arcs=2, equal=True),
    objective=eo.MinAcceleration(tof_days=650.0),
    target=eo.BodyRendezvous(body="venus"),
    planar=True,
)
