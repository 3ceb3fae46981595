"""Earth to Mars on their real orbits, minimum time, leaving between 2030 and 2033.

a_c = 1 mm/s^2, a rendezvous with Mars (its DE421 position and velocity at arrival),
departing from the Earth-Moon barycentre's orbit with no excess speed, in three
dimensions: between DE421's unprojected states, with a pitch and a clock angle per
segment, so that the sail climbs 1.85 deg out of Earth's plane to meet Mars in its own
(``earth_mars_window_planar.py`` is the ecliptic projection, for comparison).  The departure
date is free in the window: ``esail-opt solve`` seeds it by a coarse scan of the window
and then lets the optimiser move it.  ``esail-opt porkchop problems/earth_mars_window.py
--depart 2030-01-01:2033-01-01:25`` shows how the time of flight changes with the date
instead (the problem's own date is replaced by each of the scan's).
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_window",
    description="Minimum-time rendezvous with Mars (DE421), a_c = 1 mm/s^2, departure "
                "free in 2030-2033",
    departure=eo.BodyDeparture(body="earth", window=("2030-01-01", "2033-01-01")),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=40, sub_arcs=3, equal=False),
    objective=eo.MinTime(),
    target=eo.BodyRendezvous(body="mars"),
)
