"""Earth to Mercury in three dimensions: the smallest a_c for a fixed launch and flight.

A test problem of the porkchop's 3-D cells: warm from the cell 40 days shorter, the
2039-12-01 / 720 d cell kept to a poorer basin of its turn count than a lone solve
finds (0.8555 against 0.8162 mm/s^2).
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mercury_min_ac_3d",
    description="Minimum a_c for a rendezvous with Mercury (DE421), 3-D, 700 d from "
                "2040-01-01",
    departure=eo.BodyDeparture(body="earth", date="2040-01-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=50, sub_arcs=2, equal=True),
    objective=eo.MinAcceleration(tof_days=700.0),
    target=eo.BodyRendezvous(body="mercury"),
)
