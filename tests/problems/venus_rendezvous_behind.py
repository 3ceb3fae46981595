"""Rendezvous with Venus at 1 mm/s^2, the planet 30 deg behind the sail at departure,
on 40 segments of 3 sub-arcs (one start of Ipopt reported it infeasible)."""

import esail_opt as eo

problem = eo.Problem(
    name="venus_rendezvous_behind",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=40, sub_arcs=3),
    objective=eo.MinTime(),
    target=eo.Rendezvous(radius_au=0.723, phase_deg=-30.0),
)
