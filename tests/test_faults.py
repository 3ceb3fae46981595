"""Faults that heal or say what to do: a damaged compile cache, SIGTERM, a lost Dask
cluster, outputs that cannot be written or are killed while written, a torn journal and
a problem file that exits.

Each test drives the command line (or the one function at fault) the way the fault
happens in use: a library cut short on disk, a signal from outside, a scheduler process
killed, a path under a regular file, a SIGKILL at a random moment of a write.
"""

import contextlib
import errno
import functools
import json
import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from esail_opt.app import cli, engine, sweep
from esail_opt.runtime.journal import Journal
from esail_opt.runtime import files, pool
from esail_opt.errors import InputError, OutputError

from conftest import PROBLEMS, REPO, TINY_PROBLEM as TINY


def _journal(path, header):
    """The sweep's journal at ``path`` under ``header``, as the sweep's run makes it."""
    return Journal(path, header, sweep.SweepRow, len(header["values"]),
                   functools.partial(sweep.belongs, header["values"]), engine.invalid_row)



def _env(**extra):
    env = dict(os.environ, PYTHONPATH=str(REPO), **extra)
    return env


def _cli(*args, env=None, **kw):
    return subprocess.run([sys.executable, "-m", "esail_opt.app.cli", *map(str, args)],
                          capture_output=True, text=True, env=env or _env(), timeout=600,
                          **kw)


def _messages(stderr):
    """stderr's lines without the progress lines (which end in ' ...')."""
    return [ln for ln in stderr.splitlines() if ln.strip() and not ln.endswith(" ...")]


# ---------------------------------------------------------------- 1. compile cache


@pytest.mark.slow
def test_a_truncated_cached_library_is_rebuilt_with_one_line(tmp_path):
    """A cached library cut to half its size (a full disk, a copy cut off) is never
    loaded: the next process says so in one line, compiles it again, and its compiled
    arc gives the virtual machine's numbers."""
    cache = tmp_path / "cache"
    child = textwrap.dedent(f"""
        import logging, os
        import numpy as np
        os.environ["ESAIL_OPT_CACHE"] = {str(cache)!r}
        logging.basicConfig(level=logging.INFO, format="%(message)s")
        from esail_opt.propagation.compiled import compiled
        from esail_opt.propagation.rectified import panel_function
        panel = panel_function()
        fast = compiled(panel)
        point = [np.array([1.1, 0.3, 0.05, 0.98, 2.0]), 0.17, 0.7, 0.2, 0.9]
        worst = max(float(np.max(np.abs(np.array(a) - np.array(b))))
                    for a, b in zip(fast.call(point), panel.call(point)))
        print(fast.class_name(), worst)
    """)
    env = {k: v for k, v in _env().items() if k != "ESAIL_OPT_COMPILE"}
    first = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True,
                           env=env, timeout=600)
    assert first.returncode == 0, first.stderr[-2000:]
    (library,) = cache.glob("*.so")
    size = library.stat().st_size
    with open(library, "r+b") as handle:
        handle.truncate(size // 2)
    second = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True,
                            env=env, timeout=600)
    assert second.returncode == 0, second.stderr[-2000:]  # not -SIGBUS (exit 135)
    kind, difference = second.stdout.split()
    assert kind == "External" and float(difference) < 1e-12
    damaged = [ln for ln in second.stderr.splitlines() if "damaged" in ln]
    assert len(damaged) == 1 and "checksum does not match" in damaged[0]
    assert library.stat().st_size == size
    assert not list(cache.glob(".build-*"))


def test_an_unwritable_cache_is_one_plain_line_and_the_vm(tmp_path, monkeypatch, caplog):
    """A cache folder under a regular file cannot be created: one line naming the
    cache and what to do, the Function stays on the virtual machine."""
    import logging

    from esail_opt.propagation import compiled as cc
    from esail_opt.propagation.rectified import panel_function

    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(blocker / "cache"))
    monkeypatch.delenv("ESAIL_OPT_COMPILE", raising=False)
    monkeypatch.setattr(cc, "_loaded", {})
    panel = panel_function()
    with caplog.at_level(logging.INFO, logger="esail_opt"):
        assert cc.compiled(panel) is panel
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1
    assert "cannot compile into the cache" in lines[0] and "ESAIL_OPT_CACHE" in lines[0]
    assert "\n" not in lines[0]


def test_a_cache_without_space_is_not_tried_again(tmp_path, monkeypatch, caplog):
    """After a compile ran out of space the marker keeps later processes from
    compiling again while the disk stays as full; one line says why."""
    import logging

    from esail_opt.propagation import compiled as cc
    from esail_opt.propagation.rectified import panel_function

    cache = tmp_path / "cache"
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(cache))
    monkeypatch.delenv("ESAIL_OPT_COMPILE", raising=False)
    monkeypatch.setattr(cc, "_loaded", {})
    builds = []

    def full_disk(fun, compiler, target, links=(), *rest):
        builds.append(target)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(cc, "_build", full_disk)
    panel = panel_function()
    with caplog.at_level(logging.INFO, logger="esail_opt"):
        assert cc.compiled(panel) is panel
        monkeypatch.setattr(cc, "_loaded", {})  # a later process
        assert cc.compiled(panel) is panel
    assert len(builds) == 1
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 2
    assert "its disk is full" in warnings[0]
    assert "ran out of space" in warnings[1] and "not been freed" in warnings[1]


# ---------------------------------------------------------------- 2. SIGTERM

EVERY_ITERATION = ("import sys; from esail_opt.optimisation import ipopt; "
                   "ipopt.PROGRESS_SECONDS = 0.0; from esail_opt.app.cli import main; "
                   "sys.exit(main(sys.argv[1:]))")


