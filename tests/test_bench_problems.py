"""The shipped problems as package data, and what the benches take from them.

The benches load their problems by name from ``esail_opt.problems`` (the repository's
``problems/`` folder, installed inside the package); these tests check that the loader
sees exactly the repository's files, that every name a bench asks for exists, that the
packaging lists every package folder, and that the numbers a bench carries match the
stored reference they were copied from.
"""

import json

import pytest

from conftest import PROBLEMS, REPO
from esail_opt.bench import (lowthrust, polish, porkchop, porkchop3d, precision, solve_speed,
                             sweep)
from esail_opt.errors import InputError
from esail_opt.optimisation.problem import Problem
from esail_opt.optimisation.problem_file import (
    load_problem, shipped_problem, shipped_problem_names)


def test_shipped_names_are_the_repository_problem_files():
    on_disk = sorted(p.stem for p in PROBLEMS.glob("*.py") if p.name != "__init__.py")
    assert len(on_disk) >= 10
    assert list(shipped_problem_names()) == on_disk


@pytest.mark.parametrize("name", ["earth_mars_min_time", "earth_venus_min_ac"])
def test_shipped_problem_is_its_file(name):
    problem = shipped_problem(name)
    assert isinstance(problem, Problem)
    assert problem.name == name
    assert problem == load_problem(PROBLEMS / f"{name}.py")


@pytest.mark.parametrize("name", ["no_such_problem", "__init__", "earth_mars_min_time.py", ""])
def test_unknown_shipped_problem_is_one_line_naming_the_choices(name):
    with pytest.raises(InputError) as err:
        shipped_problem(name)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"shipped problem = {name!r} is not one of: ")
    assert "earth_mars_min_time" in message


def test_every_problem_a_bench_asks_for_is_shipped():
    names = {*solve_speed.PROBLEMS, *polish.PROBLEMS, *precision.PROBLEMS, lowthrust.PROBLEM,
             porkchop.PROBLEM, porkchop3d.PROBLEM}
    assert "earth_venus_min_ac" in names and "earth_mars_low_thrust" in names
    assert names <= set(shipped_problem_names())


def test_precision_cases_are_the_shipped_problems():
    cases = precision.cases()
    assert [case.problem for case in cases] == [shipped_problem(n) for n in precision.PROBLEMS]
    assert all(len(case.methods) > 5 for case in cases)


def test_pyproject_lists_every_package_folder():
    tomllib = pytest.importorskip("tomllib")  # Python 3.11 on
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    found = {".".join(p.parent.relative_to(REPO).parts)
             for p in (REPO / "esail_opt").rglob("__init__.py")}
    assert found <= listed
    assert config["package-dir"] == {"esail_opt.problems": "problems"}
    assert listed - found == {"esail_opt.problems"}
    assert (REPO / "problems" / "__init__.py").is_file()


def test_lowthrust_reference_numbers_are_the_stored_collocation_optimum():
    stored = json.loads((REPO / "tests" / "reference" / "collocation_min_time.json")
                        .read_text())["earth_mars_low"]
    assert set(lowthrust.EARTH_MARS_LOW_REFERENCE) <= set(stored)
    for key, value in lowthrust.EARTH_MARS_LOW_REFERENCE.items():
        assert stored[key] == value, key
    problem = shipped_problem(lowthrust.PROBLEM)
    assert (problem.sail.ac_mm_s2, problem.target.radius_au) == (
        stored["ac_mm_s2"], stored["rf_au"])


def test_sweep_source_defines_its_problem(tmp_path):
    path = tmp_path / "bench_sweep.py"
    path.write_text(sweep.SWEEP_SOURCE)
    problem = load_problem(path)
    assert problem.name == "bench_sweep_earth_mars"
    assert sweep.SWEEP_PARAM.split("=")[0] == "ac_mm_s2"
    assert problem.sail.ac_mm_s2 == 1.0 and problem.target.radius_au == 1.524


def test_polish_ratio_needs_both_sides_to_succeed():
    case = {"cold_seconds": 8.0, "warm_seconds": 0.2, "cold_success": True,
            "warm_success": True}
    assert polish.ratio(case) == pytest.approx(40.0)
    assert polish.ratio({**case, "cold_success": False}) is None
    assert polish.ratio({**case, "warm_success": False}) is None
