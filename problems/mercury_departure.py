"""Leaving the paper's Mercury orbit (Fig. 4) as fast as the sail allows: from the elliptic
parking orbit a0 = 0.308 au, e0 = 0.206, maximise the osculating semimajor axis after one
year at a_c = 0.1 mm/s^2, with the departure point on the parking orbit left free.

a0 = 0.308 au is the value the paper prints; Mercury's real semimajor axis is 0.387 au
(0.308 au is nearly its perihelion radius).  We use the printed value, as the paper's
Fig. 4 does (THEORY.md §6.5).  The paper's nu0 = 0 is the initial guess of the free
departure anomaly.
"""

import esail_opt as eo

problem = eo.Problem(
    name="mercury_departure",
    description="Maximum a after 1 year from the printed Mercury orbit (a0 = 0.308 au, "
    "e0 = 0.206), a_c = 0.1 mm/s^2, free departure anomaly",
    departure=eo.ParkingOrbit(a_au=0.308, e=0.206, nu_deg=0.0, free_anomaly=True),
    sail=eo.Sail(ac_mm_s2=0.1),
    segments=eo.Segments(count=60, sub_arcs=2),
    objective=eo.MaxEnergy(tof_days=365.25),
    target=None,
)