def test_sigterm_stops_a_solve_with_143_and_leaves_the_old_set(tmp_path):
    """SIGTERM while Ipopt iterates: exit 143 with one line, the folder still holding
    the previous run's set untouched, no staging folder or temporary file anywhere."""
    out = tmp_path / "out"
    out.mkdir()
    old = {"solution.json": '{"old": true}\n', "timeline.png": "old png"}
    for name, text in old.items():
        (out / name).write_text(text)
    proc = subprocess.Popen(
        [sys.executable, "-c", EVERY_ITERATION, "solve",
         str(PROBLEMS / "earth_mars_min_time.py"), "--out", str(out)],
        stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
        env=_env(ESAIL_OPT_COMPILE="0"))
    iterating = False
    try:
        for line in proc.stderr:
            if "Ipopt iteration" in line:
                iterating = True
                break
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=30)
        rest = proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
    assert iterating
    assert code == 143
    lines = _messages(rest)
    assert lines == ["esail-opt solve: stopped by SIGTERM; nothing half-done was written"]
    assert {p.name: p.read_text() for p in out.iterdir()} == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_ctrl_c_during_a_cvodes_flight_is_an_interrupt_not_a_failed_flight():
    """SIGINT while CVODES flies (the verifier's flights, the error control's segments):
    KeyboardInterrupt once the flight returns, not a SimulationError, which the
    verification would report as a flight that failed (exit 1 instead of 130)."""
    import threading

    import numpy as np

    from esail_opt.propagation.simulate import simulate

    n = 6000  # about a second of CVODES at 1e-13
    # The suite may have been started with SIGINT ignored (a background job, nohup):
    # the test sets Python's own handler, and checks that the flight gives it back.
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            simulate([1.0, 0.0, 0.0, 1.0], np.zeros(n), np.ones(n), 1e-3, samples=4,
                     tol=1e-13)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, inherited)


