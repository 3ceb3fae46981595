"""Sweeps: parameter parsing, a failed member kept in its row, and the same numbers from a
local process pool, a real Dask LocalCluster on loopback and a direct in-process solve;
then the faults: a worker killed mid-run, Ctrl-C and --resume, the journal, and members
that converge without verifying.

The families are cheap Earth-Mars and Earth-Venus variants (6 to 16 closed-form arcs; a
second or two per member), written to tmp_path as a user would write a problem file,
with a tolerance loose enough that the first-order closed form always verifies.
"""

import dataclasses
import functools
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from esail_opt.app import cli, engine, sweep
from esail_opt.runtime.journal import Journal
from esail_opt.runtime import pool
from esail_opt.errors import InputError

from conftest import REPO, TINY_PROBLEM

TINY = TINY_PROBLEM.format(name="tiny_earth_mars")
PARAM = "ac_mm_s2=0.5:1.5:3"
GRID = [0.5, 1.0, 1.5]
# Everything in a row but its wall time must be identical across executors.
NUMBERS = [k for k in sweep.CSV_FIELDS if k != "seconds"]


def _sweep_journal(path, header):
    """The sweep's journal at ``path`` under ``header``, as the sweep's run makes it."""
    return Journal(path, header, sweep.SweepRow, len(header["values"]),
                   functools.partial(sweep.belongs, header["values"]), engine.invalid_row)



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
                     "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert len([line for line in err.splitlines() if line.startswith("esail-opt sweep: [")]) == 3
    pooled = json.loads((out / "sweep.json").read_text())
    assert (out / "sweep.png").stat().st_size > 10_000
    csv_lines = (out / "sweep.csv").read_text().splitlines()
    assert csv_lines[0].startswith("index,ac_mm_s2,converged,verified,status,tof_days")
    assert len(csv_lines) == 1 + len(GRID)

    # Rows in grid order whatever finished first.
    assert [row["value"] for row in pooled["rows"]] == GRID
    others = pooled["rows"]
    assert pooled["failed"] == 0
    for row in others:
        assert row["converged"] and row["error"] is None
        assert row["status"] == "Solve_Succeeded"
        assert row["verified"] in (None, True)  # None from a solve that gives no verdict
        # A 1 au -> 1.524 au transfer at 0.5-1.5 mm/s^2 takes roughly 1.5-3 years.
        assert 400 < row["tof_days"] < 1200
        assert row["target_miss_r_km"] is not None and math.isfinite(row["target_miss_r_km"])
    # A minimum-time objective is the time of flight, in days: one panel shows both.
    panel = sweep.figure(pooled).axes[0]
    assert panel.get_ylabel() == "time of flight [d]"
    assert np.allclose(panel.get_lines()[0].get_ydata(), [r["tof_days"] for r in others],
                       rtol=1e-9)

    # A real Dask scheduler with two single-threaded worker processes on loopback.
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        dask = sweep.run(tiny, PARAM, scheduler=cluster.scheduler_address)
    assert dask["executor"].startswith("dask")
    assert _numbers(dask["rows"]) == _numbers(pooled["rows"])

    # And the same numbers as solving that member here, with no executor at all.
    import esail_opt as eo
    from esail_opt.optimisation.problem_file import load_problem

    problem = load_problem(tiny)
    direct = eo.solve(dataclasses.replace(problem, sail=dataclasses.replace(problem.sail,
                                                                            ac_mm_s2=1.0)))
    assert pooled["rows"][1]["tof_days"] == direct["tof_days"]
    assert pooled["rows"][1]["objective"] == direct["objective"]


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


def test_the_sweep_help_names_every_sweepable_field(capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["sweep", "--help"])
    assert stop.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "Sweepable names: " + ", ".join(sweep.SWEEPABLE) + "." in text


def test_building_the_command_line_leaves_the_sweep_unimported():
    """Every command builds the whole parser; the sweep's names are read only when its
    help is printed."""
    code = ("import sys; from esail_opt.app import cli; cli.build_parser(); "
            "print('esail_opt.app.sweep' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=REPO).stdout
    assert out.strip() == "False"


def test_parse_param_grid():
    assert sweep.parse_param("ac_mm_s2=0.2:2:10") == (
        "ac_mm_s2", [0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0])
    assert sweep.parse_param("ac_mm_s2=0.5:0.5:1") == ("ac_mm_s2", [0.5])
    with pytest.raises(InputError, match="COUNT = 1 needs START = STOP"):
        sweep.parse_param("ac_mm_s2=0.5:9:1")
    with pytest.raises(InputError, match="COUNT = 3 needs START != STOP"):
        sweep.parse_param("ac_mm_s2=0.5:0.5:3")
    assert sweep.parse_param("segments=10:40:4") == ("segments", [10, 20, 30, 40])


@pytest.mark.parametrize("param, message", [
    ("ac_mm_s2", "expected NAME=START:STOP:COUNT"),
    ("ac_mm_s2=1:2", "expected NAME=START:STOP:COUNT"),
    ("=1:2:3", "expected NAME=START:STOP:COUNT"),
    ("ac=1:2:3", "is not one of: ac_mm_s2, segments, sub_arcs"),
    ("ac_mm_s2=1:2:0", "COUNT = 0 is outside [1, 10000]"),
    ("ac_mm_s2=1:2:20000", "COUNT = 20000 is outside [1, 10000]"),
    ("ac_mm_s2=1:2:x", "COUNT = 'x' is not an integer"),
    ("ac_mm_s2=a:2:3", "START and STOP must be numbers"),
    ("ac_mm_s2=nan:2:3", "must be finite"),
    ("segments=1:2:3", "does not give whole numbers"),
    ("tof_days=100:200:3", "does not apply to tiny_earth_mars: its MinTime has no tof_days"),
    # A value no problem accepts is the command's mistake, refused before any member.
    ("ac_mm_s2=-1:1:3", "param ac_mm_s2: sail.ac_mm_s2 = -1.0 mm/s^2 is outside (0, 100]"),
    ("segments=0:10:2", "param segments: "),
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
    assert "workers = 0 is outside [1, 64]" in capsys.readouterr().err
    assert cli.main(["sweep", str(tiny), "--param", PARAM, "--workers", "65",
                     "--out", str(out)]) == 2
    assert "workers = 65 is outside [1, 64]" in capsys.readouterr().err
    assert cli.main(["sweep", str(tmp_path / "none.py"), "--param", PARAM,
                     "--out", str(out)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert cli.main(["sweep", str(tmp_path), "--param", PARAM, "--out", str(out)]) == 2
    assert "is a folder" in capsys.readouterr().err
    assert not out.exists()


def test_polished_member_is_exact_and_cannot_beat_the_continuous_optimum(tiny):
    """``--polish`` in a member: the exact time of flight of 6 constant-pitch segments
    flown on Eqs. 1-2 reaches the target (verified to 1 m) and is no shorter than the
    independent continuous-pitch collocation optimum (578.006 d), which any piecewise-
    constant schedule can only approach."""
    reference = json.loads((REPO / "tests" / "reference" /
                            "collocation_min_time.json").read_text())["earth_mars"]["tof_days"]
    row = sweep.solve_member(0, "ac_mm_s2", 1.0, tiny.read_text(), tiny.name, polish=True)
    assert row["error"] is None and row["converged"]
    assert row["exact_verified"] is True
    assert row["exact_target_miss_km"] < 1e-3
    assert reference - 1e-3 <= row["tof_days_exact"] < 1.05 * reference
    # The figure draws the polished miss in the panel's km, as the row holds it (it was
    # drawn a thousand times too small, as if the row held metres).
    misses = sweep.figure({"problem": "tiny", "field": "ac_mm_s2", "param": "ac_mm_s2",
                           "unit": "mm/s^2", "failed": 0, "polished": True,
                           "rows": [row]}).axes[2]
    polished = [line for line in misses.get_lines() if line.get_marker() == "s"][0]
    assert list(polished.get_ydata()) == [row["exact_target_miss_km"]]
    plain = sweep.solve_member(0, "ac_mm_s2", 1.0, tiny.read_text(), tiny.name)
    assert plain["tof_days_exact"] is None and plain["exact_verified"] is None
    assert plain["tof_days"] == row["tof_days"]


# ---------------------------------------------------------------- faults

# Earth-Venus at 8 segments x 2 sub-arcs, a small fraction of a second a member once
# compiled.  Each time a process loads it, it leaves an empty file named "<pid>-<ns>" in
# MARKS, so a test can see which worker process has just started a member, and then holds
# for HOLD seconds, so a test can be sure that worker is still busy with it.
VENUS = '''
import os
import pathlib
import time

import esail_opt as eo

pathlib.Path(r"{marks}", f"{{os.getpid()}}-{{time.time_ns()}}").touch()
time.sleep({hold})

problem = eo.Problem(
    name="tiny_earth_venus",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=8, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=0.723),
    tolerance=eo.Tolerance(position_km=1e8, velocity_m_s=1e5),
)
'''


def _venus_file(tmp_path, hold):
    marks = tmp_path / "marks"
    marks.mkdir()
    path = tmp_path / "tiny_earth_venus.py"
    path.write_text(VENUS.format(marks=marks, hold=hold))
    return path, marks


@pytest.fixture()
def venus(tmp_path):
    return _venus_file(tmp_path, hold=0)


def _journal(out):
    """Header and rows of the journal in ``out`` (every line must be whole JSON)."""
    header, *rows = [json.loads(line) for line in (out / sweep.JOURNAL).read_text().splitlines()]
    return header, rows


def _worker_marks(marks):
    """(ns, pid) of every member start by a process other than this one, oldest first."""
    found = []
    for mark in marks.iterdir():
        pid, ns = (int(part) for part in mark.name.split("-"))
        if pid != os.getpid():
            found.append((ns, pid))
    return sorted(found)


@pytest.mark.slow
def test_killed_worker_costs_only_its_own_member(tmp_path):
    """SIGKILL one of two pool workers while it solves: the pool breaks and fails every
    unfinished future, yet all four members end converged -- the killed worker's member
    run again on a fresh pool and charged with one lost worker, the members of the
    healthy worker not charged at all."""
    # Each member holds 2 s after it starts, so the worker killed 0.2 s after its newest
    # start is certainly busy; a compiled member alone is over in a tenth of a second.
    path, marks = _venus_file(tmp_path, hold=2.0)
    killed = []

    def kill_a_busy_worker():
        deadline = time.monotonic() + 100
        while time.monotonic() < deadline:
            started = _worker_marks(marks)
            if len({pid for _, pid in started}) >= 2:
                # The newest start is a member certainly still held 0.2 s later.
                pid = started[-1][1]
                time.sleep(0.2)
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return
            time.sleep(0.02)

    killer = threading.Thread(target=kill_a_busy_worker, daemon=True)
    killer.start()
    out = tmp_path / "out"
    result = sweep.run(path, "ac_mm_s2=0.5:2:4", workers=2, out_dir=out)
    killer.join(timeout=5)
    print("killed worker", killed, "lost", result["lost"], "solved", result["solved"])

    assert len(killed) == 1
    assert [row["value"] for row in result["rows"]] == [0.5, 1.0, 1.5, 2.0]
    for row in result["rows"]:
        assert row["converged"] and row["error"] is None, row
        assert row["status"] == "Solve_Succeeded"
    assert result["failed"] == 0
    # Exactly one member was charged, once, and it is the killed worker's.
    assert len(result["lost"]) == 1
    lost = result["lost"][0]
    assert lost["losses"] == 1
    assert f"worker pid {killed[0]} ended by SIGKILL" in lost["cause"]
    assert sorted(result["solved"]) == [0, 1, 2, 3]
    # The journal holds each member once, as it finished.
    header, rows = _journal(out)
    assert header["values"] == [0.5, 1.0, 1.5, 2.0] and header["problem"] == "tiny_earth_venus"
    assert sorted(row["index"] for row in rows) == [0, 1, 2, 3]
    assert [row["index"] for row in rows] == result["solved"]


@pytest.mark.slow
def test_member_lost_every_time_gets_its_own_row(venus, tmp_path, monkeypatch):
    """A member whose worker dies on every attempt ends with "worker lost 3 times" in its
    own row (not journaled, so --resume would try it again); the other member converges."""
    path, _ = venus
    # Submitted by name, so the spawned workers import this test module to run it.
    monkeypatch.setattr(pool, "_pool_member", _crashing_pool_member)
    out = tmp_path / "out"
    result = sweep.run(path, "ac_mm_s2=0.5:1:2", workers=1, out_dir=out, retries=2)
    first, second = result["rows"]
    assert first["converged"] and first["error"] is None
    assert second["converged"] is False and second["tof_days"] is None
    assert second["error"].startswith("worker lost 3 times: worker pid ")
    assert second["error"].endswith("ended by SIGKILL")
    assert result["failed"] == 1
    assert result["lost"] == [{"index": 1, "value": 1.0, "losses": 3,
                               "cause": second["error"].split(": ", 1)[1]}]
    _, rows = _journal(out)
    assert [row["index"] for row in rows] == [0]


def _crashing_pool_member(started, function, index, *args):
    """Pool member that kills its own worker for index 1 (after saying it started)."""
    from pathlib import Path

    Path(started, str(index)).write_text(str(os.getpid()))
    if index == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return function(index, *args)


def _sweep_command(path, param, out, *extra):
    return [sys.executable, "-m", "esail_opt.app.cli", "sweep", str(path), "--param", param,
            "--workers", "2", "--out", str(out), *extra]


@pytest.mark.slow
def test_interrupt_keeps_the_journal_and_resume_runs_only_the_rest(venus, tmp_path, capsys):
    """Ctrl-C (SIGINT) on ``esail-opt sweep`` once a member has finished: exit 130, the
    workers gone, the journal keeping the finished members, no sweep.csv.  Then
    ``--resume`` solves exactly the missing members and leaves the journaled ones as
    they were; a --resume with another grid is refused in one line."""
    import psutil

    path, _ = venus
    out = tmp_path / "out"
    param = "ac_mm_s2=0.5:2:6"
    values = [0.5, 0.8, 1.1, 1.4, 1.7, 2.0]
    # A shell that starts pytest in the background hands its children SIGINT ignored, and
    # Python keeps an ignored SIGINT; give the sweep the default, as a terminal would.
    proc = subprocess.Popen(_sweep_command(path, param, out), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 100
        journal = out / sweep.JOURNAL
        while time.monotonic() < deadline and proc.poll() is None:
            if journal.exists() and len(journal.read_text().splitlines()) >= 2:
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the sweep ended before it could be interrupted"
        workers = [child for child in psutil.Process(proc.pid).children(recursive=True)
                   if "spawn_main" in " ".join(child.cmdline())]
        assert workers
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        _, stderr = proc.communicate(timeout=10)
        stopped_after = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130
    assert stderr.rstrip().splitlines()[-1] == (
        "esail-opt sweep: interrupted; nothing half-done was written")
    # The pool's workers were terminated, not left solving on their own.
    gone, alive = psutil.wait_procs(workers, timeout=5)
    assert not alive
    for name in ("sweep.csv", "sweep.json", "sweep.png"):
        assert not (out / name).exists()
    before = journal.read_text()
    header, rows = _journal(out)
    assert header["values"] == values
    kept = sorted(row["index"] for row in rows)
    assert 1 <= len(kept) < len(values) and len(set(kept)) == len(kept)
    assert all(row["converged"] and row["value"] == values[row["index"]] for row in rows)
    missing = [i for i in range(len(values)) if i not in kept]
    # The line before the interrupt's says what the journal keeps.
    assert f"keeps {len(kept)} of the {len(values)} rows; run again with --resume" in stderr

    # --resume, as a user would run it after the interrupt.
    assert cli.main(_sweep_command(path, param, out, "--resume")[3:]) == 0
    err = capsys.readouterr().err
    ran = [line for line in err.splitlines() if line.startswith("esail-opt sweep: [")]
    with capsys.disabled():
        print(f"\nSIGINT to exit: {stopped_after:.2f} s; journal kept {kept}, resume ran "
              f"{missing}:\n" + "\n".join(ran))
    assert len(ran) == len(missing)
    result = json.loads((out / "sweep.json").read_text())
    assert result["resumed"] == kept
    assert sorted(result["solved"]) == missing
    assert [row["value"] for row in result["rows"]] == values
    assert all(row["converged"] and row["error"] is None for row in result["rows"])
    # The journaled rows are untouched, byte for byte; the new ones follow them.
    after = journal.read_text()
    assert after.startswith(before)
    _, rows = _journal(out)
    assert sorted(row["index"] for row in rows) == list(range(len(values)))
    by_index = {row["index"]: row for row in rows}
    for row in result["rows"]:
        assert row["tof_days"] == by_index[row["index"]]["tof_days"]

    # A journal of one grid does not resume another: one line, exit 2, nothing changed.
    assert cli.main(_sweep_command(path, "ac_mm_s2=0.5:2:5", out, "--resume")[3:]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "belongs to another sweep: its values is" in err
    assert journal.read_text() == after


def test_journal_resumes_on_index_and_value_and_refuses_another_sweep(tmp_path):
    """The journal: a torn last line and rows of another grid are not kept; a fresh
    start replaces it (with its first row, or at its end); another problem file, param,
    grid or tolerance is refused."""
    path = tmp_path / sweep.JOURNAL
    header = {"journal": "esail-opt sweep", "problem": "p", "source_sha256": "abc",
              "param": "ac_mm_s2", "values": [0.5, 1.0, 1.5], "polish": False,
              "tolerance": {"position_km": 1e4, "velocity_m_s": 10.0}}
    journal = _sweep_journal(path, header)
    assert journal.open(resume=True) == {}  # nothing to resume: a fresh journal
    journal.append({**sweep._empty_row(2, 1.5), "converged": True, "tof_days": 300.0})
    journal.append({**sweep._empty_row(1, 0.75), "converged": True})  # not this grid's
    with open(path, "a") as f:
        f.write('{"index": 0, "value": 0.5, "conv')  # torn by a crash mid-append
    kept = _sweep_journal(path, header).open(resume=True)
    assert list(kept) == [2]
    assert kept[2]["tof_days"] == 300.0 and set(kept[2]) == set(sweep.CSV_FIELDS)

    for key, value, message in (
            ("source_sha256", "def", "the problem file changed since it was written"),
            ("param", "segments", "its param is 'ac_mm_s2', not 'segments'"),
            ("values", [0.5, 1.0], "its values is [0.5, 1.0, 1.5], not [0.5, 1.0]"),
            ("tolerance", {"position_km": 1.0, "velocity_m_s": 10.0}, "its tolerance is")):
        with pytest.raises(InputError, match="belongs to another sweep") as err:
            _sweep_journal(path, {**header, key: value}).open(resume=True)
        assert message in str(err.value) and "\n" not in str(err.value)

    # Without resume the old journal is replaced by a bare header at the run's end
    # (here no row reached it).
    fresh = _sweep_journal(path, {**header, "values": [9.0]})
    assert fresh.open(resume=False) == {}
    fresh.close()
    assert [json.loads(line) for line in path.read_text().splitlines()] == [
        {**header, "values": [9.0]}]
    path.write_text("not json\n")
    with pytest.raises(InputError, match="is not a sweep journal"):
        _sweep_journal(path, header).open(resume=True)


class _Unverified:
    """Stands in for a Solution that converged but whose flight missed the tolerance."""

    converged = True
    status, tof_days, objective, iterations = "Solve_Succeeded", 300.0, 5.0, 20
    flight_verified = False
    polish = None

    def __init__(self, problem, note):
        import types

        self.problem = problem
        self.verification = types.SimpleNamespace(
            target_miss_r_km=1234.5, target_miss_v_m_s=6.5, miss_r_km=None, miss_v_m_s=None,
            error=None)
        self.verification_note = note


@pytest.mark.parametrize("field, value, why", [
    ("tof_days", "300", "tof_days = '300' is not a number"),  # a string for a number
    ("objective", True, "objective = True is not a number"),  # a bool is not a number
    ("iterations", False, "iterations = False is not a whole number"),
    ("iterations", 12.0, "iterations = 12.0 is not a whole number"),
    ("status", 3, "status = 3 is not a string"),
    ("exact_verified", 1, "exact_verified = 1 is not true or false"),
    ("converged", None, "converged is missing"),  # null where the field is not Optional
    ("value", None, "value is missing"),
])
def test_a_journal_row_is_checked_against_its_dataclass(tmp_path, field, value, why):
    """Every field of a journal row against :class:`SweepRow`'s annotation: one line
    naming the file, the line and the field; an int fills a float field and null an
    Optional one."""
    path = tmp_path / sweep.JOURNAL
    header = {"journal": "esail-opt sweep", "problem": "p", "source_sha256": "abc",
              "param": "ac_mm_s2", "values": [1.0, 2.0], "polish": False,
              "tolerance": {"position_km": 1e4, "velocity_m_s": 10.0}}
    good = {**sweep._empty_row(0, 1), "converged": True, "objective": 3, "seconds": 0.5}
    path.write_text(json.dumps(header) + "\n" + json.dumps(good) + "\n")
    assert _sweep_journal(path, header).read(resume=True)[0]["objective"] == 3
    path.write_text(json.dumps(header) + "\n" + json.dumps({**good, field: value}) + "\n")
    with pytest.raises(InputError) as err:
        _sweep_journal(path, header).read(resume=True)
    message = str(err.value)
    assert f"{path} line 2 is not a valid row: {why};" in message and "\n" not in message



def test_converged_but_not_verified_member_fails_in_its_row(tiny, monkeypatch):
    """--tol-km/--tol-m-s reach the member's problem, and a converged member whose flight
    misses them is a failure with its reason, the first line of the solve's own note."""
    from esail_opt.app import solution

    seen = []

    def fake_solve(problem, polish=False):
        seen.append(problem)
        return _Unverified(problem, "position miss 1234 km > 1000 km")

    monkeypatch.setattr(solution, "solve", fake_solve)
    row = sweep.solve_member(0, "ac_mm_s2", 1.0, tiny.read_text(), tiny.name,
                             tol_km=1000.0, tol_m_s=5.0)
    assert seen[-1].tolerance.position_km == 1000.0 and seen[-1].tolerance.velocity_m_s == 5.0
    assert seen[-1].sail.ac_mm_s2 == 1.0
    assert row["converged"] is True and row["verified"] is False
    assert row["error"] == "not verified: position miss 1234 km > 1000 km"
    # Only the bound given is replaced; the other stays the problem file's (1e5 m/s).
    sweep.solve_member(0, "ac_mm_s2", 1.0, tiny.read_text(), tiny.name, tol_km=2.0)
    assert seen[-1].tolerance.position_km == 2.0 and seen[-1].tolerance.velocity_m_s == 1e5

    monkeypatch.setattr(solution, "solve",
                        lambda problem, polish=False: _Unverified(problem, "miss 2 au > 1 au"))
    row = sweep.solve_member(0, "ac_mm_s2", 1.0, tiny.read_text(), tiny.name)
    assert row["error"] == "not verified: miss 2 au > 1 au"
    result = {"rows": [row], "param": "ac_mm_s2", "objective_shown_as": [58.5, " d"]}
    header, line = sweep.table_csv(result).splitlines()
    cells = dict(zip(header.split(","), line.split(",")))
    assert cells["verified"] == "False"
    # The CSV reads in days (the factor the sweep records), the journal in the NLP's TU.
    assert float(cells["objective"]) == pytest.approx(5.0 * 58.5) and row["objective"] == 5.0
    assert cells["objective_unit"] == "d"


def test_bad_tolerance_is_one_line_exit_2_nothing_written(tiny, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["sweep", str(tiny), "--param", PARAM, "--tol-km", "0",
                     "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tolerance.position_km = 0.0 km is outside" in err
    assert cli.main(["sweep", str(tiny), "--param", PARAM, "--tol-m-s", "nan",
                     "--out", str(out)]) == 2
    assert "tolerance.velocity_m_s = nan m/s is outside" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_two_porkchop_cells_fly_from_porkchop_json_alone(tmp_path):
    """Each row of porkchop.json carries its flight as solution.json does: flown here by
    DOP853 on the Cartesian equations from the row's 3-D departure state with the row's
    pitch, clock and duration per segment, each verified cell ends at DE421's
    unprojected Mars at the row's arrival date within the problem's tolerance, with no
    solve."""
    from scipy.integrate import solve_ivp

    from esail_opt.app import porkchop
    from esail_opt.optimisation.problem_file import load_problem
    from test_calendar import jd_of
    from test_optimisation3d import AU_KM, TU_DAYS, de421_ecliptic, esail_rhs

    from conftest import PROBLEMS

    window = PROBLEMS / "earth_mars_window.py"
    cells = tmp_path / "cells"
    porkchop.write(porkchop.run(window, "2030-01-01:2030-05-02:2", workers=1,
                                cells_out=cells), tmp_path)
    rows = json.loads((tmp_path / "porkchop.json").read_text())["rows"]
    problem = load_problem(window)
    assert problem.three_d()
    assert [row["verified"] for row in rows] == [True, True]
    km_s = TU_DAYS * 86400 / AU_KM  # km/s to au/TU
    for row in rows:
        s = row["departure_state"]
        y = np.array([s["x_au"], s["y_au"], s["z_au"], s["vx_km_s"] * km_s,
                      s["vy_km_s"] * km_s, s["vz_km_s"] * km_s])
        for seg in row["schedule"]:
            dt = seg["duration_days"] / TU_DAYS
            y = solve_ivp(esail_rhs(problem.sail.ac, math.radians(seg["alpha_deg"]),
                                    math.radians(seg["clock_deg"])), (0, dt), y,
                          method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
        elapsed = sum(seg["duration_days"] for seg in row["schedule"])
        assert elapsed == pytest.approx(row["tof_days"], rel=1e-12)
        mars = de421_ecliptic("mars", jd_of(row["arrival_date"]))
        miss_km = np.linalg.norm(y[:3] - mars[:3]) * AU_KM
        assert miss_km <= problem.tolerance.position_km
        assert np.linalg.norm(y[3:] - mars[3:]) / km_s * 1e3 <= problem.tolerance.velocity_m_s
        # And the miss the row reports (CVODES's) is the one DOP853 finds.
        assert miss_km == pytest.approx(row["target_miss_r_km"], abs=1.0)
        # --cells-out: the cell's solution folder holds the same flight, verified.
        solved = json.loads((cells / porkchop.cell_folder(row) / "solution.json").read_text())
        assert solved["verified"]
        # (solution.json's rows add each segment's local error)
        assert [{k: seg[k] for k in mine} for seg, mine in
                zip(solved["schedule"], row["schedule"], strict=True)] == row["schedule"]
        assert solved["problem"]["departure_state"] == row["departure_state"]
        assert (cells / porkchop.cell_folder(row) / "schedule.csv").exists()


def test_the_sweep_figure_plots_no_value_for_a_member_with_no_answer():
    """Of a fixed-time sweep's members, a verified one is plotted at its a_c, one that
    converged without being verified as a red cross at its a_c, and one Ipopt did not
    converge on only marked at its parameter: where Ipopt stopped is no answer.  The
    time of flight, the parameter here, gets no panel of its own; the miss panel has the
    tolerance."""
    def row(value, objective, converged, error):
        out = {name: None for name in sweep.CSV_FIELDS}
        out.update(value=value, objective=objective, converged=converged, error=error,
                   tof_days=value, target_miss_r_km=2e3)
        return out

    rows = [row(560.0, 0.7, False, "not converged: Ipopt Infeasible_Problem_Detected"),
            row(600.0, 0.24, True, "not verified: 12000 km from the target"),
            row(620.0, 0.14, True, None)]
    fig = sweep.figure({"problem": "m", "field": "objective.tof_days", "param": "tof_days",
                        "unit": "days", "failed": 2, "rows": rows,
                        "objective_shown_as": [6.0, " mm/s^2"],
                        "tolerance": {"position_km": 1e4, "velocity_m_s": 10.0}})
    objective, misses = fig.axes
    assert objective.get_ylabel() == "a_c needed [mm/s^2]"
    lines = {line.get_label(): line for line in objective.get_lines()}
    assert list(lines["verified"].get_xdata()) == [620.0]
    assert np.allclose(lines["verified"].get_ydata(), [0.84])
    assert list(lines["converged, not verified"].get_xdata()) == [600.0]
    assert np.allclose(lines["converged, not verified"].get_ydata(), [1.44])
    assert list(lines["no answer (not converged)"].get_xdata()) == [560.0]
    assert [line.get_ydata()[0] for line in misses.get_lines()
            if line.get_label() == "tolerance"] == [1e4]


def test_a_member_with_no_point_says_where_the_feasible_begins():
    """A member too short to fly says, after Ipopt's status, what its own solve found:
    the shortest feasible flight from its departure, as `esail-opt solve` says it."""
    from types import SimpleNamespace

    near = SimpleNamespace(departure_date="2033-05-01T00:00:00", tof_days=590.9,
                           ac_mm_s2_required=2.285, verified=True, infeasible_tof_days=587.2)
    sol = SimpleNamespace(converged=False, status="Infeasible_Problem_Detected",
                          tof_days=580.0, objective=0.5, iterations=300, polish=None,
                          flight_verified=False, nearest_feasible=near,
                          verification=SimpleNamespace(target_miss_r_km=None,
                                                       target_miss_v_m_s=None, error=None))
    row = sweep._empty_row(0, 580.0)
    sweep._fill(row, sol)
    assert row["error"] == ("not converged: Ipopt Infeasible_Problem_Detected; the shortest "
                            "flight found feasible departing 2033-05-01T00:00:00 takes 590.9 d "
                            "at a_c 2.285 mm/s^2 (verified; none found at 587.2 d)")


def test_a_sweep_of_the_time_of_flight_names_its_columns_once():
    """Sweeping ``tof_days`` gives the asked value its own column beside the flown
    ``tof_days``: no header names a column twice (a CSV reader would rename one)."""
    row = {name: None for name in sweep.CSV_FIELDS}
    row.update(index=0, value=650.0, converged=True, tof_days=650.0, objective=0.15)
    result = {"param": "tof_days", "objective_shown_as": [6.0, "mm/s^2"], "rows": [row]}
    header, line = sweep.table_csv(result).splitlines()
    names = header.split(",")
    assert len(names) == len(set(names))
    assert names[1] == "tof_days_asked" and "tof_days" in names
    cells = dict(zip(names, line.split(",")))
    assert (cells["tof_days_asked"], cells["objective"], cells["objective_unit"]) == \
        ("650", "0.9", "mm/s^2")


@pytest.mark.slow
def test_a_sweep_flies_each_member_under_the_wind_and_its_journal_knows_it(tmp_path):
    """``--robust``: each verified member of the 3-D Earth-Mars rendezvous is flown under
    the wind, its row says how (guided below open loop, the CVODES checks agreeing),
    the figure has the wind's panel under the a_c and the miss (the time of flight is
    the parameter), and a journal of it does not resume another sweep."""
    problem = REPO / "problems" / "earth_mars_min_ac.py"
    out = tmp_path / "windy"
    result = sweep.run(problem, "tof_days=650:660:2", workers=1, out_dir=out, robust_runs=12)
    assert result["failed"] == 0 and result["robust_runs"] == 12
    for row in result["rows"]:
        assert row["robust_verified"] is True
        assert row["robust_guided_p95_km"] < row["robust_open_p95_km"]
        assert 0.0 <= row["robust_guided_within"] <= 1.0
    labels = [ax.get_ylabel() for ax in sweep.figure(result).axes]
    assert labels[:2] == ["a_c needed [mm/s^2]", "flown target miss [km]"]
    assert len(labels) == 3 and labels[2].startswith("arrival miss under wind")
    journal = (out / sweep.JOURNAL).read_text()
    with pytest.raises(InputError, match="robust_runs is 12, not None"):
        sweep.run(problem, "tof_days=650:660:2", workers=1, out_dir=out, resume=True)
    assert (out / sweep.JOURNAL).read_text() == journal


def test_a_windy_sweep_of_a_planar_problem_is_one_line_exit_2(tmp_path, capsys):
    code = cli.main(["sweep", str(REPO / "problems" / "earth_mars_min_ac_planar.py"),
                     "--param", "tof_days=650:660:2", "--robust", "10",
                     "--out", str(tmp_path / "w")])
    assert code == cli.EXIT_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "three-dimensional" in err[0]
