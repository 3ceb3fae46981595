"""Earth to Mars rendezvous in minimum time: a_c = 1 mm/s^2, from a circular 1 au orbit to
Mars itself on a circular 1.524 au orbit, Mars 44 deg ahead at departure.

Unlike the orbit transfer (``earth_mars_min_time.py``), the arrival angle is tied to Mars,
so the transfers that gain k whole turns on Mars before meeting it are separate local
optima: ``esail-opt search`` solves one per k and ranks them.  44 deg is Mars's lead for
a Hohmann transfer (an E-sail at 1 mm/s^2 is slower than that, hence the search).
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_rendezvous",
    description="Minimum-time rendezvous, circular 1 au -> Mars at 1.524 au, 44 deg ahead, "
                "a_c = 1 mm/s^2",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=60, sub_arcs=2, equal=False),
    objective=eo.MinTime(),
    target=eo.Rendezvous(radius_au=1.524, phase_deg=44.0),
)