def _children(pid):
    """Pids of every live descendant of ``pid``, from /proc."""
    parents = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
                parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def _alive(pid):
    """Running and not a zombie."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _wait_for_workers(proc, count, deadline):
    while time.monotonic() < deadline and proc.poll() is None:
        workers = [p for p in _children(proc.pid)
                   if b"spawn_main" in Path(f"/proc/{p}/cmdline").read_bytes()]
        if len(workers) >= count:
            return workers
        time.sleep(0.1)
    return []


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGKILL])
def test_a_pool_sweeps_workers_never_outlive_it(tmp_path, signum):
    """SIGTERM to a process-pool sweep: exit 143, one line, every worker gone.  SIGKILL
    (no clean-up at all): the workers end by themselves within seconds."""
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "esail_opt.app.cli", "sweep", str(problem), "--param",
         "segments=6:48:8", "--workers", "2", "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        env=_env(ESAIL_OPT_COMPILE="0"))
    try:
        workers = _wait_for_workers(proc, 2, time.monotonic() + 120)
        assert workers, "the pool never started two workers"
        time.sleep(1.0)  # the workers are solving
        proc.send_signal(signum)
        proc.wait(timeout=30)
        stderr = proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.2)
    assert not [p for p in workers if _alive(p)], "a worker outlived the sweep"
    if signum == signal.SIGTERM:
        assert proc.returncode == 143
        assert _messages(stderr)[-1] == ("esail-opt sweep: stopped by SIGTERM; nothing "
                                         "half-done was written")
        assert not (out / "sweep.csv").exists()
    else:
        assert proc.returncode == -signal.SIGKILL


# ---------------------------------------------------------------- 3. Dask


def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_scheduler_is_one_line_within_seconds(tmp_path):
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    start = time.monotonic()
    run = _cli("sweep", problem, "--param", "ac_mm_s2=0.5:1:2", "--scheduler",
               f"tcp://127.0.0.1:{_free_port()}", "--out", tmp_path / "out")
    elapsed = time.monotonic() - start
    print(f"unreachable scheduler reported after {elapsed:.1f} s")
    assert run.returncode == 2
    lines = _messages(run.stderr)
    assert len(lines) == 1 and "cannot be reached within 5 s" in lines[0]


@pytest.mark.slow
def test_a_dask_sweep_whose_scheduler_dies_ends_with_one_line(tmp_path):
    """The scheduler process killed mid-sweep: the sweep ends within 60 s with one line
    naming the journal, which keeps the finished members; --resume on a new cluster
    runs only the others."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = subprocess.Popen([sys.executable, "-c",
                                  "from distributed.cli.dask_scheduler import main; main()",
                                  "--host", "127.0.0.1", "--port", str(port),
                                  "--no-dashboard"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 env=_env())
    worker = subprocess.Popen([sys.executable, "-c",
                               "from distributed.cli.dask_worker import main; main()",
                               address, "--nthreads", "1", "--nworkers", "1",
                               "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              env=_env(ESAIL_OPT_COMPILE="0"))
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    out = tmp_path / "out"
    try:
        sweep_proc = subprocess.Popen(
            [sys.executable, "-m", "esail_opt.app.cli", "sweep", str(problem), "--param",
             "segments=6:36:6", "--scheduler", address, "--out", str(out)],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            env=_env(ESAIL_OPT_COMPILE="0"))
        journal = out / sweep.JOURNAL
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and sweep_proc.poll() is None:
            if journal.exists() and len(journal.read_text().splitlines()) >= 2:
                break
            time.sleep(0.1)
        assert sweep_proc.poll() is None, sweep_proc.stderr.read()
        scheduler.kill()
        killed = time.monotonic()
        sweep_proc.wait(timeout=60)
        ended_after = time.monotonic() - killed
        stderr = sweep_proc.stderr.read()
    finally:
        for p in (scheduler, worker):
            if p.poll() is None:
                p.kill()
        if sweep_proc.poll() is None:
            sweep_proc.kill()
    print(f"sweep ended {ended_after:.1f} s after the scheduler was killed")
    assert sweep_proc.returncode == 1
    lines = [ln for ln in _messages(stderr) if not ln.startswith("esail-opt sweep: [")]
    assert len(lines) == 1, stderr
    assert "lost the Dask scheduler" in lines[0] and "--resume" in lines[0]
    assert "Traceback" not in stderr
    kept = [json.loads(ln) for ln in journal.read_text().splitlines()[1:]]
    assert kept and all(row["converged"] for row in kept)
    # The rest on a local pool (the same journal resumes on any executor).
    done = _cli("sweep", problem, "--param", "segments=6:36:6", "--workers", "1", "--out",
                out, "--resume", env=_env(ESAIL_OPT_COMPILE="0"))
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads((out / "sweep.json").read_text())
    assert sorted(result["resumed"]) == sorted(row["index"] for row in kept)
    assert sorted(result["resumed"] + result["solved"]) == list(range(6))



def test_a_dask_client_closed_mid_run_ends_the_run_as_cluster_lost(tmp_path):
    """Dask's client closes itself a few seconds after its scheduler dies; a job lost
    with it and submitted again then meets a closed client, which must read as the
    lost cluster, not a traceback."""
    class ClosedClient:
        status = "closed"

        def get_executor(self, pure):
            return self

        def submit(self, *args):
            raise RuntimeError("Client is closed. Can't send update-graph message.")

    runner = pool._Runner(print, {0: ()}, None, None, 1, ClosedClient(), 0,
                              "tcp://127.0.0.1:1")
    with pytest.raises(pool.ClusterLost, match="lost the Dask scheduler"):
        runner._submit([0], str(tmp_path))


def _sends_two_partials(i):
    """A pool job that sends two partial results before it returns (a scan's forward pass)."""
    pool.send_partial(("first", i))
    pool.send_partial(("second", i))
    return ("result", i)


def test_a_pool_job_sends_its_partials_before_its_result():
    """What a local pool's job sends reaches ``on_partial`` in order, before its result;
    outside a pool, sending is nothing."""
    heard = []
    pool.run(_sends_two_partials, {0: (), 1: ()}, lambda i, value: heard.append(value),
                 lambda i, message: heard.append(("failed", message)), workers=1,
                 on_partial=heard.append)
    assert sorted(heard) == sorted((what, i) for i in (0, 1)
                                   for what in ("first", "second", "result"))
    for i in (0, 1):
        assert heard.index(("first", i)) < heard.index(("second", i)) < heard.index(
            ("result", i))
    assert _sends_two_partials(5) == ("result", 5)


# ---------------------------------------------------------------- 4. outputs


@pytest.mark.parametrize("name, message", [
    ("x" * 300, "bytes long"),
    ("bad\0name", "NUL"),
    ("..", "is not a folder name"),
])
def test_an_unsafe_problem_name_is_refused_before_the_solve(tmp_path, name, message):
    problem = tmp_path / "p.py"
    problem.write_text(TINY.format(name=name))
    run = _cli("solve", problem, cwd=tmp_path)
    assert run.returncode == 2
    lines = _messages(run.stderr)
    assert len(lines) == 1 and message in lines[0] and "problem name" in lines[0], lines
    assert "Ipopt" not in run.stderr and not (tmp_path / "results").exists()


def test_an_out_under_a_regular_file_fails_before_the_solve(tmp_path):
    """``--out`` under a regular file: exit 3 (not 1, "not verified"), one line, and no
    solve (no progress line) -- the same for sweep and search."""
    problem = tmp_path / "p.py"
    problem.write_text(TINY.format(name="tiny"))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for command in (["solve", problem], ["search", problem],
                    ["sweep", problem, "--param", "ac_mm_s2=0.5:1:2"]):
        run = _cli(*command, "--out", blocker / "out", env=_env(ESAIL_OPT_COMPILE="0"))
        assert run.returncode == 3, (command, run.stderr)
        lines = _messages(run.stderr)
        assert len(lines) == 1 and "is a file, not a folder" in lines[0], lines
        assert "Ipopt" not in run.stderr and "[1/2]" not in run.stderr
    assert blocker.read_text() == "x"


def test_a_full_disk_while_writing_keeps_the_old_set(tmp_path, monkeypatch):
    """ENOSPC from the PNG writer: one-line OutputError, the folder keeps the previous
    set whole, no staging folder is left; the command line maps it to exit 3."""
    from esail_opt.app.solution import Solution

    source = next(REPO.glob("results/earth_venus_min_time/solution.json"), None)
    if source is None:
        pytest.skip("no shipped solution.json")
    sol = Solution.load(source)
    out = tmp_path / "out"
    sol.write(out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    write_bytes = Path.write_bytes

    def no_space(self, data):
        if self.suffix == ".png":  # a figure's bytes find the disk full
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return write_bytes(self, data)

    monkeypatch.setattr(Path, "write_bytes", no_space)
    with pytest.raises(OutputError, match="No space left on device") as err:
        sol.write(out)
    assert "\n" not in str(err.value) and "free some space" in str(err.value)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]

    # The command line: the same fault is one line and exit 3 (a stand-in solve).
    from esail_opt.app import solution

    monkeypatch.setattr(solution, "solve_with_nearest", lambda problem, **kw: (sol, None))
    problem = tmp_path / "p.py"
    problem.write_text(TINY.format(name="tiny"))
    assert cli.main(["solve", str(problem), "--out", str(out)]) == cli.EXIT_OUTPUT == 3
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    problem.unlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_outputs_follow_the_umask(tmp_path):
    """Files 0666 and folders 0777 less the umask, as any program's; not 0600."""
    code = textwrap.dedent(f"""
        import os
        os.umask(0o027)
        from esail_opt.app.outputs import write_json
        from esail_opt.runtime.files import atomic_path, publish
        with publish({str(tmp_path / 'out')!r}) as stage:
            write_json(stage / "a.json", {{"x": 1}})
            (stage / "b.csv").write_text("b")
        with atomic_path({str(tmp_path / 'one.json')!r}) as tmp:
            tmp.write_text("{{}}")
    """)
    subprocess.run([sys.executable, "-c", code], check=True, env=_env())
    modes = {p.name: p.stat().st_mode & 0o777 for p in
             [tmp_path / "out", *(tmp_path / "out").iterdir(), tmp_path / "one.json"]}
    assert modes == {"out": 0o750, "a.json": 0o640, "b.csv": 0o640, "one.json": 0o640}


WRITER = textwrap.dedent("""
    import sys, time
    from esail_opt.runtime.files import publish
    target, run_id = sys.argv[1], sys.argv[2]
    print("start", flush=True)
    with publish(target, family=[f"part{i}.txt" for i in range(8)]) as stage:
        for i in range(8):
            (stage / f"part{i}.txt").write_text(run_id * 2000)
            time.sleep(0.05)
    print("done", flush=True)
""")


def test_a_kill_at_any_moment_of_a_write_never_leaves_a_mixed_folder(tmp_path):
    """SIGKILL a writer of an 8-file set at random moments, 25 times over one folder:
    after each, every file in the folder carries one run's id (the previous complete
    run's, or the killed one's if it had finished), and a user's file stays.

    The writer sleeps 0.4 s in all after it says "start", so a kill within 0.35 s of
    that line falls inside its writes however slow the machine: the folder must then
    hold the previous set.  Every fifth writer is killed only after it says "done",
    and the rest at random up to just after the swap."""
    target = tmp_path / "out"
    rng = random.Random(7)
    subprocess.run([sys.executable, "-c", WRITER, str(target), "A"], check=True, env=_env())
    (target / "notes.txt").write_text("mine")
    complete = "A"
    for k in range(25):
        run_id = chr(ord("B") + k)
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(target), run_id],
                                stdout=subprocess.PIPE, text=True, env=_env())
        assert proc.stdout.readline().strip() == "start"
        wait = None if k % 5 == 4 else rng.uniform(0.0, 0.5)
        if wait is None:
            assert proc.stdout.readline().strip() == "done"
        else:
            time.sleep(wait)
        proc.kill()
        out = proc.stdout.read()
        proc.wait()
        ids = {(target / f"part{i}.txt").read_text()[:1] for i in range(8)}
        assert len(ids) == 1, (k, ids)
        (seen,) = ids
        assert seen in (complete, run_id)
        if wait is None or out.strip() == "done":
            assert seen == run_id
        elif wait < 0.35:
            assert seen == complete, (k, wait)
        complete = seen
        assert (target / "notes.txt").read_text() == "mine"
    # The next writer removes the staging folders of the killed ones.
    subprocess.run([sys.executable, "-c", WRITER, str(target), "Z"], check=True, env=_env())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_check_output_dir_refuses_what_cannot_be_a_set(tmp_path):
    for bad in (tmp_path / "..", f"{tmp_path}/.", ".", "a\0b", tmp_path / ("n" * 256)):
        with pytest.raises(InputError):
            files.check_output_dir(bad)
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputError, match="a file of that name is in the way"):
        files.check_output_dir(tmp_path / "f")
    assert files.check_output_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_the_output_check_creates_no_parent_folders(tmp_path):
    """The check passes a folder whose parents do not exist yet, and creates none of
    them (nor leaves its probe): they are made when the run's files are written."""
    (tmp_path / "kept").mkdir()
    for out in (tmp_path / "a" / "b" / "c", tmp_path / "kept" / "x" / "y"):
        assert files.check_output_dir(out) == out
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["kept"]


