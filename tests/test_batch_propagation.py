"""Many fixed-attitude cases in one call: the batch against the single-case propagator and
an independent integration, `esail-opt propagate` with ranges, and the bench's batch block."""

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from esail_opt.app.cli import main
from esail_opt.app.propagate import GRID_COLUMNS
from esail_opt.bench import propagate as bench
from esail_opt.physics import constants as units
from esail_opt.propagation.arcs import FIRST_ORDER, PANEL_NODES, ArcModel
from esail_opt.propagation.batch import arcs_at_angles, propagate_batch
from esail_opt.propagation.fixed_attitude import FixedAttitudeCase, eps_over_swept_angle
from esail_opt.propagation.rectified import propagate


def _cases(m, n, seed):
    """m random starts near 1 au, with n segments each of pitch, length and a_c."""
    rng = np.random.default_rng(seed)
    r0 = rng.uniform(0.8, 1.3, m)
    x0 = np.column_stack([r0, rng.uniform(-1, 1, m), rng.uniform(-0.05, 0.05, m),
                          r0**-0.5 * rng.uniform(0.95, 1.05, m)])
    return (x0, rng.uniform(-1.2, 1.2, (m, n)), rng.uniform(0.3, 2.5, (m, n)),
            units.accel_from_mm_s2(rng.uniform(0.02, 0.3, m)))


