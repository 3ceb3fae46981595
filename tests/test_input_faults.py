"""Bad input refused before anything runs (issue 30, items 3-5 and 7): a symlinked output
folder, body fields that disagree with the tracked span or with each other, numbers given
as strings, problem names that no folder or terminal line can hold, and a problem file
that ends its own process.

Each case is checked where a user meets it: the command line's exit status 2 and its one
line naming the field, with nothing written; or the one InputError of the API.
"""

import dataclasses
import datetime
import os
import signal
import subprocess
import sys

import pytest

import esail_opt as eo
from esail_opt.runtime import files
from esail_opt.errors import InputError
from esail_opt.optimisation.problem_file import load_problem

from conftest import REPO, TINY_PROBLEM as TINY


def _cli(*args, cwd=None, **env):
    environment = dict(os.environ, PYTHONPATH=str(REPO), ESAIL_OPT_COMPILE="0", **env)
    return subprocess.run([sys.executable, "-m", "esail_opt.app.cli", *map(str, args)],
                          capture_output=True, text=True, env=environment, timeout=600,
                          cwd=cwd)


def _messages(stderr):
    """stderr's lines without the progress lines (which end in ' ...')."""
    return [ln for ln in stderr.splitlines() if ln.strip() and not ln.endswith(" ...")]


def _refused(run, *words):
    """The run ended with exit 2 and one line holding every word, before any solve."""
    lines = _messages(run.stderr)
    assert run.returncode == 2, (run.returncode, run.stderr)
    assert len(lines) == 1 and all(w in lines[0] for w in words), lines
    assert "Ipopt" not in run.stderr and "Traceback" not in run.stderr


# ---------------------------------------------------------------- 3. a symlinked --out


@pytest.mark.parametrize("dangling", [False, True])
def test_a_symlinked_out_is_refused_before_the_solve(tmp_path, dangling):
    problem = tmp_path / "p.py"
    problem.write_text(TINY.format(name="tiny"))
    real = tmp_path / "real"
    if not dangling:
        real.mkdir()
        (real / "mine.txt").write_text("kept")
    link = tmp_path / "link"
    link.symlink_to(real, target_is_directory=True)
    run = _cli("solve", problem, "--out", link)
    _refused(run, "symbolic link", str(link))
    assert link.is_symlink() and os.readlink(link) == str(real)
    if dangling:
        assert not real.exists()
    else:
        assert sorted(p.name for p in real.iterdir()) == ["mine.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["p.py", "link"]
                                                                + ([] if dangling else ["real"]))


def test_check_output_dir_refuses_a_link_also_given_with_a_slash(tmp_path):
    """The check the sweep and the porkchop call too: a link is refused however it is
    written, and a folder under a linked parent is not a link itself."""
    (tmp_path / "real").mkdir()
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "real")
    for given in (link, f"{link}/"):
        with pytest.raises(InputError, match="is a symbolic link"):
            files.check_output_dir(given)
    assert files.check_output_dir(link / "inside") == link / "inside"


# ---------------------------------------------------------------- 4. the body API


def _dated(departure=None, target=None, objective=None, segments=None):
    return eo.Problem(name="dated",
                      departure=departure or eo.BodyDeparture(body="earth", date="2031-01-01"),
                      sail=eo.Sail(ac_mm_s2=1.0), segments=segments or eo.Segments(count=10),
                      objective=objective or eo.MinTime(),
                      target=target or eo.BodyRendezvous(body="mars"))


def _small(**changes):
    fields = dict(name="test", a_au=1.5, e=0.1, inclination_deg=2.0, node_deg=10.0,
                  argument_of_perihelion_deg=40.0, mean_anomaly_deg=20.0, epoch="2030-01-01")
    return eo.SmallBody(**dict(fields, **changes))