def test_a_refused_run_leaves_no_parent_folders_of_out(tmp_path, capsys):
    """A run refused after the output check (here, a bad --tof) leaves the file
    system as it found it: no parent folder of --out is created."""
    out = tmp_path / "a" / "b" / "c"
    assert cli.main(["porkchop", str(WINDOW), "--depart", "2030-01-01:2030-03-01:2",
                     "--tof", "-100:850:2", "--out", str(out)]) == 2
    assert "tof START" in capsys.readouterr().err
    assert not (tmp_path / "a").exists()


# ---------------------------------------------------------------- 5. journal

HEADER = {"journal": "esail-opt sweep", "problem": "p", "source_sha256": "abc",
          "param": "ac_mm_s2", "values": [0.5, 1.0, 1.5], "polish": False,
          "tolerance": {"position_km": 1e4, "velocity_m_s": 10.0}}


def test_a_torn_journal_line_is_cut_off_before_the_next_row(tmp_path):
    """A row torn mid-append is ignored and cut off the file, so the next row starts a
    line of its own and a second resume keeps it."""
    path = tmp_path / sweep.JOURNAL
    journal = _journal(path, HEADER)
    journal.open(resume=False)
    journal.append({**sweep._empty_row(0, 0.5), "converged": True})
    with open(path, "a") as handle:
        handle.write('{"index": 1, "value": 1.0, "conv')
    kept = _journal(path, HEADER).open(resume=True)
    assert list(kept) == [0]
    _journal(path, HEADER).append({**sweep._empty_row(1, 1.0), "converged": True})
    lines = path.read_text().splitlines()
    assert len(lines) == 3 and all(json.loads(line) for line in lines)
    assert sorted(_journal(path, HEADER).open(resume=True)) == [0, 1]