@pytest.mark.parametrize("options", [
    {"model": FIRST_ORDER},
    {"samples": 3, "model": FIRST_ORDER},
    {"length_in": "time", "model": ArcModel(sub_arcs=1, nodes=PANEL_NODES)},
    {"length_in": "time", "samples": 2, "model": FIRST_ORDER},
    {"samples": 2},
])
def test_batch_equals_the_single_case_propagator_case_by_case(options):
    x0, alphas, lengths, ac = _cases(6, 4, seed=3)
    throttles = np.linspace(0.2, 1.0, 4)
    xs, q3 = propagate_batch(x0, alphas, lengths, ac, throttles=throttles, **options)
    arcs = 4 * options.get("model", ArcModel()).sub_arcs
    assert xs.shape == (6, 5, arcs * options.get("samples", 1) + 1) and q3.shape == (6, arcs)
    for m in range(6):
        one, q3_one = propagate(x0[m], alphas[m], lengths[m], ac[m], throttles=throttles,
                                **options)
        # The same Function on the same numbers: equal to rounding.
        np.testing.assert_allclose(xs[m], one, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(q3[m], q3_one, rtol=1e-13, atol=1e-14)


def test_arcs_at_angles_of_different_counts_equal_one_arc_each():
    x0, alphas, _, ac = _cases(5, 1, seed=4)
    counts, span = [3, 8, 1, 5, 8], 2.7
    angles = [span * (np.arange(n + 1) / n) for n in counts]
    arcs = arcs_at_angles(x0, ac, alphas[:, 0], angles)
    for m, (xs, q3) in enumerate(arcs):
        one, q3_one = propagate(x0[m], alphas[m], [span], ac[m], samples=counts[m],
                                model=FIRST_ORDER)
        assert xs.shape == one.shape and q3.shape == (counts[m],)
        np.testing.assert_allclose(xs, one, rtol=1e-13, atol=1e-14)
        assert q3[-1] == pytest.approx(q3_one[-1], rel=1e-13)


def _eqs_1_2(ac, alpha):
    """Eqs. 1-2 in polar form, canonical units (mu = 1, r_E = 1), written out for scipy,
    with R, T of Eqs. 3-4 at b1 = 3/4, b2 = 1/4."""
    R, T = 0.75 + 0.25 * math.cos(2 * alpha), 0.25 * math.sin(2 * alpha)

    def f(_t, y):
        r, _th, vr, vt = y
        return [vr, vt / r, vt**2 / r - 1 / r**2 + ac * R / r, -vr * vt / r + ac * T / r]

    return f


def test_batched_second_order_arcs_against_dop853():
    """One year in 20 arcs of equal duration, four pitches and accelerations, one call.
    The second-order arcs' error is O(a~_c^2) relative per arc (THEORY.md); the bound
    is a~_c^2 r0 at the largest a_c flown (3e-4 au here), the final error over all arcs."""
    alphas_deg, acs_mm = np.array([45.0, -30.0, 0.0, 70.0]), np.array([0.1, 0.05, 0.1, 0.08])
    acs = units.accel_from_mm_s2(acs_mm)
    horizon, arcs = units.time_from_years(1.0), 20
    x0 = [1.0, 0.0, 0.0, 1.0]
    xs, q3 = propagate_batch(x0, np.repeat(np.radians(alphas_deg)[:, None], arcs, 1),
                             np.full((4, arcs), horizon / arcs), acs, length_in="time",
                             model=ArcModel(sub_arcs=1, nodes=PANEL_NODES))
    assert np.all(q3 > 0)
    bound = acs.max() ** 2
    for m in range(4):
        end = solve_ivp(_eqs_1_2(acs[m], math.radians(alphas_deg[m])), (0, horizon), x0,
                        method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
        got = xs[m, :, -1]
        assert got[4] == pytest.approx(horizon, rel=1e-12)
        gap = math.hypot(got[0] * math.cos(got[1]) - end[0] * math.cos(end[1]),
                         got[0] * math.sin(got[1]) - end[0] * math.sin(end[1]))
        assert gap < bound


def test_batched_paper_arc_within_the_papers_eps_against_dop853():
    """The paper's single first-order arc over two years: Fig. 3 puts eps (Eq. 27) below
    4 % for a_c <= 0.1 mm/s^2 from the circular orbit at 1 au."""
    alphas = np.radians([45.0, -45.0, 20.0])
    acs = units.accel_from_mm_s2(np.array([0.1, 0.1, 0.05]))
    span = 4 * math.pi
    theta = span * np.arange(201) / 200
    arcs = arcs_at_angles(np.tile([1.0, 0.0, 0.0, 1.0], (3, 1)), acs, alphas, [theta] * 3)
    for m, (xs, q3) in enumerate(arcs):
        assert q3[-1] > 0
        in_time = _eqs_1_2(acs[m], alphas[m])

        def in_theta(th, y, f=in_time):
            return np.array(f(None, np.r_[y[0], th, y[1:]]))[[0, 2, 3]] * y[0] / y[2]

        r = solve_ivp(in_theta, (0, span), [1.0, 0.0, 1.0], method="DOP853", rtol=1e-12,
                      atol=1e-12, t_eval=theta).y[0]
        eps = np.max(np.abs(r - xs[0]))
        assert eps < 0.04


def _run(tmp_path, capsys, *options):
    out = tmp_path / "grid.json"
    code = main(["propagate", *options, "--out", str(out)])
    return code, out, capsys.readouterr()


def test_propagate_grid_writes_json_csv_and_png(tmp_path, capsys):
    code, out, _ = _run(tmp_path, capsys, "--alpha", "30:60:2", "--ac", "0.05:0.1:2",
                        "--years", "0.5", "--samples", "64")
    assert code == 0
    data = json.loads(out.read_text())
    assert data["ranged"] == ["ac_mm_s2", "alpha_deg"]
    assert data["input"]["axes"]["alpha_deg"] == [30.0, 60.0]
    cols = data["columns"]
    assert len(cols["eps_percent"]) == 4 and not data["invalid"]
    lines = out.with_suffix(".csv").read_text().splitlines()
    assert lines[0].split(",") == list(GRID_COLUMNS) and len(lines) == 5
    assert out.with_suffix(".png").stat().st_size > 0
    # Row 1 is ac = 0.05, alpha = 60: the same numbers as that case flown alone.
    assert (cols["ac_mm_s2"][1], cols["alpha_deg"][1]) == (0.05, 60.0)
    alone = eps_over_swept_angle(
        FixedAttitudeCase(1.0, 0.0, 0.0, 0.05, 60.0, 0.5), samples=64)
    assert cols["eps_percent"][1] == pytest.approx(100 * alone[0], rel=1e-12)
    assert cols["swept_deg"][1] == pytest.approx(math.degrees(alone[1]), rel=1e-12)
    # Half a year from the circular orbit: CVODES's a, independently, from Eq. 2's
    # h = 1 + a_c T t is close to the closed form's a (within eps of a).
    assert abs(cols["closed_form_a_au"][1] - cols["cvodes_a_au"][1]) < 0.01


@pytest.mark.parametrize("options, field", [
    (["--alpha", "-90:100:5", "--ac", "0.1"], "alpha_deg"),
    (["--alpha", "0:30:x", "--ac", "0.1"], "--alpha"),
    (["--alpha", "0:30:0", "--ac", "0.1"], "--alpha"),
    (["--alpha", "0:30", "--ac", "0.1"], "--alpha"),
    (["--alpha", "10", "--ac", "0:0.1:3"], "ac_mm_s2"),
    (["--alpha", "10", "--ac", "0.1", "--e0", "0.5:1:3"], "e0"),
    (["--alpha", "10", "--ac", "0.1:0.2:1"], "--ac"),
    (["--alpha", "10", "--ac", "nan:0.2:3"], "--ac"),
    (["--alpha", "0:30:3", "--ac", "0.1", "--method", "cvodes"], "method"),
    (["--alpha", "0:30:200", "--ac", "0.01:0.1:200"], "grid"),
])
def test_propagate_bad_ranges_fail_in_one_line_and_write_nothing(tmp_path, capsys, options,
                                                                 field):
    code, out, captured = _run(tmp_path, capsys, *options, "--years", "1")
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and field in lines[0]
    assert any(word in lines[0] for word in ("outside", "allowed", "START", "COUNT"))
    assert list(tmp_path.iterdir()) == []


def test_propagate_single_value_still_flies_one_case(tmp_path, capsys):
    code, out, _ = _run(tmp_path, capsys, "--alpha", "45", "--ac", "0.1", "--years", "0.5",
                        "--samples", "64", "--method", "closed-form")
    assert code == 0
    data = json.loads(out.read_text())
    assert data["input"]["alpha_deg"] == 45.0 and "closed_form" in data


SMALL = {"alpha_deg": (30.0, 60.0, 2), "ac_mm_s2": (0.05, 0.1, 2)}


def test_bench_batch_block_layout(tmp_path):
    # On the virtual machine: the layout is under test, and a compile would cost seconds.
    block = bench.batch(1, grid=SMALL, cvodes_cases=2, native=False)
    for key in ("cases", "arcs", "closed_form_seconds", "cvodes_seconds_equal_error",
                "cvodes_seconds_tight", "ratio_equal_error", "ratio_tight",
                "median_final_error_km"):
        assert key in block
    assert block["cases"] == 4 and block["arcs"] == bench.ARCS
    assert block["cvodes_cases_timed"] == 2
    assert block["ratio_tight"] == pytest.approx(block["cvodes_seconds_tight"]
                                                 / block["closed_form_seconds"])
    # The closed form's 20 second-order arcs over ten years miss by hundreds to
    # thousands of km (the race: 234 km at 45 deg, 0.1 mm/s^2); CVODES at 1e-12 by
    # well under a km, so its error curve brackets the closed form's.
    assert 1.0 < block["median_final_error_km"] < 1e6
    tight = next(p for p in block["cvodes_points"] if p["tolerance"] == 1e-12)
    assert tight["median_final_error_km"] < 1.0
    path = tmp_path / "batch.json"
    from esail_opt.app.outputs import write_json

    write_json(path, {"batch": block})
    assert set(json.loads(path.read_text())["batch"]) >= {"cases", "ratio_tight"}


def test_a_compiled_3d_batch_of_native_arcs_flies_as_the_mapped_one():
    """A 3-D batch in theta calls the disk cache's compiled arcs: asked to compile, it
    is mapped as it is instead of linked without them (which once killed the process
    with an undefined symbol, so it is flown here in a process of its own)."""
    import subprocess
    import sys

    code = ("import numpy as np\n"
            "from esail_opt.propagation.batch import propagate_batch3d\n"
            "rows = [np.full((3, 4), v) for v in (0.5, 0.3, 0.5)]\n"
            "x0, q0 = np.array([1.0, 0, 0, 1.0]), np.array([1.0, 0, 0, 0])\n"
            "a, b = (propagate_batch3d(x0, q0, *rows, 0.1, jit=j)[0] for j in (True, False))\n"
            "print(a.shape, bool(np.array_equal(a, b)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["(3,", "9,", "9)", "True"]
