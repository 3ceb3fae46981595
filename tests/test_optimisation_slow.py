"""Slow known cases of the optimiser: the shipped transfers against an independent
continuous-control optimum, and the free-pitch orbit raising against the paper's 45 deg."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

import esail_opt as eo
from esail_opt.optimisation.problem_file import load_problem
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_from_polar
from esail_opt.propagation.simulate import simulate

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
REFERENCE = REPO / "tests" / "reference" / "collocation_min_time.json"


def _low_thrust(radius):
    """The reference's low-acceleration cases (0.1 mm/s^2, 6-7 revolutions)."""
    return eo.Problem("low", eo.ParkingOrbit(1.0), eo.Sail(0.1), eo.Segments(100, 2),
                      eo.MinTime(), eo.CircularOrbit(radius))


@pytest.fixture(scope="module")
def transfers():
    solved = {name: eo.solve(load_problem(REPO / "problems" / f"{name}_min_time.py"))
              for name in ("earth_venus", "earth_mars")}
    solved["earth_venus_low"] = eo.solve(_low_thrust(0.723))
    solved["earth_mars_low"] = eo.solve(_low_thrust(1.524))
    return solved


@pytest.mark.parametrize("name, radius, target_miss_km", [
    ("earth_venus", 0.723, 1e4),
    ("earth_mars", 1.524, 3e4),
    ("earth_venus_low", 0.723, 1e4),
    ("earth_mars_low", 1.524, 3e4),
])
def test_transfer_converges_and_reaches_target(transfers, name, radius, target_miss_km):
    sol = transfers[name]
    assert sol["status"] == "Solve_Succeeded" and sol.converged
    assert sol["constraint_violation"] < 1e-9
    final = sol["final_state"]
    # On the closed form the target is met to the solver's tolerance ...
    assert final["r_au"] == pytest.approx(radius, abs=1e-9)
    assert abs(final["vr_km_s"]) < 1e-7
    assert final["vtheta_km_s"] == pytest.approx(units.speed_to_km_s(radius ** -0.5), abs=1e-7)
    # ... and flown on Eqs. 1-2 it ends within the closed form's verified error of it.
    assert sol["verification"]["target_miss_r_km"] < target_miss_km


def explained_days(sol, ref):
    """How much time the closed form's verified error can hide, days.

    Flown on Eqs. 1-2, the schedule ends off the target by dr (km) and dv (m/s) and off
    the NLP's own end by ds (km).  Closing those would take about dr / (mean radial rate
    of the transfer) + dv / (a_c r_E / R, the sail's full acceleration at the target) +
    ds / (orbital speed), plus the reference's own mesh error |tof_coarse - tof_fine|.
    Measured (this commit): Earth-Venus +0.045 d against 0.02 d explained; Earth-Mars
    +3.87 d; 0.1 mm/s^2 Earth-Venus -0.142 d (the closed form's error) against 0.20 d;
    0.1 mm/s^2 Earth-Mars +1.08 d.
    """
    v = sol["verification"]
    radius = ref["rf_au"]
    radial_rate_km_day = units.length_to_km(abs(radius - ref["r0_au"])) / sol.tof_days
    accel_m_s2 = ref["ac_mm_s2"] * 1e-3 / radius  # the sail's full acceleration there
    v_circ_km_s = units.speed_to_km_s(radius ** -0.5)
    return (v["target_miss_r_km"] / radial_rate_km_day
            + v["target_miss_v_m_s"] / accel_m_s2 / units.DAY
            + v["miss_r_km"] / v_circ_km_s / units.DAY
            + abs(ref["tof_days_coarse"] - ref["tof_days_fine"]))


@pytest.mark.parametrize("name", ["earth_venus", "earth_mars", "earth_venus_low",
                                  "earth_mars_low"])
def test_transfer_time_against_continuous_collocation_optimum(transfers, name):
    """The piecewise-constant schedule cannot beat the continuous-control optimum of the
    same transfer (direct collocation of Eqs. 1-2, esail_opt.bench.collocation) by more
    than the closed form's verified error explains (:func:`explained_days`):

        tof >= tof_collocation - explained_days

    and it must not lose by more than 1.5 %: a larger gap would mean another basin
    (more revolutions) or a schedule too coarse to be worth having.
    """
    ref = json.loads(REFERENCE.read_text())[name]
    sol = transfers[name]
    assert sol.tof_days >= ref["tof_days"] - explained_days(sol, ref)
    assert sol.tof_days <= 1.015 * ref["tof_days"]