@pytest.mark.parametrize("bad, message", [
    (b'{"index": 0, garbage\n', "line 2 is not JSON"),
    (b'{"index": 0, "value": "\xff\xfe"}\n', "line 2 is not UTF-8"),
])
def test_an_unreadable_journal_line_is_one_error_naming_file_and_line(tmp_path, bad,
                                                                      message):
    path = tmp_path / sweep.JOURNAL
    path.write_bytes((json.dumps(HEADER) + "\n").encode() + bad)
    with pytest.raises(InputError) as err:
        _journal(path, HEADER).open(resume=True)
    assert message in str(err.value) and str(path) in str(err.value)
    assert "\n" not in str(err.value)


def test_a_failed_append_leaves_no_half_line(tmp_path, monkeypatch):
    path = tmp_path / sweep.JOURNAL
    journal = _journal(path, HEADER)
    journal.open(resume=False)
    journal.append({**sweep._empty_row(0, 0.3), "converged": True})  # the fresh one's first
    before = path.read_bytes()
    real = os.write

    def half(fd, data):
        real(fd, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "write", half)
    with pytest.raises(OutputError, match="No space left"):
        journal.append({**sweep._empty_row(0, 0.5), "converged": True})
    monkeypatch.setattr(os, "write", real)
    assert path.read_bytes() == before


def test_a_fresh_scan_replaces_the_old_journal_only_with_its_first_row(tmp_path):
    """A scan started afresh over a folder holding another scan's journal leaves that
    journal as it is until its own first row (the old outputs beside it still match
    it, and --resume can continue it); then its header and the row replace it whole.
    A fresh scan that ends with no row written leaves its header."""
    path = tmp_path / sweep.JOURNAL
    old = _journal(path, {**HEADER, "values": [9.0]})
    old.open(resume=False)
    old.append({**sweep._empty_row(0, 9.0), "converged": True})
    before = path.read_bytes()
    fresh = _journal(path, HEADER)
    assert fresh.open(resume=False) == {}
    assert path.read_bytes() == before
    fresh.append({**sweep._empty_row(0, 0.5), "converged": True})
    assert fresh.read(resume=True)[0]["value"] == 0.5
    assert json.loads(path.read_text().splitlines()[0]) == json.loads(json.dumps(HEADER))
    empty = _journal(path, {**HEADER, "values": [7.0]})
    empty.open(resume=False)
    empty.close()
    assert [json.loads(line) for line in path.read_text().splitlines()] == [
        json.loads(json.dumps({**HEADER, "values": [7.0]}))]


def test_a_verified_row_sent_before_its_job_ends_is_journaled_and_kept(tmp_path):
    """A row a job sends before ending is journaled at once if it is verified (an
    interrupted job keeps it), not if it failed (a resumed run solves it again); the
    job's end journals only what changed, and of two rows of one index the later is
    read.  A job that dies keeps the verified rows it sent."""
    path = tmp_path / sweep.JOURNAL
    journal = _journal(path, HEADER)
    journal.open(resume=False)

    def row(i, **fields):
        return {**sweep._empty_row(i, HEADER["values"][i]), "converged": True,
                "tof_days": 300.0, **fields}

    scan = engine.Scan(journal_name=sweep.JOURNAL, header=HEADER, row_type=sweep.SweepRow,
                       count=3, function=None, jobs={0: ([0, 1], ()), 1: ([2], ())},
                       failed_row=lambda i, message: row(i, error=message))
    rows = engine._Rows(scan, {}, journal, progress=None)
    rows.partial(row(0, verified=True, objective=2.0))
    rows.partial(row(1, verified=False))
    assert list(journal.read(resume=True)) == [0]  # what an interrupt now leaves
    rows.finished(0, [row(0, verified=True, objective=2.0), row(1, verified=False)])
    assert len(path.read_text().splitlines()) == 3  # the header, row 0 once, row 1
    rows.finished(0, [row(0, verified=True, objective=1.5)])  # a repair pass improved it
    assert journal.read(resume=True)[0]["objective"] == 1.5
    rows.partial(row(2, verified=True, objective=3.0))
    rows.unfinished(1, "worker lost")
    assert rows.rows[2]["objective"] == 3.0 and rows.rows[2]["error"] is None


# ---------------------------------------------------------------- 6. problem files


@pytest.mark.parametrize("call", ["sys.exit(0)", "sys.exit()", "raise SystemExit('bye')"])
def test_a_problem_file_that_exits_is_an_input_error(tmp_path, call):
    problem = tmp_path / "exits.py"
    problem.write_text(f"import sys\n{call}\n")
    run = _cli("solve", problem, "--out", tmp_path / "out")
    assert run.returncode == 2
    lines = _messages(run.stderr)
    assert len(lines) == 1 and "exits.py: the file called sys.exit(" in lines[0], lines
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- the process's end


def _console(tmp_path, *argv):
    """``cli.console`` on ``argv`` in a process of its own, its output on pipes; a line
    printed after it would say it returned."""
    script = ("import atexit, sys; from esail_opt.app import cli; "
              "atexit.register(lambda: sys.stderr.write('exit handler ran\\n')); "
              f"sys.argv = ['esail-opt', *{list(argv)!r}]; "
              "cli.console(); print('console returned')")
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=_env(), timeout=120, cwd=tmp_path)


