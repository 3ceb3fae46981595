"""The polish (``--polish``): the closed-form optimum re-solved on CVODES arcs in time.

References: the verified-miss bounds of issue 6 (1 m, 1 mm/s: what CVODES at a relative
1e-12 resolves), and the independent continuous-control collocation optimum of
tests/reference/collocation_min_time.json, which a piecewise-constant exact schedule can
approach but not beat (beyond the reference's own mesh error, 2e-9 d).
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest

import esail_opt as eo
from esail_opt.optimisation import polish
from esail_opt.optimisation.verify import within
from esail_opt.optimisation.problem_file import load_problem
from esail_opt.optimisation.ipopt import solve_problem
from esail_opt.optimisation.segment_methods import CVODES
from esail_opt.optimisation.transcription import transcribe

REPO = Path(__file__).resolve().parents[1]
REFERENCE = json.loads((REPO / "tests" / "reference" / "collocation_min_time.json").read_text())
#: Slack on "cannot beat the continuous optimum": the reference's coarse and fine meshes
#: agree to 2e-9 d, so 1e-3 d only absorbs the polish's own convergence tolerance.
BEAT_SLACK_DAYS = 1e-3


def _problem(name, segments=None):
    problem = load_problem(REPO / "problems" / f"{name}_min_time.py")
    return problem if segments is None else problem.with_segments(segments)


def _assert_exact(sol):
    """The polished schedule converged and flies to within 1 m and 1 mm/s of both the
    polished NLP's final state and the target."""
    p = sol["polish"]
    assert p["converged"], p["status"]
    v = p["verification"]
    assert v["error"] is None
    assert v["miss_r_km"] < 1e-3 and v["miss_v_m_s"] < 1e-3, v
    assert v["target_miss_r_km"] < 1e-3 and v["target_miss_v_m_s"] < 1e-3, v
    assert p["verified"] and p["within_bounds_vs_nlp"] and p["within_bounds_vs_target"]
    assert p["note"].startswith("exact")


# -- fast: a coarse Earth-Venus (6 segments), polished and not


@pytest.fixture(scope="module")
def coarse_venus():
    problem = _problem("earth_venus", segments=6)
    return problem, eo.solve(problem, polish=True), eo.solve(problem)


def test_coarse_polish_flies_within_bounds(coarse_venus):
    _, sol, _ = coarse_venus
    _assert_exact(sol)
    assert sol["polish"]["iterations"] > 0 and sol["polish"]["seconds"] > 0


def test_coarse_polish_cannot_beat_the_continuous_optimum(coarse_venus):
    # 6 constant-pitch segments are a coarse control: above the continuous optimum
    # (305.105 d), never below it.
    _, sol, _ = coarse_venus
    assert sol["tof_days_exact"] >= REFERENCE["earth_venus"]["tof_days"] - BEAT_SLACK_DAYS
    assert sol["objective_exact"] == sol["polish"]["objective"]
    assert math.isclose(sol["tof_days_exact"], sol["polish"]["tof_days"], rel_tol=1e-12)


def test_polish_leaves_the_closed_form_fields_unchanged(coarse_venus):
    _, polished, plain = coarse_venus
    for key in ("objective", "tof_days", "status", "iterations", "schedule", "final_state"):
        assert polished[key] == plain[key], key
    assert polished["objective_closed_form"] == plain["objective"]
    assert "polish" not in plain.to_json() and "objective_exact" not in plain.to_json()
    assert "polished" not in plain["trajectory"]


def test_polished_schedule_is_consistent(coarse_venus):
    # The rows sum to the exact time of flight, their angles to the final theta, and the
    # polished CVODES trajectory ends where the schedule says.
    _, sol, _ = coarse_venus
    rows = sol["polish"]["schedule"]
    assert len(rows) == 6
    assert math.isclose(sum(r["duration_days"] for r in rows), sol["tof_days_exact"],
                        rel_tol=1e-12)
    assert math.isclose(sum(r["dtheta_deg"] for r in rows),
                        sol["polish"]["final_state"]["theta_deg"], rel_tol=1e-9)
    assert math.isclose(sol["trajectory"]["polished"]["t_days"][-1], sol["tof_days_exact"],
                        rel_tol=1e-12)


def test_polished_solution_writes_and_loads_back(coarse_venus, tmp_path):
    _, sol, _ = coarse_venus
    paths = sol.write(tmp_path)
    assert tmp_path / "schedule_closed_form.csv" in paths
    back = eo.Solution.load(tmp_path / "solution.json")
    assert back["polish"]["verified"] and back["tof_days_exact"] == sol["tof_days_exact"]
    lines = (tmp_path / "schedule.csv").read_text().splitlines()
    assert len(lines) == 7 and float(lines[1].split(",")[3]) > 0
    # The file holds the verified schedule to the digit: flown from it, it is the same
    # flight (10 significant digits put a 2500-day polished spiral 3.5 m off).
    header = lines[0].split(",")
    for line, row in zip(lines[1:], back["polish"]["schedule"]):
        assert {k: float(v) for k, v in zip(header, line.split(","))} == row
    assert "polish: exact" in back.summary()


def test_warm_start_satisfies_continuity_and_drops_q3():
    # Nodes from the CVODES flight of the closed-form schedule: every continuity row of the
    # time NLP holds at the start (to CVODES round-off), only the target is missed; and
    # the exact NLP has no q3 rows.
    problem = _problem("earth_venus", segments=4)
    result, tr = solve_problem(problem)
    guess = polish.exact_guess(problem, result.x_start, result.as_guess(durations=True))
    exact = transcribe(problem, CVODES(in_time=True), guess)
    assert "q3" not in exact.names and "q3" in tr.names
    g = exact.constraints(exact.x0)
    assert np.max(np.abs(g[: exact.names["continuity"]])) < 1e-9
    np.testing.assert_allclose(guess.lengths, result.durations)


