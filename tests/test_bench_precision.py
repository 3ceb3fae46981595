"""The work-precision benchmark's pieces: the RK4 segment and the reading of its curves."""

import math

import numpy as np
import pytest

from esail_opt.bench.precision import (
    at_miss, draw_precision, envelope, precision_figure, seconds_at_miss)
from esail_opt.propagation.rk4 import rk4_segment
from esail_opt.physics import constants as units
from esail_opt.propagation.simulate import simulate


def test_rk4_segment_is_fourth_order_against_cvodes():
    # An eccentric start (e about 0.2) at 1 mm/s^2 over one radian: on a circular orbit
    # without thrust the state in theta would barely change, and any method looks exact.
    x0 = [1.0, 0.0, 0.1, 1.1]
    ac, alpha, dtheta = units.accel_from_mm_s2(1.0), math.radians(35.0), 1.0
    truth = simulate(x0, [alpha], [dtheta], ac, length_in="theta")[:, -1]
    errors = []
    for steps in (8, 16, 32):
        x1, q3 = rk4_segment(steps)(np.r_[x0, 0.0], ac, alpha, dtheta)
        assert q3.shape == (0, 1)
        errors.append(float(np.max(np.abs(np.array(x1).ravel() - truth))))
    # Measured 1.2e-6, 7.5e-8, 4.7e-9 (t included): ratios 15.7 and 15.8, far above
    # CVODES's 1e-12.
    assert errors[-1] > 1e3 * 1e-12
    for coarse, fine in zip(errors, errors[1:]):
        assert 14.0 < coarse / fine < 18.0


def test_rk4_segment_carries_time_and_theta():
    x0 = np.array([1.0, 0.3, 0.0, 1.0, 2.0])
    x1 = np.array(rk4_segment(4)(x0, 0.0, 0.0, 0.5)[0]).ravel()
    # Unthrusted circular orbit at 1 au: theta and t both advance by the angle, exactly.
    assert x1 == pytest.approx([1.0, 0.8, 0.0, 1.0, 2.5], abs=1e-14)


# Synthetic curve: (seconds, miss km).  (5, 2e6) is slower and worse than (1, 1e6), and a
# failed point has no miss; neither is on the envelope.
POINTS = [(10.0, 1e4), (1.0, 1e6), (5.0, 2e6), (2.0, None), (20.0, 1e2), (20.0, 3e2)]


def test_envelope_keeps_only_undominated_points():
    assert envelope(POINTS) == [(1.0, 1e6), (10.0, 1e4), (20.0, 1e2)]
    assert envelope([]) == []
    assert envelope([(1.0, None)]) == []


def test_seconds_at_miss_interpolates_log_log_between_brackets():
    # 1e5 is half-way between 1e6 and 1e4 in log miss: half-way between 1 s and 10 s in
    # log time, sqrt(10) s.
    assert seconds_at_miss(POINTS, 1e5) == pytest.approx(math.sqrt(10.0), rel=1e-12)
    # 1e3 is half-way between 1e4 and 1e2: sqrt(10 x 20) s.
    assert seconds_at_miss(POINTS, 1e3) == pytest.approx(math.sqrt(200.0), rel=1e-12)
    # A quarter of the way from 1e6 to 1e4 in log miss: 10^0.25 s.
    assert seconds_at_miss(POINTS, 10 ** 5.5) == pytest.approx(10 ** 0.25, rel=1e-12)
    # Exactly on a point: that point's time.
    assert seconds_at_miss(POINTS, 1e4) == pytest.approx(10.0, rel=1e-12)


def test_seconds_at_miss_never_extrapolates():
    # The fastest point already reaches the miss: its own time, not a faster guess.
    assert seconds_at_miss(POINTS, 1e6) == 1.0
    assert seconds_at_miss(POINTS, 1e7) == 1.0
    # No point reaches it.
    assert seconds_at_miss(POINTS, 10.0) is None
    assert seconds_at_miss([(1.0, None)], 1e6) is None


def test_at_miss_layout_and_ratios():
    points = ([{"method": "closed_form", "seconds": s, "miss_km": m} for s, m in POINTS]
              + [{"method": "rk4", "seconds": 0.5, "miss_km": 1e5},
                 {"method": "rk4", "seconds": 2.0, "miss_km": 1e3}])
    table = at_miss(points)
    assert list(table) == ["1e6", "1e5", "1e4"]
    assert set(table["1e5"]) == {"closed_form_seconds", "rk4_seconds", "cvodes_seconds",
                                 "ratio_rk4_over_closed_form",
                                 "ratio_cvodes_over_closed_form"}
    assert table["1e6"]["rk4_seconds"] == 0.5
    assert table["1e6"]["ratio_rk4_over_closed_form"] == 0.5
    assert table["1e5"]["ratio_rk4_over_closed_form"] == pytest.approx(0.5 / math.sqrt(10))
    # 1e4 is half-way between rk4's 1e5 and 1e3: sqrt(0.5 x 2) = 1 s.
    assert table["1e4"]["rk4_seconds"] == pytest.approx(1.0, rel=1e-12)
    assert table["1e4"]["closed_form_seconds"] == pytest.approx(10.0, rel=1e-12)
    assert table["1e4"]["cvodes_seconds"] is None
    assert table["1e4"]["ratio_cvodes_over_closed_form"] is None


def test_rk4_segment_in_the_nlp_solves_and_verifies():
    # The NLP takes a segment with an empty q3 (no q3 rows); a coarse RK4 transcription of
    # Earth-Mars at 1 mm/s^2 (10 segments x 2 steps) converges in a fraction of a second
    # and its schedule, flown by CVODES, ends 4.3e3 km from the target orbit (measured).
    from esail_opt.bench.precision import Case, rk4, run_case
    from esail_opt.optimisation.problem_file import shipped_problem

    case = run_case(Case(shipped_problem("earth_mars_min_time"), (rk4(segments=10, steps=2),)),
                    1)
    point = case["points"][0]
    assert point["status"] == "Solve_Succeeded"
    assert (point["segments"], point["steps"]) == (10, 2)
    assert 0.0 < point["miss_km"] < 2e4
    assert case["at_miss_km"]["1e5"]["rk4_seconds"] == point["seconds"]


def test_precision_figure_draws_each_case_on_its_own_axes(tmp_path):
    from matplotlib.figure import Figure

    points = ([{"method": "closed_form", "seconds": s, "miss_km": m} for s, m in POINTS]
              + [{"method": "rk4", "seconds": 0.5, "miss_km": None}])
    case = {"problem": "synthetic", "ac_mm_s2": 1.0, "points": points}
    fig = precision_figure([case, case])
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    # The closed form's envelope is one line of its 3 undominated points (POINTS holds one
    # failed point); rk4 only failed.
    ax = fig.axes[0]
    assert ax.get_xscale() == ax.get_yscale() == "log"
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert labels == ["closed_form (1 of 6 failed)", "rk4 (1 of 1 failed)"]
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert list(lines["closed_form (1 of 6 failed)"].get_xdata()) == [1.0, 10.0, 20.0]
    # Given axes are drawn on and returned; without, a new Figure's axes.
    assert draw_precision(case, ax=fig.axes[1]) is fig.axes[1]
    alone = draw_precision(case)
    assert isinstance(alone.figure, Figure) and alone.figure is not fig
    fig.savefig(tmp_path / "precision.png")
    assert (tmp_path / "precision.png").stat().st_size > 0