@pytest.mark.parametrize("build, words", [
    # An arrival window past the dates bodies are tracked on (2000-2060).
    (lambda: eo.BodyRendezvous(body="mars", arrival_window=("2059-06-01", "2061-01-01")),
     ["target.arrival_window[1] = 2061-01-01", "2060-01-01"]),
    (lambda: eo.BodyIntercept(body="mars", arrival_window=("1990-01-01", "2030-01-01")),
     ["target.arrival_window[0] = 1990-01-01", "2000-01-01"]),
    # An arrival window that closes before the departure date, or the window's start.
    (lambda: _dated(target=eo.BodyRendezvous(body="mars",
                                             arrival_window=("2029-01-01", "2030-06-01"))),
     ["target.arrival_window", "departure.date = 2031-01-01"]),
    (lambda: _dated(departure=eo.BodyDeparture(body="earth",
                                               window=("2031-01-01", "2033-01-01")),
                    target=eo.BodyIntercept(body="mars",
                                            arrival_window=("2030-01-01", "2030-12-31"))),
     ["target.arrival_window", "departure.window[0] = 2031-01-01"]),
    # A fixed time of flight that no departure date of the window can arrive in: 37 s in
    # Ipopt ended in "does not prove the target unreachable".
    (lambda: _dated(departure=eo.BodyDeparture(body="earth",
                                               window=("2031-01-01", "2032-01-01")),
                    objective=eo.MinAcceleration(tof_days=600.0),
                    target=eo.BodyRendezvous(body="mars",
                                             arrival_window=("2032-01-01", "2032-06-01"))),
     ["objective.tof_days = 600 d", "from 2032-08-23T00:00:00 to 2033-08-23T00:00:00",
      "never inside target.arrival_window"]),
    (lambda: _dated(objective=eo.MinAcceleration(tof_days=300.0),
                    target=eo.BodyRendezvous(body="mars",
                                             arrival_window=("2032-01-01", "2032-06-01"))),
     ["objective.tof_days = 300 d", "never inside target.arrival_window"]),
    # Extrapolated arcs exist in the plane only: refused when the file loads, not after
    # a window scan on the projected model had run.
    (lambda: _dated(segments=eo.Segments(count=10, extrapolate=True)),
     ["segments.extrapolate = True", "three dimensions"]),
    # A date and a window together: the date was silently ignored.
    (lambda: eo.BodyDeparture(body="earth", date="2031-06-01",
                              window=("2031-01-01", "2032-01-01")),
     ["departure.date = '2031-06-01'", "departure.window = "]),
    # A small body's elements from outside the tracked span.
    (lambda: _small(epoch="1800-01-01"), ["body.epoch = 1800-01-01", "2000-01-01"]),
    (lambda: _small(epoch="9999-01-01"), ["body.epoch = 9999-01-01", "2060-01-01"]),
    # Semimajor axes no target may have; the refusal named another field.
    (lambda: _small(a_au=1e9), ["body.a_au = 1000000000.0 au", "[0.05, 100] au"]),
    (lambda: _small(a_au=1e-6), ["body.a_au = 1e-06 au", "[0.05, 100] au"]),
    (lambda: _small(name="Bennu\r\x1b[2K"), ["body.name = ", "U+000D CR"]),
    # A small body's perihelion given twice (or not at all): the catalogue's w and the
    # longitude of perihelion share a range, so only naming one of them tells them apart.
    (lambda: _small(perihelion_deg=50.0),
     ["body.argument_of_perihelion_deg = 40.0 and body.perihelion_deg = 50.0",
      "give exactly one", "small-body database lists it as w", "node + omega"]),
    (lambda: _small(argument_of_perihelion_deg=None),
     ["body.argument_of_perihelion_deg = None and body.perihelion_deg = None",
      "give exactly one"]),
    # Numbers given as strings: a TypeError far from the file that named no field.
    (lambda: eo.MinAcceleration(tof_days="650"), ["objective.tof_days = '650'", "(0, 36525]"]),
    (lambda: eo.MaxRadius(tof_days="365"), ["objective.tof_days = '365'"]),
    (lambda: eo.Sail(ac_mm_s2="1.0"), ["sail.ac_mm_s2 = '1.0'", "(0, 100] mm/s^2"]),
    (lambda: eo.ParkingOrbit(a_au="1"), ["departure.a_au = '1'"]),
    (lambda: eo.BodyDeparture(body="earth", date="2031-01-01", vinf_km_s="3"),
     ["departure.vinf_km_s = '3'", "[0, 10] km/s"]),
    # Switches given as strings: any non-empty one read as True, "no" included.
    (lambda: eo.ParkingOrbit(a_au=1.0, free_anomaly="no"),
     ["departure.free_anomaly = 'no'", "True or False"]),
    (lambda: eo.Segments(count=10, equal="False"), ["segments.equal = 'False'"]),
    (lambda: eo.Segments(count=10, extrapolate="yes"), ["segments.extrapolate = 'yes'"]),
])
def test_body_and_numeric_fields_are_refused_naming_the_field(build, words):
    with pytest.raises(InputError) as refused:
        build()
    line = str(refused.value)
    assert "\n" not in line and all(w in line for w in words), line


