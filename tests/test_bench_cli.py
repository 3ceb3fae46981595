"""The benchmarks' own command, ``esail-opt-bench`` (``python -m esail_opt.bench``)."""

import os
import subprocess
import sys

import pytest

from conftest import REPO
from esail_opt.app import cli as app_cli
from esail_opt.bench import BENCHES
from esail_opt.bench import cli


def test_bad_repeats_is_one_line_and_exit_2_before_any_bench_runs(capsys, tmp_path):
    assert cli.main(["solve", "--repeats", "0", "--out", str(tmp_path)]) == 2
    out = capsys.readouterr()
    assert out.err.strip() == "esail-opt-bench: error: repeats = 0 is outside [1, inf)"
    assert out.out == "" and list(tmp_path.iterdir()) == []


def test_names_are_the_benches(capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["no_such_bench"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'no_such_bench'" in err
    assert all(repr(name) in err for name in BENCHES)


def test_esail_opt_has_no_bench_subcommand(capsys):
    with pytest.raises(SystemExit) as stop:
        app_cli.main(["bench", "solve"])
    assert stop.value.code == 2
    assert "invalid choice: 'bench'" in capsys.readouterr().err


def test_python_m_runs_the_same_command():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])}
    run = subprocess.run([sys.executable, "-m", "esail_opt.bench", "solve", "--repeats", "0"],
                         capture_output=True, text=True, env=env, cwd=REPO, timeout=120)
    assert run.returncode == 2
    assert run.stderr.strip() == "esail-opt-bench: error: repeats = 0 is outside [1, inf)"
