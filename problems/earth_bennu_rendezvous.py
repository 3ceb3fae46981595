"""Earth to the near-Earth asteroid (101955) Bennu, rendezvous in minimum time.

a_c = 1 mm/s^2, leaving the Earth-Moon barycentre's orbit on 2031-03-01 (TDB) with no
excess speed.  Bennu flies on its JPL osculating elements (``eo.BENNU`` names their
source), on Keplerian motion from all six of them; its orbit is inclined 6 deg to the
ecliptic, and the transfer flies in three dimensions to meet it (``planar=True`` would
drop the inclination, and ``solution.json`` would report how far out of the plane Bennu
is at the arrival, ``target_body.out_of_plane_km``).
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_bennu_rendezvous",
    description="Minimum-time rendezvous with (101955) Bennu, a_c = 1 mm/s^2, departing "
                "2031-03-01",
    departure=eo.BodyDeparture(body="earth", date="2031-03-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=30, sub_arcs=3, equal=False),
    objective=eo.MinTime(),
    target=eo.BodyRendezvous(body=eo.BENNU),
)