def test_orbit_raising_beats_fixed_45_deg_on_cvodes():
    """The free-pitch 10-year orbit raising, flown on Eqs. 1-2, ends on a larger osculating
    semimajor axis than the paper's fixed 45 deg flown the same 10 years on Eqs. 1-2.

    The gain is small (about 1.2e-4 au = 18,000 km with 60 segments): near a circle,
    45 deg already maximises the energy rate, and a free pitch only adds a second-order
    term through v_r.  The test asks for 5e-5 au.
    """
    problem = load_problem(REPO / "problems" / "orbit_raising_10yr.py")
    sol = eo.solve(problem)
    assert sol.converged
    a_opt = sol["verification"]["cvodes_final_state"]["a_au"]
    tof = units.time_from_days(problem.objective.tof_days)
    fixed = simulate(problem.x0(), [math.radians(45.0)], [tof], problem.sail.ac)
    a_45 = float(classical_from_polar(fixed[:4, -1])[0])
    assert a_opt > a_45 + 5e-5
    assert sol.tof_days == pytest.approx(10 * 365.25, abs=1e-6)


def test_mercury_departure_beats_fixed_45_deg_from_the_paper_anomaly_on_cvodes():
    """From the paper's Mercury orbit (a0 = 0.308 au as printed, e0 = 0.206), the free
    pitch and free departure anomaly end the year on a larger CVODES-verified a than
    45 deg from nu0 = 0 (measured: 0.339814 against 0.339375 au)."""
    problem = load_problem(REPO / "problems" / "mercury_departure.py")
    sol = eo.solve(problem)
    assert sol.converged
    a_opt = sol["verification"]["cvodes_final_state"]["a_au"]
    tof = units.time_from_days(problem.objective.tof_days)
    fixed = simulate(problem.x0(), [math.radians(45.0)], [tof], problem.sail.ac)
    a_45 = float(classical_from_polar(fixed[:4, -1])[0])
    assert a_opt > a_45 + 2e-4
    # the NLP's own final a agrees with the CVODES flight to the closed form's error
    assert sol["final_state"]["a_au"] == pytest.approx(a_opt, abs=1e-5)


def test_rendezvous_meets_the_body():
    problem = eo.Problem("rdv", eo.ParkingOrbit(1.0), eo.Sail(1.0), eo.Segments(30, 2),
                         eo.MinTime(), eo.Rendezvous(1.2, 20.0))
    sol = eo.solve(problem)
    assert sol.converged
    final = sol["final_state"]
    t = units.time_from_days(sol.tof_days)
    body = math.degrees(math.radians(20.0) + t * 1.2 ** -1.5)
    assert math.remainder(final["theta_deg"] - body, 360.0) == pytest.approx(0.0, abs=1e-6)
    assert final["r_au"] == pytest.approx(1.2, abs=1e-9)


def test_cli_writes_a_solution_that_loads_back(tmp_path, capsys):
    from esail_opt.app import cli

    out = tmp_path / "venus"
    code = cli.main(["solve", str(REPO / "problems" / "earth_venus_min_time.py"),
                     "--segments", "12", "--out", str(out)])
    assert code == 0
    for name in ("solution.json", "schedule.csv", "trajectory.png", "timeline.png"):
        assert (out / name).stat().st_size > 0
    sol = eo.Solution.load(out / "solution.json")
    assert sol.converged and sol["status"] == "Solve_Succeeded" and sol["iterations"] > 0
    assert len(sol["schedule"]) == 12
    rows = (out / "schedule.csv").read_text().splitlines()
    assert rows[0].split(",")[:3] == ["t_days", "theta_deg", "alpha_deg"] and len(rows) == 13
    assert float(rows[-1].split(",")[2]) == pytest.approx(sol["schedule"][-1]["alpha_deg"],
                                                           rel=1e-9)
    assert sum(r["duration_days"] for r in sol["schedule"]) == pytest.approx(sol.tof_days)
    for key in ("miss_r_km", "miss_v_m_s", "miss_theta_deg", "target_miss_r_km"):
        assert np.isfinite(sol["verification"][key])
    assert "Solve_Succeeded" in str(sol)
    assert "converged" in capsys.readouterr().out
