"""Earth to Venus: the smallest characteristic acceleration for given dates.

Leaving the Earth-Moon barycentre's orbit on 2031-01-01 and meeting Venus (DE421
position and velocity) 650 days later, the throttle free on every segment: the a_c the
sail must have for that launch date and flight time, in three dimensions: it also
turns the orbital plane onto Venus's, 3.39 deg off the ecliptic
(``earth_venus_min_ac_planar.py`` is the ecliptic projection, for comparison).  Its porkchop, over launch dates
and flight times, is the sail designer's chart:

    esail-opt porkchop problems/earth_venus_min_ac.py --depart 2031-01-01:2032-06-01:6 \\
        --tof 550:850:4

The sail's ``ac_mm_s2`` is only the seed and the scale of the a_c the optimiser finds.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_venus_min_ac",
    description="Minimum a_c for a rendezvous with Venus (DE421), departing 2031-01-01, "
                "650 days, throttle free",
    departure=eo.BodyDeparture(body="earth", date="2031-01-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=24, sub_arcs=2, equal=True),
    objective=eo.MinAcceleration(tof_days=650.0),
    target=eo.BodyRendezvous(body="venus"),
)