def test_the_process_ends_with_mains_status_and_its_output_whole(tmp_path):
    """``esail-opt`` (``cli.console``) ends the process with the run's status, after the
    exit handlers, and with what the command printed on a pipe flushed."""
    failed = _console(tmp_path, "solve", str(tmp_path / "missing.py"))
    assert failed.returncode == 2
    assert "missing.py" in failed.stderr and "exit handler ran" in failed.stderr
    assert "console returned" not in failed.stdout
    out = tmp_path / "flight.json"
    flown = _console(tmp_path, "propagate", "--ac", "1", "--alpha", "30", "--years", "0.1",
                     "--method", "closed-form", "--out", str(out))
    assert flown.returncode == 0, flown.stderr
    lines = flown.stdout.splitlines()
    assert len(lines) == 2 and lines[0].startswith("closed_form  end: t = 36.5")
    assert lines[1] == f"wrote {out}"
    assert json.loads(out.read_text())["closed_form"]["t_days"]


def test_a_killed_runs_scratch_folder_is_removed_by_the_next_run(tmp_path):
    """SIGKILL leaves a sweep's scratch folder behind; the next run removes it, and
    leaves those of live runs and folders it cannot attribute alone."""
    from esail_opt.runtime import processes
    from esail_opt.runtime.pool import SCRATCH_PREFIX

    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()  # a pid that no longer exists
    dead = tmp_path / f"{SCRATCH_PREFIX}{ended.pid}_k1"
    live = tmp_path / f"{SCRATCH_PREFIX}{os.getpid()}_k2"
    other = tmp_path / f"{SCRATCH_PREFIX}notapid_k3"
    for folder in (dead, live, other):
        (folder / "1").mkdir(parents=True)
        (folder / "1" / "0").write_text("12345")
    processes.remove_dead(tmp_path, SCRATCH_PREFIX)
    assert not dead.exists()
    assert live.exists() and other.exists()


# ---------------------------------------------------------------- 7. refused before any change
#
# Every check that can refuse a scan (the options, the scheduler, a journal --resume
# cannot continue, a row of it) is made before anything on disk changes.

WINDOW = PROBLEMS / "earth_mars_window.py"


def _scan_command(kind, problem, out, *extra):
    if kind == "sweep":
        return ("sweep", problem, "--param", "ac_mm_s2=0.5:1.5:3", "--out", out, *extra)
    return ("porkchop", WINDOW, "--depart", "2030-01-01:2030-03-01:2", "--out", out, *extra)


def _old_set(out, kind):
    """A folder holding an earlier scan: a journal of five lines and its outputs."""
    out.mkdir()
    rows = [json.dumps({"journal": f"esail-opt {kind}", "problem": "earlier"})]
    rows += [json.dumps({"index": i, "value": 0.1 * i}) for i in range(4)]
    (out / f"{kind}.jsonl").write_text("\n".join(rows) + "\n")
    for name in (f"{kind}.csv", f"{kind}.json", f"{kind}.png"):
        (out / name).write_text(f"the earlier {name}\n")
    return {p.name: p.read_bytes() for p in out.iterdir()}


@pytest.mark.parametrize("kind", ["sweep", "porkchop"])
def test_an_unreachable_scheduler_leaves_the_journal_and_outputs_as_they_were(tmp_path,
                                                                             kind):
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    out = tmp_path / "out"
    before = _old_set(out, kind)
    run = _cli(*_scan_command(kind, problem, out, "--scheduler",
                              f"tcp://127.0.0.1:{_free_port()}"))
    assert run.returncode == 2
    assert len(_messages(run.stderr)) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_refused_resume_leaves_the_torn_line_in_place(tmp_path):
    """--resume of another problem's journal is refused, and the row torn at its end
    (which an accepted resume would cut off) is still there."""
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    out = tmp_path / "out"
    out.mkdir()
    journal = out / sweep.JOURNAL
    journal.write_text(json.dumps({**HEADER, "problem": "another"}) + "\n"
                       + json.dumps(sweep._empty_row(0, 0.5)) + "\n"
                       + '{"index": 1, "value": 1.0, "conv')
    before = journal.read_bytes()
    run = _cli(*_scan_command("sweep", problem, out, "--resume"))
    assert run.returncode == 2
    lines = _messages(run.stderr)
    assert len(lines) == 1 and "belongs to another sweep" in lines[0]
    assert journal.read_bytes() == before


def test_a_journal_holding_part_of_its_header_is_not_cut_to_nothing(tmp_path):
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    out = tmp_path / "out"
    out.mkdir()
    journal = out / sweep.JOURNAL
    journal.write_text(json.dumps(HEADER)[:40])  # the first write was cut off
    run = _cli(*_scan_command("sweep", problem, out, "--resume"))
    assert run.returncode == 2
    assert "is not a sweep journal" in _messages(run.stderr)[0]
    assert journal.read_text() == json.dumps(HEADER)[:40]


@pytest.mark.parametrize("kind", ["sweep", "porkchop"])
@pytest.mark.parametrize("dangling", [False, True])
def test_a_symlinked_out_is_refused_before_anything_runs(tmp_path, kind, dangling):
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    target = tmp_path / "elsewhere"
    if not dangling:
        target.mkdir()
    link = tmp_path / "out"
    link.symlink_to(target)
    run = _cli(*_scan_command(kind, problem, link))
    assert run.returncode == 2
    lines = _messages(run.stderr)
    assert len(lines) == 1 and "--out" in lines[0] and "symbolic link" in lines[0], lines
    assert not target.exists() if dangling else not list(target.iterdir())