def test_an_arrival_window_that_fits_the_departure_is_kept():
    """The checks refuse only what cannot fly: a window that opens before the departure
    but closes after it is a loose bound, and stays; so does a fixed time of flight
    that some date of the departure window ends inside it, and a planar problem's
    extrapolated arcs."""
    problem = _dated(target=eo.BodyRendezvous(body="mars",
                                              arrival_window=("2029-01-01", "2033-01-01")))
    lo, hi = problem.target.arrival_jd
    assert hi - lo == (datetime.date(2033, 1, 1) - datetime.date(2029, 1, 1)).days
    _dated(departure=eo.BodyDeparture(body="earth", window=("2031-01-01", "2032-01-01")),
           objective=eo.MinAcceleration(tof_days=600.0),
           target=eo.BodyRendezvous(body="mars", arrival_window=("2032-01-01", "2032-09-01")))
    planar = dataclasses.replace(_dated(), planar=True,
                                 segments=eo.Segments(count=10, extrapolate=True))
    assert not planar.three_d()


@pytest.mark.parametrize("name, kind", [
    ("x\x1b[31mred", "U+001B"), ("back\rover", "U+000D"), ("tab\there", "U+0009"),
    ("two\nlines", "U+000A"), ("lone\udc80", "U+DC80"), ("nul\0", "U+0000"),
])
def test_a_problem_name_with_control_characters_is_refused(name, kind):
    with pytest.raises(InputError) as refused:
        dataclasses.replace(_dated(), name=name)
    line = str(refused.value)
    assert line.startswith("name = ") and kind in line and "printable" in line, line
    # What stays allowed: any printable text, a '$' included (the figures draw it).
    for fine in ("x$a^b^c$", "Mars, 2031 (é)"):
        assert dataclasses.replace(_dated(), name=fine).name == fine


BODY_FILE = '''
import esail_opt as eo

problem = eo.Problem(
    name={name!r},
    departure=eo.BodyDeparture(body="earth", date="2031-01-01"),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=6, sub_arcs=1),
    objective=eo.MinTime(),
    target=eo.BodyRendezvous(body="mars", arrival_window={window!r}),
)
'''


