"""No target: the most orbital energy after 300 days at 0.5 mm/s^2 from 1 au, on 8
segments of 2 sub-arcs; the flight must end where the NLP says it does."""

import esail_opt as eo

problem = eo.Problem(
    name="max_energy_one_year",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=0.5),
    segments=eo.Segments(count=8, sub_arcs=2),
    objective=eo.MaxEnergy(tof_days=300.0),
)
