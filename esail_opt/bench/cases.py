"""The benchmarks' problems, built here so that an installed package runs every bench.

Each function returns the problem of the shipped file of the same name in the
repository's ``problems/`` folder; ``tests/test_bench_cases.py`` compares them field by
field with those files, so the two cannot drift apart.
"""

import esail_opt as eo


def _circle_to_circle(name, ac_mm_s2, radius_au, segments):
    """Minimum time from the circular 1 au orbit to the circular orbit of ``radius_au``,
    worded as the shipped files word it."""
    return eo.Problem(
        name=name,
        description=(f"Minimum-time transfer, circular 1 au -> circular {radius_au:g} au, "
                     f"a_c = {ac_mm_s2:g} mm/s^2"),
        departure=eo.ParkingOrbit(a_au=1.0),
        sail=eo.Sail(ac_mm_s2=ac_mm_s2),
        segments=segments,
        objective=eo.MinTime(),
        target=eo.CircularOrbit(radius_au=radius_au),
    )


def earth_venus_min_time():
    """Earth to Venus in minimum time at 1 mm/s^2: circular 1 au -> 0.723 au, 30 free
    segments x 1 sub-arc (``problems/earth_venus_min_time.py``)."""
    return _circle_to_circle("earth_venus_min_time", 1.0, 0.723,
                             eo.Segments(count=30, sub_arcs=1, equal=False))


def earth_mars_min_time():
    """Earth to Mars in minimum time at 1 mm/s^2: circular 1 au -> 1.524 au, 60 free
    segments x 3 sub-arcs (``problems/earth_mars_min_time.py``)."""
    return _circle_to_circle("earth_mars_min_time", 1.0, 1.524,
                             eo.Segments(count=60, sub_arcs=3, equal=False))


def earth_mars_low_thrust():
    """Earth to Mars in minimum time at 0.1 mm/s^2 (about 6.5 revolutions), 16 segments
    per revolution x 1 sub-arc (``problems/earth_mars_low_thrust.py``)."""
    return _circle_to_circle("earth_mars_low_thrust", 0.1, 1.524,
                             eo.Segments(per_revolution=16, sub_arcs=1))


def orbit_raising_10yr():
    """The paper's orbit raising with free pitch: 10 years from 1 au at 0.1 mm/s^2,
    maximising the final semimajor axis, 60 segments x 2 sub-arcs
    (``problems/orbit_raising_10yr.py``)."""
    return eo.Problem(
        name="orbit_raising_10yr",
        description="Maximum final semimajor axis after 10 years from 1 au, a_c = 0.1 mm/s^2",
        departure=eo.ParkingOrbit(a_au=1.0),
        sail=eo.Sail(ac_mm_s2=0.1),
        segments=eo.Segments(count=60, sub_arcs=2),
        objective=eo.MaxEnergy(tof_days=10 * 365.25),
        target=None,
    )


def earth_venus_min_ac():
    """Earth to Venus on their real orbits, the smallest a_c for a 650-day rendezvous
    leaving on 2031-01-01, 24 equal segments x 2 sub-arcs (``problems/earth_venus_min_ac.py``)."""
    return eo.Problem(
        name="earth_venus_min_ac",
        description="Minimum a_c for a rendezvous with Venus (DE421), departing 2031-01-01, "
                    "650 days, throttle free",
        departure=eo.BodyDeparture(body="earth", date="2031-01-01"),
        sail=eo.Sail(ac_mm_s2=1.0),
        segments=eo.Segments(count=24, sub_arcs=2, equal=True),
        objective=eo.MinAcceleration(tof_days=650.0),
        target=eo.BodyRendezvous(body="venus"),
    )


#: The collocation optimum of :func:`earth_mars_low_thrust`'s transfer, the entry
#: ``earth_mars_low`` of the repository's ``tests/reference/collocation_min_time.json``
#: (written by ``python -m esail_opt.bench.collocation``; ``runtime_seconds`` is its
#: whole multistart and refinement).  ``tests/test_bench_cases.py`` checks these numbers
#: against that entry.
EARTH_MARS_LOW_REFERENCE = {
    "ac_mm_s2": 0.1,
    "rf_au": 1.524,
    "tof_days": 3329.616487062407,
    "intervals": 547,
    "intervals_fine": 1094,
    "runtime_seconds": 160.6611323940001,
}

#: The sweep bench's problem file (the sweep runs a file, whose text its workers load):
#: Earth-Mars minimum time, coarse enough that each member takes seconds.
SWEEP_SOURCE = '''
import esail_opt as eo

problem = eo.Problem(
    name="bench_sweep_earth_mars",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=20, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
)
'''
#: The sweep bench's parameter: 8 values of a_c in [0.6, 1.6] mm/s^2.
SWEEP_PARAM = "ac_mm_s2=0.6:1.6:8"
