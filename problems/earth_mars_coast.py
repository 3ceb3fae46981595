"""Earth to Mars in minimum time with a throttled sail: a_c = 2 mm/s^2, circular 1 au to
circular 1.524 au, each segment's throttle kappa in [0, 1] free.

At 2 mm/s^2 a sail that is always on cannot make this transfer faster than at 1 mm/s^2
(THEORY.md §1.4: its permanent outward thrust pushes the final state
off the Keplerian target).  With the throttle free the optimum is bang-bang: thrust,
coast for about half the transfer, thrust.  Measured (polished, exact on Eqs. 1-2,
30 equal segments x 3 sub-arcs): 461.9 d throttled, against 878.3 d for the same
segments always on and 727.6 d always on with free segment lengths.

The segments are equal in angle: with free lengths the coast segments' durations can
trade time among themselves without changing the flight, a flat direction that kept the
exact polish from converging in 200 iterations.
"""

import esail_opt as eo

problem = eo.Problem(
    name="earth_mars_coast",
    description="Minimum-time transfer with coasting, circular 1 au -> circular 1.524 au, "
                "a_c = 2 mm/s^2, throttle kappa in [0, 1] per segment",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=2.0, throttle=True),
    segments=eo.Segments(count=30, sub_arcs=3, equal=True),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
)
