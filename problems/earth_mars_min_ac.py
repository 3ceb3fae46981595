"""Earth to Mars: the smallest characteristic acceleration for one fixed launch, in three
dimensions.

Leaving the Earth-Moon barycentre's orbit on 2031-08-11T12:18:59.938 and meeting Mars
(DE421 position and velocity, unprojected) 657.0191 days later, the throttle free on
every one of 40 segments: the a_c the sail must have for that launch and flight time,
with the plane change to Mars's orbit paid.  Its planar twin,
``earth_mars_min_ac_planar.py``, poses the same transfer in the ecliptic projection, as
another tool's script and the earlier releases did:

    esail-opt solve problems/earth_mars_min_ac.py --polish

The sail's ``ac_mm_s2`` is only the seed and the scale of the a_c the optimiser finds.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_min_ac",
    description="Minimum a_c for a rendezvous with Mars (DE421, unprojected), departing "
                "2031-08-11T12:18:59.938, 657.0191 days, throttle free",
    departure=eo.BodyDeparture(body="earth", date="2031-08-11T12:18:59.938"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=40),
    objective=eo.MinAcceleration(tof_days=657.0191),
    target=eo.BodyRendezvous(body="mars"),
)
