"""Minimum a_c for a 650-day Earth-Venus rendezvous in three dimensions: the sail must
also turn its orbital plane onto Venus's (3.39 deg off the ecliptic), which the planar
`earth_venus_min_ac.py` never pays for."""

import esail_opt as eo

problem = eo.Problem(
    name="earth_venus_min_ac_3d",
    description="Minimum a_c for a rendezvous with Venus (DE421) in 3-D, departing "
                "2031-01-01, 650 days, throttle free",
    departure=eo.BodyDeparture(body="earth", date="2031-01-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=24, sub_arcs=2, equal=True),
    objective=eo.MinAcceleration(tof_days=650.0),
    target=eo.BodyRendezvous(body="venus"),
    planar=False,
)
