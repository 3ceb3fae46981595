"""The benchmarks' problems (``esail_opt.bench.cases``) are the shipped problem files'.

The benches build their problems in code so that an installed package can run them;
these tests load each shipped file and compare it with the bench's copy field by field,
and check the collocation numbers the low-thrust bench carries against the stored
reference, so that neither can drift from its source.
"""

import dataclasses
import json

import pytest

from conftest import PROBLEMS, REPO
from esail_opt.bench import cases, polish, precision, solve_speed
from esail_opt.optimisation.problem import Problem
from esail_opt.optimisation.problem_file import load_problem

#: Every problem a bench runs, by the name of its function in ``cases``.
BENCH_PROBLEMS = ("earth_venus_min_time", "earth_mars_min_time", "earth_mars_low_thrust",
                  "orbit_raising_10yr", "earth_venus_min_ac")


def _differences(a, b, where="problem"):
    """Paths of the fields where two problems differ, descending into nested dataclasses."""
    if dataclasses.is_dataclass(a) and type(a) is type(b):
        out = []
        for f in dataclasses.fields(a):
            out += _differences(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
        return out
    return [] if a == b else [f"{where}: {a!r} != {b!r}"]


@pytest.mark.parametrize("name", BENCH_PROBLEMS)
def test_bench_problem_equals_the_shipped_file(name):
    built = getattr(cases, name)()
    shipped = load_problem(PROBLEMS / f"{name}.py")
    assert isinstance(built, Problem)
    assert _differences(built, shipped) == []
    # Field by field as above, and whole: nothing is left out of the comparison.
    assert built == shipped


def test_differences_sees_a_nested_field():
    built = cases.earth_mars_min_time()
    other = dataclasses.replace(built, segments=dataclasses.replace(built.segments,
                                                                    sub_arcs=4))
    assert _differences(built, other) == ["problem.segments.sub_arcs: 3 != 4"]


def test_every_bench_problem_is_checked():
    used = {p.__name__ for p in (*solve_speed.PROBLEMS, *polish.PROBLEMS)}
    used |= {case.problem.name for case in precision.CASES}
    used.add(cases.earth_mars_low_thrust.__name__)  # lowthrust.run's problem
    assert used <= set(BENCH_PROBLEMS)


def test_lowthrust_reference_numbers_are_the_stored_collocation_optimum():
    stored = json.loads((REPO / "tests" / "reference" / "collocation_min_time.json")
                        .read_text())["earth_mars_low"]
    for key, value in cases.EARTH_MARS_LOW_REFERENCE.items():
        assert stored[key] == value, key


def test_sweep_source_defines_its_problem(tmp_path):
    path = tmp_path / "bench_sweep.py"
    path.write_text(cases.SWEEP_SOURCE)
    problem = load_problem(path)
    assert problem.name == "bench_sweep_earth_mars"
    assert cases.SWEEP_PARAM.split("=")[0] == "ac_mm_s2"
    assert problem.sail.ac_mm_s2 == 1.0 and problem.target.radius_au == 1.524


def test_polish_ratio_needs_both_sides_to_succeed():
    case = {"cold_seconds": 8.0, "warm_seconds": 0.2, "cold_success": True,
            "warm_success": True}
    assert polish.ratio(case) == pytest.approx(40.0)
    assert polish.ratio({**case, "cold_success": False}) is None
    assert polish.ratio({**case, "warm_success": False}) is None
