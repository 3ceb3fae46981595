"""Earth to Mars on their real orbits, minimum time, leaving on 2035-07-15.

a_c = 1 mm/s^2, a rendezvous with Mars (its DE421 position and velocity at arrival),
departing from the Earth-Moon barycentre's orbit with no excess speed, in three
dimensions (a real body's default), the problem as an analyst first writes it: everything else at its default.  Its fastest transfer is not in
the turn count that a constant-pitch seed winds, so ``esail-opt solve`` looks at the
turn counts around the seed's and keeps the best verified one.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_2035",
    description="Minimum-time rendezvous with Mars (DE421), departing 2035-07-15, "
                "a_c = 1 mm/s^2",
    departure=eo.BodyDeparture(body="earth", date="2035-07-15"),
    sail=eo.Sail(ac_mm_s2=1.0),
    objective=eo.MinTime(),
    target=eo.BodyRendezvous(body="mars"),
)
