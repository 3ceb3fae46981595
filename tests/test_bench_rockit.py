"""The rockit baseline of ``esail-opt-bench rockit`` (``esail_opt.bench.rockit_baseline``).

References: the independent continuous-pitch collocation optimum of Earth-Mars at
1 mm/s^2 (tests/reference/collocation_min_time.json), which a schedule of 60
constant-pitch intervals approaches from above; and the schedule flown on Eqs. 1-2 by
scipy's DOP853 written out in the tests (``conftest.fly_dop853``).  Without rockit the
solving tests are skipped, and the bench must say so in one line.
"""

import json
import math
import sys
from pathlib import Path

import pytest

from conftest import fly_dop853, independent_target_miss
from esail_opt.bench import cli, rockit_baseline
from esail_opt.optimisation.problem_file import shipped_problem
from esail_opt.physics import constants as units

REPO = Path(__file__).resolve().parents[1]
REFERENCE = json.loads((REPO / "tests" / "reference" / "collocation_min_time.json")
                       .read_text())["earth_mars"]["tof_days"]
#: 60 constant-pitch intervals cost O(1/N^2) of time against a continuous pitch; 0.1 %
#: (0.58 d) is the bench's own agreement bound of 0.5 % made five times tighter.
TOF_BOUND = 1e-3
#: DOP853 at rtol 1e-13 against CVODES at the verifier's tolerance: metres apart on these
#: flights (``propagation.simulate``'s note on VERIFY_TOLERANCE), so 50 m.
INTEGRATORS_KM = 0.05


@pytest.fixture(scope="module")
def solved():
    pytest.importorskip("rockit")
    problem = shipped_problem(rockit_baseline.PROBLEM)
    return problem, rockit_baseline.solve(problem)


def test_rockit_optimum_agrees_with_the_collocation_reference(solved):
    _, record = solved
    assert record["status"] == "Solve_Succeeded"
    assert abs(record["tof_days"] / REFERENCE - 1.0) < TOF_BOUND


def test_rockit_schedule_flies_to_the_target_on_an_independent_integrator(solved):
    problem, record = solved
    days = units.time_to_days(record["duration_tu"])
    schedule = [{"alpha_deg": math.degrees(a), "duration_days": days}
                for a in record["alpha_rad"]]
    x, t = fly_dop853(problem, schedule)
    position_km, velocity_m_s = independent_target_miss(problem, x, t)
    assert position_km < problem.tolerance.position_km
    assert velocity_m_s < problem.tolerance.velocity_m_s
    assert abs(rockit_baseline.fly(problem, record)["target_miss_r_km"] - position_km) \
        < INTEGRATORS_KM


def test_without_rockit_the_bench_says_so_in_one_line_and_exits_2(monkeypatch, tmp_path,
                                                                    capsys):
    # A None entry in sys.modules is how Python marks a module that cannot be imported.
    monkeypatch.setitem(sys.modules, "rockit", None)
    assert cli.main(["rockit", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rockit" in err[0]
    assert not (tmp_path / "rockit.json").exists()
