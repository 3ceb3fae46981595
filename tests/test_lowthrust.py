"""Low-performance multi-revolution transfers (a_c = 0.1 mm/s^2): segments given per
revolution, the shipped low-thrust problems against the collocation reference, and the
5-year spiral against the best constant pitch.

The fast tests check the per-revolution rule itself; the slow ones solve the shipped
files (a few seconds each) and fly the results on Eqs. 1-2 with CVODES.
"""

import json
import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import esail_opt as eo
from conftest import PROBLEMS, REPO
from esail_opt.errors import InputError
from esail_opt.optimisation import error_control
from esail_opt.optimisation.problem_file import load_problem
from esail_opt.optimisation.seed import initial_guess
from esail_opt.physics import constants as units
from esail_opt.propagation.simulate import simulate

REFERENCE = REPO / "tests" / "reference" / "collocation_min_time.json"

#: Shipped file -> (collocation reference case, N that 16 segments per revolution give).
#: The counts follow from the seeding propagation's sweep (+-45 deg, to the target
#: radius or for 5 years): 6.21, 6.90 and 4.05 revolutions.
SHIPPED = {
    "earth_mars_low_thrust": ("earth_mars_low", 100),
    "earth_venus_low_thrust": ("earth_venus_low", 111),
    "spiral_out_5au": (None, 65),
}


def _shipped(name):
    return load_problem(PROBLEMS / f"{name}.py")


# ---------------------------------------------------------------- the per-revolution rule


@pytest.mark.parametrize("value", [0, -3, 2.5, True, "8", float("nan")])
def test_per_revolution_out_of_range_names_the_field_and_range(value):
    with pytest.raises(InputError, match=r"^segments\.per_revolution = .* "
                                         r"(is outside|is not an integer in) \[1, inf\)$"):
        eo.Segments(per_revolution=value)


def test_per_revolution_and_count_are_exclusive():
    with pytest.raises(InputError, match="segments.count = 10 and segments.per_revolution = 8"):
        eo.Segments(count=10, per_revolution=8)
    # The plain default is unchanged.
    assert eo.Segments().count == 20 and eo.Segments().per_revolution is None


def test_bad_per_revolution_in_a_problem_file_fails_before_any_solve(tmp_path):
    path = tmp_path / "bad.py"
    path.write_text("import esail_opt as eo\n"
                    "problem = eo.Problem('bad', eo.ParkingOrbit(1.0), eo.Sail(0.1),\n"
                    "    eo.Segments(per_revolution=0), eo.MinTime(), eo.CircularOrbit(1.5))\n")
    with pytest.raises(InputError, match=r"bad\.py: segments\.per_revolution = 0 is outside "
                                         r"\[1, inf\)"):
        load_problem(path)


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_count_is_ceil_of_k_times_the_seed_sweep(name):
    """N = ceil(K sweep / 2 pi), with sweep the seed's total angle; no count in the file."""
    problem = _shipped(name)
    k = problem.segments.per_revolution
    assert problem.segments.count is None and k == 16
    guess = initial_guess(problem)
    sweep = float(np.sum(guess.lengths))
    n = guess.alpha.size
    assert n == SHIPPED[name][1]
    assert n - 1 < k * sweep / (2 * math.pi) <= n
    # Equal segments that tile the sweep, and nodes the NLP's own segments reach.
    assert np.allclose(guess.lengths, sweep / n, rtol=1e-12)
    assert guess.nodes.shape == (5, n)


def test_solution_records_the_resolved_count_and_the_override_replaces_the_rule():
    """A short high-thrust hop (1 -> 1.3 au at 1 mm/s^2) keeps this fast: 12 per
    revolution give the seed's 0.3 of a turn 4 segments, and the optimum, which flies
    about three quarters of a turn, is solved again on enough for 12 a turn of its own;
    the record gives the count solved."""
    problem = eo.Problem("hop", eo.ParkingOrbit(1.0), eo.Sail(1.0),
                         eo.Segments(per_revolution=12, sub_arcs=2), eo.MinTime(),
                         eo.CircularOrbit(1.3))
    guess = initial_guess(problem)
    n = guess.alpha.size
    assert n == math.ceil(12 * float(np.sum(guess.lengths)) / (2 * math.pi)) == 4
    sol = eo.solve(problem)
    assert sol.converged
    count = sol["problem"]["segments"]
    assert count == len(sol["schedule"]) > n
    turns = sum(row["dtheta_deg"] for row in sol["schedule"]) / 360
    assert count >= 12 * turns / error_control.DENSITY_SLACK
    assert sol["problem"]["segments_per_revolution"] == 12
    # --segments (here the API's segments=) replaces the rule, and the record says so.
    fixed = eo.solve(problem, segments=6)
    assert fixed["problem"]["segments"] == 6 == len(fixed["schedule"])
    assert fixed["problem"]["segments_per_revolution"] is None


