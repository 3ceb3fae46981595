"""The Solution: its JSON fields, CSV rows, and a round trip through the files."""

import json
import math
from pathlib import Path

import pytest

import esail_opt as eo
from esail_opt.physics import constants as units
from esail_opt.app import schema
from esail_opt.app.record import plain
from esail_opt.app.solution import Solution
from esail_opt.errors import InputError


@pytest.fixture(scope="module")
def solution():
    problem = eo.Problem("tiny", eo.ParkingOrbit(1.0), eo.Sail(1.0), eo.Segments(6, 2),
                         eo.MinTime(), eo.CircularOrbit(0.723))
    return eo.solve(problem)


def test_json_has_the_issue_fields(solution):
    d = solution.to_json()
    for key in ("status", "converged", "objective", "tof_days", "iterations", "solve_seconds",
                "schedule", "final_state", "verification"):
        assert key in d
    assert set(d["schedule"][0]) >= {"t_days", "theta_deg", "alpha_deg"}
    assert set(d["final_state"]) >= {"r_au", "theta_deg", "vr_km_s", "vtheta_km_s"}
    assert set(d["verification"]) >= {"miss_r_km", "miss_v_m_s", "miss_theta_deg",
                                      "target_miss_r_km"}
    assert d["converged"] is (d["status"] == "Solve_Succeeded")
    # min time: the objective is the time of flight, in TU
    assert units.time_to_days(d["objective"]) == pytest.approx(d["tof_days"], rel=1e-12)
    starts = [row["t_days"] for row in d["schedule"]]
    assert starts[0] == 0.0 and all(b > a for a, b in zip(starts, starts[1:]))
    assert all(-90 <= row["alpha_deg"] <= 90 for row in d["schedule"])