@pytest.mark.parametrize("name, window, words", [
    ("late", ("2059-01-01", "2061-01-01"), ["target.arrival_window[1] = 2061-01-01"]),
    ("early", ("2029-01-01", "2030-01-01"), ["target.arrival_window", "departure.date"]),
    ("x\x1b[2Jy", None, ["name = ", "U+001B"]),
])
def test_bad_body_input_ends_the_command_with_one_line_and_nothing_written(
        tmp_path, name, window, words):
    problem = tmp_path / "p.py"
    problem.write_text(BODY_FILE.format(name=name, window=window))
    run = _cli("solve", problem, cwd=tmp_path)
    _refused(run, "p.py: ", *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.py"]


# ---------------------------------------------------------------- 5. a problem file's exit


@pytest.mark.parametrize("call, words", [
    ("os._exit(0)", ["ended the process that loaded it (exit status 0)"]),
    ("os._exit(3)", ["ended the process that loaded it (exit status 3)"]),
    ("os.kill(os.getpid(), signal.SIGKILL)", ["(killed by SIGKILL)"]),
    ("raise BaseException('bye')", ["BaseException: bye"]),
    ("raise GeneratorExit", ["GeneratorExit"]),
])
def test_a_problem_file_that_ends_its_process_is_bad_input(tmp_path, call, words):
    """Exit 0 with no output read as verified; a BaseException was a traceback."""
    problem = tmp_path / "ends.py"
    problem.write_text(f"import os, signal\n{TINY.format(name='tiny')}\n{call}\n")
    run = _cli("solve", problem, "--out", tmp_path / "out")
    _refused(run, "ends.py: ", *words)
    assert not (tmp_path / "out").exists()


def test_a_problem_file_that_exits_is_refused_before_a_sweep_makes_any_folder(tmp_path):
    """A sweep's members each ran the file in a scratch folder that its exit leaked."""
    problem = tmp_path / "ends.py"
    problem.write_text(f"import os\n{TINY.format(name='tiny')}\nos._exit(0)\n")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    run = _cli("sweep", problem, "--param", "ac_mm_s2=0.8:1.2:2", "--workers", "1",
               "--out", tmp_path / "out", TMPDIR=str(scratch))
    _refused(run, "ends.py: ", "ended the process that loaded it")
    assert list(scratch.iterdir()) == [] and not (tmp_path / "out").exists()


def test_a_problem_file_raising_keyboard_interrupt_is_an_interrupt(tmp_path):
    problem = tmp_path / "stops.py"
    problem.write_text("raise KeyboardInterrupt\n")
    run = _cli("solve", problem, "--out", tmp_path / "out")
    assert run.returncode == 128 + signal.SIGINT, run.stderr
    assert "interrupted" in run.stderr and "Traceback" not in run.stderr


@pytest.mark.parametrize("call, kind", [("raise BaseException('bye')", "BaseException"),
                                        ("raise GeneratorExit", "GeneratorExit")])
def test_load_problem_words_any_base_exception_as_one_line(tmp_path, call, kind):
    problem = tmp_path / "raises.py"
    problem.write_text(f"{call}\n")
    with pytest.raises(InputError, match=f"^raises.py: {kind}"):
        load_problem(problem)


def test_a_misspelt_field_names_the_fields_its_part_takes(tmp_path):
    problem = tmp_path / "typo.py"
    problem.write_text("import esail_opt as eo\nsail = eo.Sail(acc_mm_s2=1.5)\n")
    with pytest.raises(InputError) as refused:
        load_problem(problem)
    line = str(refused.value)
    assert line.startswith("typo.py: TypeError: ") and "'acc_mm_s2'" in line, line
    assert line.endswith("; Sail takes " + ", ".join(
        f.name for f in dataclasses.fields(eo.Sail) if f.init)), line
    assert "ac_mm_s2" in line.split("takes ")[1]


@pytest.mark.parametrize("angles, words", [
    ("argument_of_perihelion_deg=66.2, perihelion_deg=68.3",
     ["body.argument_of_perihelion_deg = 66.2 and body.perihelion_deg = 68.3",
      "give exactly one"]),
    # The positional form whose sixth number was the longitude: refused, not read.
    ("68.3, 101.7, '2030-01-01'", ["TypeError", "positional"]),
])
def test_a_problem_file_with_an_ambiguous_perihelion_is_one_line(tmp_path, angles, words):
    problem = tmp_path / "rock.py"
    problem.write_text("import esail_opt as eo\n"
                       f"rock = eo.SmallBody('rock', 1.1, 0.2, 6.0, 2.1, {angles}"
                       + (", mean_anomaly_deg=101.7, epoch='2030-01-01')\n"
                          if "=" in angles else ")\n"))
    with pytest.raises(InputError) as refused:
        load_problem(problem)
    line = str(refused.value)
    assert line.startswith("rock.py: ") and "\n" not in line
    assert all(w in line for w in words), line


def test_a_loaded_file_prints_once_and_its_problem_is_the_files(tmp_path, capfd):
    """The file runs in a child first (whose output is discarded) and then here: what it
    prints is seen once, and the problem is the one the file builds."""
    problem = tmp_path / "says.py"
    problem.write_text(f"print('loading says.py')\n{TINY.format(name='says')}\n")
    loaded = load_problem(problem)
    assert capfd.readouterr().out.count("loading says.py") == 1
    assert loaded.name == "says" and loaded.sail.ac_mm_s2 == 1.0
