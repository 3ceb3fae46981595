"""The pykep baseline of ``esail-opt-bench pykep`` (``esail_opt.bench.pykep_zoh``).

References, each independent of the baseline: the package's own answer to the same
transfer (results/earth_mars_min_ac/solution.json, polished: another transcription, the
closed form on segments of equal swept angle, verified by CVODES); the package's
Cartesian equations (``physics.dynamics.rhs_cartesian`` under
``physics.thrust.radial_transverse_normal``), against which the baseline's own heyoka
equations are evaluated; and the package's CVODES verifier, which flies the baseline's
schedule again.  Without pykep, heyoka or pygmo the solving tests are skipped (by the
bench's own check: pykep 3.0.1 itself does not import), and the bench must say it
skipped the baseline.
"""

import json
import sys

import numpy as np
import pytest

from conftest import REPO
from esail_opt.bench import cli, pykep_zoh
from esail_opt.optimisation.problem_file import shipped_problem

STORED = json.loads((REPO / "results" / pykep_zoh.PROBLEM / "solution.json").read_text())
#: The grids differ (equal durations here, equal swept angles there), by 7e-5 of a_c on
#: this transfer; 1e-3 is the bench's own bound.
AC_BOUND = pykep_zoh.AC_AGREEMENT
#: The issue's "to 1 m".
MISS_M = 1.0


def needs_baseline():
    reason = pykep_zoh.missing()
    if reason:
        pytest.skip(reason)


@pytest.fixture(scope="module")
def solved():
    needs_baseline()
    problem = shipped_problem(pykep_zoh.PROBLEM)
    return problem, pykep_zoh.solve(problem)


def test_heyoka_equations_are_the_packages_cartesian_equations():
    needs_baseline()
    import casadi as ca
    import heyoka as hy

    from esail_opt.physics.dynamics import rhs_cartesian
    from esail_opt.physics.thrust import EXACT, radial_transverse_normal

    system, variables = pykep_zoh.dynamics(EXACT)
    rates = hy.cfunc_dbl([rate for _, rate in system], variables, compact_mode=True)
    rng = np.random.default_rng(47)
    for _ in range(5):
        y = np.r_[rng.uniform(-1.5, 1.5, 3), rng.uniform(-1.0, 1.0, 3)]
        alpha, delta = rng.uniform(-np.pi / 2, np.pi / 2), rng.uniform(-np.pi, np.pi)
        kappa, ac = rng.uniform(0.0, 1.0), rng.uniform(0.01, 0.3)
        theirs = rates(y, pars=[alpha, delta, kappa, ac])
        R, T, N = radial_transverse_normal(alpha, delta, EXACT)
        ours = np.array(rhs_cartesian(ca.DM(y), ac * kappa, R, T, N), float).ravel()
        assert np.allclose(theirs, ours, rtol=1e-13, atol=1e-15)


def test_pykep_a_c_agrees_with_the_packages_own_solve(solved):
    _, record = solved
    assert record["converged"], record["status"]
    ours = STORED["polish"]["ac_mm_s2_required"]
    assert abs(record["ac_mm_s2"] / ours - 1.0) < AC_BOUND


def test_pykep_schedule_meets_mars_to_a_metre_on_both_integrators(solved):
    problem, record = solved
    assert record["miss_m"] < MISS_M
    flown = pykep_zoh.fly(problem, record)
    assert flown["cvodes_miss_m"] < MISS_M
    assert len(record["alpha_rad"]) == problem.segments.count


@pytest.mark.parametrize("name", ["earth_mars_min_time", "earth_mars_min_ac_planar"])
def test_a_problem_the_baseline_cannot_transcribe_is_refused_by_name(name):
    with pytest.raises(ValueError, match=name):
        pykep_zoh.transfer(shipped_problem(name))


def test_bad_repeats_is_refused_before_anything_runs(tmp_path, capsys):
    assert cli.main(["pykep", "--repeats", "0", "--out", str(tmp_path)]) == 2
    assert "repeats = 0" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("package", pykep_zoh.PACKAGES)
def test_without_a_baseline_package_the_bench_says_it_skipped(monkeypatch, tmp_path, capsys,
                                                              package):
    # A None entry in sys.modules is how Python marks a module that cannot be imported.
    monkeypatch.setitem(sys.modules, package, None)
    assert cli.main(["pykep", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "bench pykep: baseline skipped:" in out and package in out
    record = json.loads((tmp_path / "pykep.json").read_text())
    assert package in record["skipped"] and "ratio_without_figures" not in record
    assert pykep_zoh.main([]) == 2
