"""The paper's Sec. 3 reproduction (Figs. 5-7, convergence) and the propagate bench:
what they write, checked against CVODES-derived bounds."""

import json

import pytest

from esail_opt import bench
from esail_opt.app import reproduce


@pytest.fixture(scope="module")
def fig7(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    written = reproduce.fig7(out)
    assert {p.name for p in written} == {"fig7.json", "fig7.png"}
    assert (out / "fig7.png").stat().st_size > 10_000
    return json.loads((out / "fig7.json").read_text())


def test_fig7_names_the_rectifications_and_marks_them(fig7):
    assert fig7["case"]["rectifications"] == 19 and fig7["case"]["arcs"] == 20
    points = fig7["rectification_points"]
    assert len(points["t_days"]) == 21  # departure, 19 rectifications, arrival
    # Six months apart on the closed form's clock (365.25 / 2 days).
    gaps = [b - a for a, b in zip(points["t_days"], points["t_days"][1:])]
    assert max(abs(g - 182.625) for g in gaps) < 1e-9


def test_fig7_errors_against_cvodes(fig7):
    errors = fig7["errors"]
    # Issue 3: below 2 % with 20 arcs (measured 1.18 %); Ref. [10] omits the
    # short-period oscillation (measured 2.26 %).
    assert errors["closed_form_max_dr_over_r0"] < 0.02
    assert errors["ref10_max_dr_over_r0"] > errors["closed_form_max_dr_over_r0"]
    # Re-sampling the arcs in theta reproduces the timed arcs' clock.
    assert errors["closed_form_clock_mismatch_tu"] < 1e-10
    # All three curves end near r = 1.64 au after 10 years.
    for curve in ("cvodes", "ref10", "closed_form"):
        assert abs(fig7[curve]["r_au"][-1] - 1.64) < 0.02


@pytest.mark.slow
def test_convergence_study(tmp_path):
    reproduce.convergence(tmp_path)
    data = json.loads((tmp_path / "convergence.json").read_text())
    arcs = data["arcs"]
    assert arcs[0] == 5 and arcs[-1] >= 640
    i20, i640 = arcs.index(20), arcs.index(640)
    for key in ("err_r_au", "err_theta_deg", "err_tof_days"):
        assert data[key][i640] < 0.1 * data[key][i20]
        # First order (measured -0.93); Richardson second order (measured -2.02).
        assert -1.1 < data["slope"][key]["plain"] < -0.85
        assert data["slope"][key]["richardson"] < -1.8


def test_bench_propagate_reports_speed_and_accuracy(tmp_path, capsys):
    path = bench.propagate.run(tmp_path, repeats=3)
    data = json.loads(path.read_text())
    for key in ("closed_form_seconds", "cvodes_seconds", "ref10_seconds",
                "ratio_cvodes_over_closed_form", "closed_form_final_err_km",
                "ref10_final_err_km"):
        assert data[key] > 0
    # The speed itself is the benchmark's to report, never a test's to assert: on a
    # shared machine a timing floor fails for reasons that are not the code's.
    # Accuracy at 10 years (measured): closed form 0.0118 au in r and 10.8 deg ahead
    # in theta, 4.6e7 km in position; Ref. [10] 0.0071 au, 1.0 deg, 4.5e6 km.
    assert 1.5e6 < data["closed_form_final_err_r_km"] < 2.0e6
    assert 4.0e7 < data["closed_form_final_err_km"] < 5.0e7
    assert 3.5e6 < data["ref10_final_err_km"] < 5.5e6
    assert "ratio CVODES / closed form" in capsys.readouterr().out
