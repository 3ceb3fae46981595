"""Sweeps: parameter parsing, a failed member kept in its row, and the same numbers from a
local process pool, a real Dask LocalCluster on loopback and a direct in-process solve.

The family is a cheap Earth-Mars variant (6 segments of one closed-form arc each; under a
second per member), written to tmp_path as a user would write a problem file.
"""

import dataclasses
import json
import math

import pytest

from esail_opt import cli, sweep
from esail_opt.errors import InputError

TINY = '''
import esail_opt as eo

problem = eo.Problem(
    name="tiny_earth_mars",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=6, sub_arcs=1),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
)
'''
# a_c = 0 is outside Sail's (0, 100] mm/s^2: that member must fail in its row alone.
PARAM = "ac_mm_s2=0:1.5:4"
GRID = [0.0, 0.5, 1.0, 1.5]
# Everything in a row but its wall time must be identical across executors.
NUMBERS = [k for k in sweep.CSV_FIELDS if k != "seconds"]


@pytest.fixture()
def tiny(tmp_path):
    path = tmp_path / "tiny_earth_mars.py"
    path.write_text(TINY)
    return path


def _numbers(rows):
    return [{k: row[k] for k in NUMBERS} for row in rows]


def test_pool_and_dask_cluster_give_identical_rows(tiny, tmp_path, capsys):
    from dask.distributed import LocalCluster

    # The process pool, through the command line, as a user runs it.
    out = tmp_path / "pool"
    assert cli.main(["sweep", str(tiny), "--param", PARAM, "--workers", "2",
                     "--out", str(out)]) == 1  # one member failed: said in the exit code
    err = capsys.readouterr().err
    assert len([line for line in err.splitlines() if line.startswith("esail-opt sweep: [")]) == 4
    pool = json.loads((out / "sweep.json").read_text())
    assert (out / "sweep.png").stat().st_size > 10_000
    csv_lines = (out / "sweep.csv").read_text().splitlines()
    assert csv_lines[0].startswith("index,ac_mm_s2,converged,status,tof_days")
    assert len(csv_lines) == 1 + len(GRID)

    # Rows in grid order whatever finished first, the failed one kept and explained.
    assert [row["value"] for row in pool["rows"]] == GRID
    first, *others = pool["rows"]
    assert first["converged"] is False and first["tof_days"] is None
    assert "sail.ac_mm_s2" in first["error"] and "(0, 100]" in first["error"]
    assert pool["failed"] == 1
    for row in others:
        assert row["converged"] and row["error"] is None
        assert row["status"] == "Solve_Succeeded"
        # A 1 au -> 1.524 au transfer at 0.5-1.5 mm/s^2 takes roughly 1.5-3 years.
        assert 400 < row["tof_days"] < 1200
        assert row["target_miss_r_km"] is not None and math.isfinite(row["target_miss_r_km"])

    # A real Dask scheduler with two single-threaded worker processes on loopback.
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        dask = sweep.run(tiny, PARAM, scheduler=cluster.scheduler_address)
    assert dask["executor"].startswith("dask")
    assert _numbers(dask["rows"]) == _numbers(pool["rows"])

    # And the same numbers as solving that member here, with no executor at all.
    import esail_opt as eo
    from esail_opt.optimisation.problem_file import load_problem

    problem = load_problem(tiny)
    direct = eo.solve(dataclasses.replace(problem, sail=dataclasses.replace(problem.sail,
                                                                            ac_mm_s2=1.0)))
    assert pool["rows"][2]["tof_days"] == direct["tof_days"]
    assert pool["rows"][2]["objective"] == direct["objective"]


def test_variant_maps_names_to_fields(tiny):
    from esail_opt.optimisation.problem_file import load_problem

    problem = load_problem(tiny)
    assert sweep.variant(problem, "ac_mm_s2", 0.7).sail.ac_mm_s2 == 0.7
    assert sweep.variant(problem, "segments", 9).segments.count == 9
    assert sweep.variant(problem, "sub_arcs", 2).segments.sub_arcs == 2
    assert sweep.variant(problem, "target_radius_au", 1.3).target.radius_au == 1.3
    assert sweep.variant(problem, "departure_a_au", 1.1).departure.a_au == 1.1
    # The rest of the problem is untouched.
    changed = sweep.variant(problem, "ac_mm_s2", 0.7)
    assert changed.segments == problem.segments and changed.target == problem.target
    with pytest.raises(InputError, match="sail.ac_mm_s2"):
        sweep.variant(problem, "ac_mm_s2", -1.0)


def test_parse_param_grid():
    assert sweep.parse_param("ac_mm_s2=0.2:2:10") == (
        "ac_mm_s2", [0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0])
    assert sweep.parse_param("ac_mm_s2=0.5:9:1") == ("ac_mm_s2", [0.5])
    assert sweep.parse_param("segments=10:40:4") == ("segments", [10, 20, 30, 40])


@pytest.mark.parametrize("param, message", [
    ("ac_mm_s2", "expected NAME=START:STOP:COUNT"),
    ("ac_mm_s2=1:2", "expected NAME=START:STOP:COUNT"),
    ("=1:2:3", "expected NAME=START:STOP:COUNT"),
    ("ac=1:2:3", "is not one of: ac_mm_s2, segments, sub_arcs"),
    ("ac_mm_s2=1:2:0", "COUNT = 0 is outside [1, inf)"),
    ("ac_mm_s2=1:2:x", "COUNT = 'x' is not an integer"),
    ("ac_mm_s2=a:2:3", "START and STOP must be numbers"),
    ("ac_mm_s2=nan:2:3", "must be finite"),
    ("segments=1:2:3", "does not give whole numbers"),
    ("tof_days=100:200:3", "does not apply to tiny_earth_mars: its MinTime has no tof_days"),
])
def test_bad_param_is_one_line_exit_2_nothing_written(tiny, tmp_path, capsys, param, message):
    out = tmp_path / "out"
    assert cli.main(["sweep", str(tiny), "--param", param, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("esail-opt sweep: error: ")
    assert message in err
    assert not out.exists()


def test_bad_workers_and_missing_file(tiny, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["sweep", str(tiny), "--param", PARAM, "--workers", "0",
                     "--out", str(out)]) == 2
    assert "workers = 0 is outside [1, inf)" in capsys.readouterr().err
    assert cli.main(["sweep", str(tmp_path / "none.py"), "--param", PARAM,
                     "--out", str(out)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert not out.exists()


def test_polished_member_is_exact_and_cannot_beat_the_continuous_optimum(tiny):
    """``--polish`` in a member: the exact time of flight of 6 constant-pitch segments
    flown on Eqs. 1-2 reaches the target (verified to 1 m) and is no shorter than the
    independent continuous-pitch collocation optimum (578.006 d), which any piecewise-
    constant schedule can only approach."""
    from pathlib import Path

    reference = json.loads((Path(__file__).parent / "reference" /
                            "collocation_min_time.json").read_text())["earth_mars"]["tof_days"]
    row = sweep.solve_member(0, "ac_mm_s2", 1.0, tiny.read_text(), tiny.name, polish=True)
    assert row["error"] is None and row["converged"]
    assert row["exact_verified"] is True
    assert row["exact_target_miss_m"] < 1.0
    assert reference - 1e-3 <= row["tof_days_exact"] < 1.05 * reference
    plain = sweep.solve_member(0, "ac_mm_s2", 1.0, tiny.read_text(), tiny.name)
    assert plain["tof_days_exact"] is None and plain["exact_verified"] is None
    assert plain["tof_days"] == row["tof_days"]