# ---------------------------------------------------------------- shipped transfers


@pytest.fixture(scope="module")
def transfers():
    return {name: eo.solve(_shipped(name))
            for name in ("earth_mars_low_thrust", "earth_venus_low_thrust")}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["earth_mars_low_thrust", "earth_venus_low_thrust"])
def test_low_thrust_transfer_within_1_percent_of_collocation(transfers, name):
    """Converged from the shipped file alone (100 and 111 segments x 2 sub-arcs), and
    the time of flight of the schedule flown on Eqs. 1-2 is within 1 % of the
    continuous-pitch collocation optimum.  Measured: Earth-Mars 3330.698 d against
    3329.616 d (+0.033 %), Earth-Venus 2067.698 d against 2067.815 d (-0.006 %); flown,
    they end 11,600 km / 0.78 m/s and 2,000 km / 0.35 m/s off the target orbit.
    """
    case, count = SHIPPED[name]
    ref = json.loads(REFERENCE.read_text())[case]
    sol = transfers[name]
    assert sol["status"] == "Solve_Succeeded" and sol.converged
    assert sol["problem"]["segments"] == count
    v = sol["verification"]
    assert v["error"] is None
    assert v["cvodes_tof_days"] == pytest.approx(ref["tof_days"], rel=0.01)
    # Tighter than the issue asks: what the shipped resolution actually achieves.
    assert v["cvodes_tof_days"] == pytest.approx(ref["tof_days"], rel=1e-3)
    # Same basin as the reference: the same number of revolutions.
    revs = math.radians(sol["final_state"]["theta_deg"]) / (2 * math.pi)
    assert revs == pytest.approx(ref["revolutions"], abs=0.05)
    # The flight really ends on the target orbit, to the closed form's verified error.
    assert v["target_miss_r_km"] < 2e4 and v["target_miss_v_m_s"] < 1.5


# ---------------------------------------------------------------- 5-year spiral


def best_constant_pitch(problem):
    """The constant pitch that maximises r after the problem's time of flight, flown with
    CVODES on Eqs. 1-2: a 1-deg grid over [-90, 90] deg (r(alpha) has one hump, but the
    grid guards against a second), then Brent's method in the best cell.

    Returns (alpha_deg, r_au).
    """
    tof = units.time_from_days(problem.objective.tof_days)

    def final_r(deg):
        return float(simulate(problem.x0(), [math.radians(deg)], [tof], problem.sail.ac)[0, -1])

    grid = np.arange(-90.0, 90.5, 1.0)
    values = np.array([final_r(a) for a in grid])
    i = int(np.argmax(values))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    found = minimize_scalar(lambda a: -final_r(a), bounds=(lo, hi), method="bounded",
                            options={"xatol": 1e-4})
    return float(found.x), max(-float(found.fun), float(values[i]))


@pytest.mark.slow
def test_spiral_free_pitch_beats_best_constant_pitch_on_cvodes():
    """Free pitch (65 segments x 2 sub-arcs), flown on Eqs. 1-2, ends 5 years out at a
    larger radius than the best constant pitch flown the same 5 years.

    Measured: 1.33905 au free against 1.28775 au at the best constant pitch (44.6 deg):
    the free schedule ends near an aphelion of an orbit it has made eccentric (e = 0.15),
    which no constant pitch can aim for.  The test asks for 0.04 au.
    """
    problem = _shipped("spiral_out_5au")
    alpha, r_const = best_constant_pitch(problem)
    assert 40.0 < alpha < 50.0 and 1.28 < r_const < 1.30
    sol = eo.solve(problem)
    assert sol.converged and sol["problem"]["segments"] == SHIPPED["spiral_out_5au"][1]
    v = sol["verification"]
    assert v["cvodes_tof_days"] == pytest.approx(5 * 365.25, abs=1e-6)
    r_free = v["cvodes_final_state"]["r_au"]
    assert r_free > r_const + 0.04
    # The NLP's own final radius agrees with the flight to the closed form's error.
    assert sol["final_state"]["r_au"] == pytest.approx(r_free, abs=1e-4)