@pytest.mark.parametrize("row, message", [
    ({"tof_days": "abc"}, "line 2 is not a valid row: tof_days = 'abc' is not a number"),
    ({"converged": "yes"}, "line 2 is not a valid row: converged = 'yes' is not true or false"),
    ({"index": 1.5}, "line 2 is not a valid row: index = 1.5 is not a whole number"),
])
def test_a_bad_journal_row_is_one_line_naming_its_line(tmp_path, row, message):
    path = tmp_path / sweep.JOURNAL
    good = {**sweep._empty_row(0, 0.5), "converged": True}
    path.write_text(json.dumps(HEADER) + "\n" + json.dumps({**good, **row}) + "\n")
    with pytest.raises(InputError) as err:
        _journal(path, HEADER).open(resume=True)
    assert message in str(err.value) and str(path) in str(err.value)
    assert "\n" not in str(err.value)


def test_a_verified_row_with_a_nan_time_is_not_verified(tmp_path):
    """A hand-edited row claiming "verified" with a NaN time of flight is refused
    through the command line (exit 2, one line with its line number), never counted
    as a verified member (exit 0)."""
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    out = tmp_path / "out"
    out.mkdir()
    values = [0.5, 1.0, 1.5]
    header = {"journal": "esail-opt sweep", "problem": "tiny",
              "source_sha256": engine.source_digest(problem.read_text()),
              "param": "ac_mm_s2", "values": values, "polish": False,
              "tolerance": {"position_km": 1e6, "velocity_m_s": 1e4}}
    lines = [json.dumps(header)]
    for i, value in enumerate(values):
        row = {**sweep._empty_row(i, value), "converged": True, "verified": True,
               "status": "Solve_Succeeded", "objective": 1.0, "tof_days": 500.0}
        lines.append(json.dumps(row))
    lines[2] = lines[2].replace('"tof_days": 500.0', '"tof_days": NaN')
    (out / sweep.JOURNAL).write_text("\n".join(lines) + "\n")
    tolerance = ("--tol-km", "1e6", "--tol-m-s", "1e4")
    run = _cli(*_scan_command("sweep", problem, out, "--resume", *tolerance))
    assert run.returncode == 2, run.stderr
    messages = _messages(run.stderr)
    assert len(messages) == 1 and "line 3" in messages[0] and "NaN" in messages[0]


