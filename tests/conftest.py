"""Helpers shared by the tests: where things are, a problem file that solves in a second,
and a second integrator.

The package verifies every schedule with CVODES; a test that wants to know whether a
claimed miss is true flies the schedule again here with scipy's DOP853, an integrator
that shares no code with the package (Eqs. 1-2 are written out again below).
"""

import math
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from esail_opt.physics import constants as units

REPO = Path(__file__).resolve().parents[1]
PROBLEMS = REPO / "problems"
USER_PROBLEMS = Path(__file__).resolve().parent / "problems"
RESULTS = REPO / "results"


#: A problem file that solves in a second or two (Earth-Mars on 6 segments, held to a
#: loose tolerance): for tests of what happens around a solve, not of its numbers.
TINY_PROBLEM = '''
import esail_opt as eo

problem = eo.Problem(
    name={name!r},
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=6, sub_arcs=1),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
    tolerance=eo.Tolerance(position_km=1e8, velocity_m_s=1e5),
)
'''


def fly_dop853(problem, schedule, rtol=1e-13, x0=None, ac=None):
    """Fly a schedule (solution.json rows: ``alpha_deg``, ``duration_days`` and maybe
    ``throttle``) on Eqs. 1-2 with DOP853, from ``x0`` (polar, canonical; default the
    problem's departure) at the characteristic acceleration ``ac`` (canonical; default
    the sail's).

    Returns the final polar state [r, theta, v_r, v_theta] and the elapsed time, TU.
    """
    b1, b2 = problem.sail.coefficients
    ac = problem.sail.ac if ac is None else ac
    x = np.asarray(problem.x0() if x0 is None else x0, float)
    elapsed = 0.0
    for row in schedule:
        alpha = math.radians(row["alpha_deg"])
        kappa = row.get("throttle", 1.0)
        radial = b1 + b2 * math.cos(2 * alpha)
        transverse = b2 * math.sin(2 * alpha)
        duration = units.time_from_days(row["duration_days"])

        def rhs(_t, y, radial=radial, transverse=transverse, kappa=kappa):
            r, _th, vr, vt = y
            push = kappa * ac / r
            return [vr, vt / r, vt * vt / r - 1 / r**2 + push * radial,
                    -vr * vt / r + push * transverse]

        x = solve_ivp(rhs, (0.0, duration), x, method="DOP853", rtol=rtol,
                      atol=rtol * 1e-2).y[:, -1]
        elapsed += duration
    return x, elapsed


def position_km(x, y):
    """Distance between two polar states, km."""
    dx = x[0] * math.cos(x[1]) - y[0] * math.cos(y[1])
    dy = x[0] * math.sin(x[1]) - y[0] * math.sin(y[1])
    return units.length_to_km(math.hypot(dx, dy))


def velocity_m_s(x, y):
    """Difference of the velocities of two polar states, m/s."""
    def cart(z):
        c, s = math.cos(z[1]), math.sin(z[1])
        return np.array([z[2] * c - z[3] * s, z[2] * s + z[3] * c])

    return 1e3 * units.speed_to_km_s(float(np.linalg.norm(cart(x) - cart(y))))


def independent_target_miss(problem, x, t):
    """Miss of polar state ``x`` at time ``t`` (TU) from the problem's target, written
    here from the definitions: (position km, velocity m/s or None).

    Circular orbit: |r - R| and the velocity error against (0, sqrt(1/R)); (a, e) orbit:
    max(|a - a*|, a* |e - e*|) in km from energy and angular momentum, no velocity;
    rendezvous: distance and relative speed to the body at phase + n t.
    """
    r, th, vr, vt = (float(v) for v in x)
    target = problem.target
    if hasattr(target, "phase_deg"):
        radius = target.radius_au
        body = (radius, math.radians(target.phase_deg) + t * radius ** -1.5, 0.0, radius ** -0.5)
        return position_km(x, body), velocity_m_s(x, body)
    if hasattr(target, "radius_au"):
        radius = target.radius_au
        dv = math.hypot(vr, vt - radius ** -0.5)
        return units.length_to_km(abs(r - radius)), 1e3 * units.speed_to_km_s(dv)
    energy = 0.5 * (vr**2 + vt**2) - 1 / r
    a = -0.5 / energy
    e = math.sqrt(max(0.0, 1 + 2 * energy * (r * vt) ** 2))
    return units.length_to_km(max(abs(a - target.a_au), target.a_au * abs(e - target.e))), None


def polar_of(state):
    """A solution.json state (r_au, theta_deg, vr_km_s, vtheta_km_s) in canonical units."""
    return [state["r_au"], math.radians(state["theta_deg"]),
            units.speed_from_km_s(state["vr_km_s"]), units.speed_from_km_s(state["vtheta_km_s"])]


def solved_under(monkeypatch, variable, values, problem):
    """``problem`` solved once with the environment ``variable`` set to each of
    ``values``: {value: NLPResult}, for checks that a switch leaves the optimum alone."""
    from esail_opt.optimisation.ipopt import solve_problem

    results = {}
    for value in values:
        monkeypatch.setenv(variable, value)
        results[value] = solve_problem(problem)[0]
    return results
