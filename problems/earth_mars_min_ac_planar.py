"""Earth to Mars: the smallest characteristic acceleration for one fixed launch, in the
ecliptic projection (the planar twin of ``earth_mars_min_ac.py``).

Leaving the Earth-Moon barycentre's orbit on 2031-08-11T12:18:59.938 and meeting Mars
(DE421 position and velocity) 657.0191 days later, the throttle free on every one of 40
segments: the a_c the sail must have for that launch and flight time.  An analyst's
script with another tool poses the same transfer, so the two answers, and the time each
takes, can be set side by side:

    esail-opt solve problems/earth_mars_min_ac_planar.py --polish

The sail's ``ac_mm_s2`` is only the seed and the scale of the a_c the optimiser finds.
It flies in the ecliptic projection (``planar=True``): the other tool's answer it is
set beside, and the release it is timed against, are of the projected transfer.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_min_ac_planar",
    description="Minimum a_c for a rendezvous with Mars (DE421), departing "
                "2031-08-11T12:18:59.938, 657.0191 days, throttle free, in the "
                "ecliptic projection",
    departure=eo.BodyDeparture(body="earth", date="2031-08-11T12:18:59.938"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=40),
    objective=eo.MinAcceleration(tof_days=657.0191),
    target=eo.BodyRendezvous(body="mars"),
    planar=True,
)