def test_cvodes_segments_refuse_a_problem_in_three_dimensions():
    from esail_opt.optimisation.problem_file import shipped_problem

    with pytest.raises(ValueError, match="Eqs. 1-2 only"):
        transcribe(shipped_problem("earth_mars_2035"), CVODES(in_time=True))


@pytest.mark.parametrize("miss, ok", [
    ({"position_m": 0.2, "velocity_mm_s": 0.01}, True),
    ({"position_m": 1.5, "velocity_mm_s": 0.01}, False),
    ({"position_m": 0.2, "velocity_mm_s": 2.0}, False),
    ({"position_m": 0.2, "velocity_mm_s": None}, True),  # an (a, e) target: no velocity miss
    ({"position_m": None, "velocity_mm_s": None}, False),  # no flight: never within
    ({"position_m": float("nan"), "velocity_mm_s": 0.0}, False),
])
def test_polish_bounds(miss, ok):
    def km(metres):
        return None if metres is None else metres / 1e3

    misses = {"target_miss_r_km": km(miss["position_m"]),
              "target_miss_v_m_s": km(miss["velocity_mm_s"]),
              "verifier_error_r_km": 0.0, "verifier_error_v_m_s": 0.0}
    assert within(misses, polish.TOLERANCE) is ok


# -- slow: the shipped transfers at 1 mm/s^2 against the collocation optimum


@pytest.mark.slow
@pytest.mark.parametrize("name, segments", [("earth_venus", 30), ("earth_mars", 60)])
def test_shipped_transfer_polished_is_exact_and_near_collocation(name, segments):
    sol = eo.solve(_problem(name), polish=True)
    assert sol["problem"]["segments"] == segments
    _assert_exact(sol)
    reference = REFERENCE[name]["tof_days"]
    tof = sol["tof_days_exact"]
    assert abs(tof - reference) < 0.01 * reference
    assert tof >= reference - BEAT_SLACK_DAYS


@pytest.mark.slow
@pytest.mark.parametrize("name, reference_key, segments", [
    ("earth_venus_low_thrust", "earth_venus_low", 111),
    ("earth_mars_low_thrust", "earth_mars_low", 100),
])
def test_low_thrust_transfer_polished_within_0_3_percent(name, reference_key, segments):
    """Issue 5: polished multi-revolution spirals at 0.1 mm/s^2 land within 0.3 % of the
    collocation optimum (measured: +0.003 % Venus, +0.048 % Mars) and cannot beat it."""
    sol = eo.solve(load_problem(REPO / "problems" / f"{name}.py"), polish=True)
    assert sol["problem"]["segments"] == segments
    _assert_exact(sol)
    reference = REFERENCE[reference_key]["tof_days"]
    tof = sol["tof_days_exact"]
    assert abs(tof - reference) < 0.003 * reference
    assert tof >= reference - BEAT_SLACK_DAYS


def test_polish_steps_are_the_fewest_whose_defects_are_small():
    # Four long segments (about 1.3 rad each): 4 RK4 steps are far from Eqs. 1-2 there,
    # so the polish must take more.  Each count's defects are judged here by CVODES
    # flights from every node (error_control.segment_ends), not by the polish's own flight.
    from types import SimpleNamespace

    from esail_opt.optimisation.error_control import segment_ends
    from esail_opt.optimisation.segment_methods import RK4

    problem = _problem("earth_venus", segments=4)
    result, _ = solve_problem(problem)
    start = polish.exact_guess(problem, result.x_start,
                                         result.as_guess(durations=True))
    chain = SimpleNamespace(alpha=start.alpha, throttle=start.throttle, x_start=result.x_start,
                            durations=start.lengths, nodes=start.nodes, ac_scale=1.0)
    worst = {}
    for count in polish.RK4_STEPS:
        flown, model = segment_ends(problem, chain, RK4(count, in_time=True))
        worst[count] = float(np.max(np.abs(flown - model)[:4]))
    chosen = polish.rk4_polish_method(problem, result.x_start, start)
    assert chosen.in_time
    count = chosen.steps
    steps = list(polish.RK4_STEPS)
    assert worst[steps[0]] > polish.STEP_DEFECT, worst
    assert count > steps[0] and worst[count] < polish.STEP_DEFECT, (count, worst)
    assert worst[steps[steps.index(count) - 1]] >= polish.STEP_DEFECT, (count, worst)


def test_a_polish_that_fails_leaves_the_closed_form_verdict_standing(tmp_path, monkeypatch,
                                                                     capsys):
    """A polish not verified makes the run exit 1, and its line also gives the
    closed-form answer's verdict, which stands: an analyst must not read the failure of
    a 1 m polish as the failure of the transfer."""
    from esail_opt.app import cli, solution

    data = json.loads((REPO / "results" / "earth_mars_min_time_polished"
                       / "solution.json").read_text())
    data["polish"]["verified"] = False
    data["polish"]["note"] = "NOT verified: the verifier's own error alone reaches the bound"
    monkeypatch.setattr(solution, "solve_with_nearest",
                        lambda *args, **kwargs: (solution.Solution.from_json(data), None))
    code = cli.main(["solve", str(REPO / "problems" / "earth_mars_min_time.py"), "--polish",
                     "--no-plots", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.splitlines()[-1]
    assert code == 1
    assert err == ("esail-opt solve: polish NOT verified: the verifier's own error alone "
                   "reaches the bound; the closed-form answer stays "
                   + data["verification_note"])
    assert data["verification_note"].startswith("verified: ")