@pytest.mark.parametrize("args, words", [
    (("--out", ""), ("--out",)),
    (("--scheduler", "inproc://x"), ("--scheduler", "tcp://HOST:PORT")),
    (("--scheduler", "tcp://127.0.0.1:99999"), ("--scheduler", "[1, 65535]")),
    (("--scheduler", "tcp://127.0.0.1:0"), ("--scheduler", "[1, 65535]")),
    (("--workers", "65"), ("workers", "[1, 64]")),
])
@pytest.mark.parametrize("kind", ["sweep", "porkchop"])
def test_a_bad_scan_option_is_one_line_naming_it(tmp_path, capsys, kind, args, words):
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    out = tmp_path / "out"
    command = list(map(str, _scan_command(kind, problem, out)))
    if args[0] == "--out":
        command = command[:-2]
    assert cli.main([*command, *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and all(word in err for word in words), err
    assert not out.exists()


@pytest.mark.parametrize("command", ["search", "solve"])
def test_an_empty_out_is_refused(tmp_path, capsys, monkeypatch, command):
    """``--out ""`` is no folder: one line, exit 2, and nothing written (solve used to
    take it for its default ``results/<name>``)."""
    monkeypatch.chdir(tmp_path)
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    assert cli.main([command, str(problem), "--out", ""]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.py"]


def test_a_users_folder_is_never_replaced_by_an_output_set(tmp_path, capsys, monkeypatch):
    """A run swaps its whole folder in: it refuses, before solving and with one line,
    an --out that is the working folder or holds it (the shell would be left in a
    deleted folder), and an --out whose folder holds a folder named like one of its
    files (that folder, the user's, would go with the old set)."""
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    here = tmp_path / "here"
    (here / "notes").mkdir(parents=True)
    monkeypatch.chdir(here)
    for out in (str(here), str(tmp_path)):
        assert cli.main(["solve", str(problem), "--out", out]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is the working folder or holds it" in err
    assert sorted(p.name for p in here.iterdir()) == ["notes"]
    mine = here / "run" / "schedule.csv"
    mine.mkdir(parents=True)
    (mine / "notes.txt").write_text("precious\n")
    assert cli.main(["solve", str(problem), "--out", "run"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "schedule.csv" in err and "in the way" in err
    assert (mine / "notes.txt").read_text() == "precious\n"


def test_publish_keeps_a_folder_that_took_a_files_name_during_the_run(tmp_path):
    """The same refusal when the folder appears after the check, at the swap: the old
    set, the user's folder in it, stays, and no staging folder is left."""
    target = tmp_path / "out"
    (target / "a.csv").mkdir(parents=True)
    (target / "a.csv" / "notes.txt").write_text("precious\n")
    with pytest.raises(OutputError, match="a.csv"):
        with files.publish(target, family=("a.csv",)) as stage:
            (stage / "a.csv").write_text("x\n")
    assert (target / "a.csv" / "notes.txt").read_text() == "precious\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_an_out_in_the_way_is_one_line_before_the_work(tmp_path, capsys):
    """propagate's --out (a file) where a folder is, and reproduce's (a folder) where a
    file is, are refused before anything is flown: one line, exit 3."""
    (tmp_path / "folder").mkdir()
    (tmp_path / "file").write_text("mine\n")
    assert cli.main(["propagate", "--alpha", "45", "--ac", "0.1", "--years", "5",
                     "--out", str(tmp_path / "folder")]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a folder of that name is in the way" in err
    assert cli.main(["reproduce", "fig2", "--out", str(tmp_path / "file")]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a file of that name is in the way" in err
    assert (tmp_path / "file").read_text() == "mine\n"
    assert not any((tmp_path / "folder").iterdir())


def test_a_figure_whose_name_a_folder_holds_is_one_line(tmp_path, capsys):
    """``esail-opt plot`` into a folder where a folder bears a figure's name: one line
    naming that figure, exit 3, and the folder's own contents untouched."""
    from esail_opt.app.solution import Solution

    sol = Solution.load(REPO / "results" / "earth_mars_min_time" / "solution.json")
    sol.write(tmp_path, plots=False)
    (tmp_path / "trajectory.png").mkdir()
    assert cli.main(["plot", str(tmp_path)]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(tmp_path / "trajectory.png") in err
    held = tmp_path / "trajectory.png"
    assert held.is_dir() and not any(held.iterdir())


def test_a_negative_tof_range_is_one_line_not_a_usage_message(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["porkchop", str(WINDOW), "--depart", "2030-01-01:2030-03-01:2",
                     "--tof", "-100:850:2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tof START" in err and "usage" not in err, err
    assert not out.exists()


def test_a_cache_out_of_inodes_is_full(tmp_path, monkeypatch):
    """Creating a file fails for want of inodes while bytes are free: the cache is
    full, and a run does not try a compile there."""
    from esail_opt.propagation import compiled as cc

    real = os.statvfs(tmp_path)

    class NoInodes:
        f_bavail, f_frsize = real.f_bavail, real.f_frsize
        f_files, f_favail = 1_000_000, 0

    monkeypatch.setattr(cc.os, "statvfs", lambda folder: NoInodes)
    reason = cc._unusable(tmp_path)
    assert reason is not None and "inodes" in reason


# ---------------------------------------------------------------- 8. what a killed worker leaves


def _naming(needle):
    """Pids of the live processes whose command line holds ``needle``."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and int(entry.name) != os.getpid():
            try:
                if os.fsencode(needle) in (entry / "cmdline").read_bytes() \
                        and _alive(int(entry.name)):
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM])
def test_a_process_killed_mid_compile_leaves_no_compiler_and_no_files(tmp_path, signum):
    """A process compiling the cache's first library is ended by a signal it does not
    handle (a pool worker's end): no gcc runs on, no build folder stays in the cache,
    and no assembler file stays in the temporary folder."""
    cache, scratch = tmp_path / "cache", tmp_path / "tmp"
    scratch.mkdir()
    child = ("from esail_opt.propagation.compiled import compiled; "
             "from esail_opt.propagation.rectified import panel_function; "
             "compiled(panel_function())")
    env = {k: v for k, v in _env(ESAIL_OPT_CACHE=str(cache), TMPDIR=str(scratch)).items()
           if k != "ESAIL_OPT_COMPILE"}
    proc = subprocess.Popen([sys.executable, "-c", child], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            if any(b"cc1" in Path(f"/proc/{p}/cmdline").read_bytes()
                   for p in _naming(str(cache)) if Path(f"/proc/{p}").exists()):
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the compile ended before it could be killed"
        time.sleep(0.5)  # well inside cc1's work on the Hessian block
        proc.send_signal(signum)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and (_naming(str(cache)) or list(cache.glob(".build-*"))):
        time.sleep(0.2)
    left = _naming(str(cache))
    for pid in left:  # not to outlive the test either way
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    assert not left, "a compiler outlived the process that started it"
    assert not list(cache.glob(".build-*"))
    assert not list(scratch.glob("cc*"))


@pytest.mark.slow
def test_a_member_whose_file_ends_its_worker_leaks_no_folder(tmp_path):
    """A problem file that calls os._exit in the workers (not in the command's own
    process) costs its member: it is lost with its worker, tried again and reported,
    and no try leaves its folder in the temporary folder."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    problem = tmp_path / "exits.py"
    problem.write_text("import multiprocessing, os\n"
                       "if multiprocessing.parent_process() is not None:\n"
                       "    os._exit(3)\n" + TINY.format(name="exits"))
    run = _cli("sweep", problem, "--param", "ac_mm_s2=1:1:1", "--workers", "1",
               "--out", tmp_path / "out", env=_env(TMPDIR=str(scratch), ESAIL_OPT_COMPILE="0"))
    assert run.returncode == 1, run.stderr
    row = json.loads((tmp_path / "out" / "sweep.json").read_text())["rows"][0]
    assert "worker lost 3 times" in row["error"]
    assert not [p.name for p in scratch.iterdir() if p.name.startswith("esail_")]


@pytest.mark.slow
def test_an_unusable_cache_is_said_once_per_run_not_per_worker(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    problem = tmp_path / "tiny.py"
    problem.write_text(TINY.format(name="tiny"))
    env = {k: v for k, v in _env(ESAIL_OPT_CACHE=str(blocker / "cache")).items()
           if k != "ESAIL_OPT_COMPILE"}
    run = _cli("sweep", problem, "--param", "ac_mm_s2=0.5:1.5:2", "--workers", "2",
               "--out", tmp_path / "out", env=env)
    assert run.returncode == 0, run.stderr
    said = [ln for ln in run.stderr.splitlines() if "cannot compile into the cache" in ln]
    assert len(said) == 1, said


def test_cells_out_is_checked_before_anything_runs(tmp_path, capsys):
    out = tmp_path / "out"
    base = ["porkchop", str(WINDOW), "--depart", "2030-01-01:2030-03-01:2", "--out", str(out)]
    assert cli.main([*base, "--cells-out", ""]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--cells-out" in err
    assert cli.main([*base, "--cells-out", str(tmp_path / "cells"), "--scheduler",
                     "tcp://127.0.0.1:8786"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--cells-out" in err and "--scheduler" in err
    assert not (out / "porkchop.jsonl").exists() and not (tmp_path / "cells").exists()
