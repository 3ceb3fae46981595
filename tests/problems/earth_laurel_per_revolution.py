"""Earth to the main-belt asteroid 2865 Laurel (inclined 14.3 deg), minimum time, in 3-D,
with a throttled 2 mm/s^2 sail and 10 segments asked per revolution.

The per-revolution count is set on the constant-pitch seed's angle, about half a turn
here, while the optimum flies well over a turn: the mesh must follow the optimum.
Laurel's elements: JPL Horizons, solution JPL#74, epoch 2018-08-29 TDB.
"""

import esail_opt as eo

LAUREL = eo.SmallBody(name="2865 Laurel", a_au=2.561338323366159, e=0.07019375927807329,
                      inclination_deg=14.29225894747608, node_deg=321.7746687674003,
                      argument_of_perihelion_deg=293.5453340658181,
                      mean_anomaly_deg=157.4596025949455, epoch="2018-08-29",
                      source="JPL Horizons, JPL#74, epoch 2018-08-29 TDB")

problem = eo.Problem(
    name="earth_laurel_per_revolution",
    departure=eo.BodyDeparture(body="earth", date="2045-01-01"),
    sail=eo.Sail(ac_mm_s2=2.0, throttle=True, throttle_min=0.3, throttle_max=0.9),
    segments=eo.Segments(per_revolution=10, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.BodyRendezvous(body=LAUREL),
    planar=False,
)