def test_files_round_trip(solution, tmp_path):
    written = solution.write(tmp_path, plots=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["schedule.csv", "solution.json"]
    loaded = Solution.load(written[0])
    assert loaded == solution
    assert loaded.to_json() == json.loads(written[0].read_text()) == solution.to_json()
    rows = (tmp_path / "schedule.csv").read_text().splitlines()
    assert len(rows) == len(solution["schedule"]) + 1
    first = dict(zip(rows[0].split(","), map(float, rows[1].split(","))))
    assert first["alpha_deg"] == pytest.approx(solution["schedule"][0]["alpha_deg"], rel=1e-9)
    assert "tiny" in loaded.summary()


def test_non_finite_numbers_become_null():
    assert plain({"a": [math.nan, 1.0], "b": math.inf}) == {"a": [None, 1.0], "b": None}


def test_same_problem_gives_the_same_numbers(solution):
    again = eo.solve(eo.Problem("tiny", eo.ParkingOrbit(1.0), eo.Sail(1.0), eo.Segments(6, 2),
                                eo.MinTime(), eo.CircularOrbit(0.723))).to_json()
    first = dict(solution.to_json())
    for d in (first, again):
        d.pop("solve_seconds")
        for row in d["refinement"]["rounds"]:
            row.pop("seconds")
    assert json.dumps(first) == json.dumps(again)


def test_a_file_of_another_schema_version_fails_with_one_clear_line(solution, tmp_path):
    written = solution.write(tmp_path, plots=False)[0]
    assert json.loads(written.read_text())["schema_version"] == schema.SCHEMA_VERSION
    old = json.loads(written.read_text())
    del old["schema_version"]  # as every file before versions existed
    written.write_text(json.dumps(old))
    with pytest.raises(InputError, match="schema version 1, but this esail_opt reads versions 2, 3"):
        Solution.load(written)


def test_a_dated_file_gives_its_exact_epoch_and_one_of_version_6_loads_without_it(tmp_path):
    """Version 7 added ``departure_epoch_days``: the shipped window answer's agrees with
    its date, written to the millisecond, and a version-6 file (no such key) loads."""
    from esail_opt.bodies.dates import jd_from_iso

    results = Path(__file__).resolve().parents[1] / "results"
    data = json.loads((results / "earth_mars_window" / "solution.json").read_text())
    days = data["departure_epoch_days"]
    assert abs(2451545.0 + days - jd_from_iso(data["departure_date"])) <= 0.5e-3 / 86400 + 1e-9
    old = dict(data, schema_version=6)
    del old["departure_epoch_days"]
    (tmp_path / "solution.json").write_text(json.dumps(old))
    loaded = Solution.load(tmp_path / "solution.json")
    assert loaded.departure_epoch_days is None
    assert loaded.departure_date == data["departure_date"]


def test_the_summary_counts_error_control_rounds_as_its_progress_lines_do(solution):
    """The progress lines number the error control's rounds from 0; the summary names
    the same rounds (it said '0 error-control round(s)' after round 0)."""
    from esail_opt.app.report import _refinements

    first = solution.summary().splitlines()[0]
    assert first.endswith(_refinements(len(solution.rounds)))
    assert [_refinements(n) for n in (1, 2, 3)] == [
        "error control: round 0 only", "error control: rounds 0-1 (1 mesh refinement)",
        "error control: rounds 0-2 (2 mesh refinements)"]


def test_a_dated_schedule_gives_each_segment_its_start_date(solution):
    """A dated flight's schedule.csv ends each row with its segment's start, ISO 8601
    (TDB): the first is the departure, and the last plus its duration the arrival; an
    undated schedule has no such column."""
    import csv
    import io

    from esail_opt.app.solution_files import schedule_csv
    from esail_opt.bodies.dates import jd_from_iso

    results = Path(__file__).resolve().parents[1] / "results"
    dated = Solution.load(results / "earth_mars_min_ac" / "solution.json")
    rows = list(csv.DictReader(io.StringIO(schedule_csv(dated))))
    start = dated.polish.departure_date or dated.departure_date
    assert rows[0]["start_date_tdb"] == start
    last = jd_from_iso(rows[-1]["start_date_tdb"]) + float(rows[-1]["duration_days"])
    assert abs(last - jd_from_iso(dated.arrival_date)) < 1e-3 / 86400
    assert all(len(r["start_date_tdb"]) == 23 for r in rows)  # YYYY-MM-DDThh:mm:ss.sss
    assert "start_date_tdb" not in schedule_csv(solution).splitlines()[0]


def test_a_file_that_is_not_a_solution_fails_with_one_clear_line(solution, tmp_path):
    written = solution.write(tmp_path, plots=False)[0]
    data = json.loads(written.read_text())
    del data["schedule"]
    written.write_text(json.dumps(data))
    with pytest.raises(InputError, match="solution.json's field schedule is missing") as err:
        Solution.load(written)
    assert "\n" not in str(err.value)
    written.write_text("{ not json")
    with pytest.raises(InputError, match="cannot read solution.json") as err:
        Solution.load(written)
    assert "\n" not in str(err.value)


def _damaged(data, path, value):
    """``data`` with the dotted key ``path`` set to ``value``."""
    *parents, last = path.split(".")
    where = data
    for part in parents:
        where = where[part]
    where[last] = value
    return data


@pytest.mark.parametrize("path, value, message", [
    ("trajectory", None, "field trajectory is not a JSON object"),
    ("schedule", "abc", "field schedule = 'abc' is not a list of segments"),
    ("verification", 3, "field verification = 3 is not a JSON object"),
    ("tof_days", float("nan"), "it holds NaN, which is not a number"),
    ("trajectory.cvodes.r_au", [1.0] * 10,
     "field trajectory.cvodes is not valid: its samples differ in number (r_au 10, ")])
def test_a_damaged_field_is_named_in_one_line(solution, tmp_path, path, value, message):
    """A hand-damaged solution.json is refused as it is read, with one line that names
    the field and what is wrong with it, before any figure reads a broken array."""
    written = solution.write(tmp_path, plots=False)[0]
    written.write_text(json.dumps(_damaged(json.loads(written.read_text()), path, value)))
    with pytest.raises(InputError) as err:
        Solution.load(written)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_the_solution_is_typed_and_agrees_with_its_file(solution):
    """Readers get typed fields: the schedule's rows, the verification's misses, the
    problem's parts; each is the value the file holds under its key."""
    d = solution.to_json()
    assert solution.outcome.value == d["outcome"] and solution.outcome.found
    assert [row.alpha_deg for row in solution.schedule] == [r["alpha_deg"] for r in d["schedule"]]
    assert solution.verification.target_miss_r_km == d["verification"]["target_miss_r_km"]
    assert solution.problem.target.kind == "CircularOrbit"
    assert solution.problem.target.radius_au == 0.723
    assert solution.problem.departure.a_au == 1.0
    assert [r.sub_arcs for r in solution.rounds] == [r["sub_arcs"] for r in
                                                     d["refinement"]["rounds"]]
    # Frozen: a Solution is what was solved, not a scratch pad.
    with pytest.raises(AttributeError):
        solution.tof_days = 0.0
    with pytest.raises(AttributeError):
        solution.problem.target.radius_au = 1.0
    # The README's read by the file's name.
    assert solution["tof_days"] == solution.tof_days


@pytest.mark.parametrize("path", sorted((Path(__file__).resolve().parents[1] / "results")
                                        .glob("**/solution.json")),
                         ids=lambda p: p.parent.name)
def test_every_shipped_solution_file_reads_back_to_the_same_content(path):
    """The typed Solution loses nothing: a file read and written again holds the same
    keys, in the same order, with the same values."""
    data = json.loads(path.read_text())
    again = Solution.load(path).to_json()
    assert again == data and list(again) == list(data)


def test_a_polished_solution_built_from_its_run_equals_the_one_read_back(tmp_path):
    """Built from the Run directly, a polished solution holds the values its file gives
    back, the polish's schedule and flight included; a version-3 file's polish, which
    has no start of its own, still reads and writes without one."""
    sol = eo.solve(eo.Problem("tiny", eo.ParkingOrbit(1.0), eo.Sail(1.0), eo.Segments(6, 2),
                              eo.MinTime(), eo.CircularOrbit(0.723)), polish=True)
    written = sol.write(tmp_path, plots=False)[0]
    assert sol.polished and Solution.load(written) == sol
    rows = (tmp_path / "schedule.csv").read_text().splitlines()
    assert len(rows) == len(sol.polish.schedule) + 1
    old = json.loads(written.read_text())
    old["schema_version"] = 3
    del old["polish"]["departure_state"]
    v3 = Solution.from_json(old)
    assert v3.polish.departure_state is None and v3.polish.schedule == sol.polish.schedule
    assert "departure_state" not in v3.to_json()["polish"]


def _mars_3d(**sail):
    return eo.Problem(name="m3", departure=eo.BodyDeparture(body="earth", date="2031-08-11"),
                      sail=eo.Sail(ac_mm_s2=1.0, **sail), segments=eo.Segments(count=4),
                      objective=eo.MinAcceleration(tof_days=650.0),
                      target=eo.BodyRendezvous(body="mars"), planar=False)


@pytest.mark.parametrize("sail, renamed", [({}, True),
                                           ({"clock_min_deg": -170.0}, False),
                                           ({"alpha_min_deg": -60.0}, False)])
def test_schedule_names_each_attitude_canonically_where_both_names_are_allowed(sail, renamed):
    """With the clock free and the pitch bounded symmetrically, a row's clock lies in
    (-90, 90] deg and its (pitch, clock) gives the NLP's thrust; otherwise the rows keep
    the NLP's own pitch (its clock only wrapped to [-180, 180))."""
    from types import SimpleNamespace

    import numpy as np

    from esail_opt.app.from_run import _attitudes_deg
    from esail_opt.physics.thrust import radial_transverse_normal

    alpha = np.radians([30.0, -20.0, 45.0, 10.0])
    delta = np.radians([170.0, -120.0, 400.0, 0.0])
    rows = _attitudes_deg(_mars_3d(**sail), SimpleNamespace(alpha=alpha, delta=delta))
    for (a_deg, c_deg), a, d in zip(rows, alpha, delta):
        want = [float(v) for v in radial_transverse_normal(a, d)]
        got = [float(v) for v in radial_transverse_normal(math.radians(a_deg),
                                                          math.radians(c_deg))]
        assert max(abs(g - w) for g, w in zip(got, want)) < 1e-14
        assert -180 <= c_deg < 180
        if renamed:
            assert -90 < c_deg <= 90
        else:
            assert a_deg == pytest.approx(math.degrees(a), abs=1e-12)


def test_an_answer_at_the_end_of_its_date_window_says_the_window_binds():
    """A free departure that Ipopt left at its window's end was stopped by the window,
    not by the mission: the summary says so, and says nothing where the date is inside."""
    data = json.loads((Path(__file__).parents[1] / "results" / "earth_mars_window"
                       / "solution.json").read_text())
    inside = Solution.from_json(data)
    assert "the window binds" not in inside.summary()
    data["problem"]["departure"]["window"] = ["2030-01-01", data["departure_date"][:10]]
    data["departure_date"] = data["departure_date"][:10] + "T00:00:00.000"
    line = (f"  departs as its departure window closes ({data['departure_date'][:10]}): "
            "the window binds, and a wider one may do better")
    assert line in Solution.from_json(data).summary().splitlines()
