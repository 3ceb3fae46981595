"""trajectory.oem: a CCSDS OEM written through the ``oem`` package, read back by another
reader.

The reader here is written from the standard's KVN layout (CCSDS 502.0-B: a header of
``KEY = value`` lines, ``META_START`` ... ``META_STOP``, then one line per state: epoch and
six numbers); its epochs become Julian dates by ERFA's dtf2d and its states are compared
with DE421 read directly by jplephem (heliocentric, ICRF, km), so that neither the
package's rotation nor its dates nor the ``oem`` package's reader is trusted.
"""

import math
import re

import erfa
import numpy as np
import pytest

from esail_opt.app import oem as oem_module
from esail_opt.app.oem import states_km_km_s, write_oem
from esail_opt.bodies.ephemeris import ecliptic_state
from esail_opt.bodies.keplerian import BENNU
from esail_opt.errors import InputError

EPS = math.radians(84381.448 / 3600.0)  # written out again, not the package's
# The bounds: 1 mm and 1 micron/s.  The file keeps 15 significant digits (the oem package's
# scientific format): below 1e9 km each coordinate is rounded by at most half of 1e-6 km,
# so a position by at most sqrt(3) / 2 mm = 0.87 mm, and a velocity below 100 km/s by
# 1e-12 km/s; the rotation adds 1e-16 relative (0.03 mm).
MM_KM = 1e-6  # 1 mm in km
MICRON_S_KM_S = 1e-9  # 1 micron/s in km/s
_EPOCH = re.compile(r"(\d{4})-(\d{2})-(\d{2})T(\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)$")


def read_kvn(path):
    """(header, metadata, [(jd1, jd2)], states (N, 6)) of a one-segment KVN OEM."""
    lines = [line.strip() for line in path.read_text().splitlines()]
    lines = [line for line in lines if line and not line.startswith("COMMENT")]
    assert lines[0].startswith("CCSDS_OEM_VERS")
    start, stop = lines.index("META_START"), lines.index("META_STOP")
    pairs = [tuple(part.strip() for part in line.split("=", 1)) for line in lines[:start]]
    header = dict(pairs)
    metadata = dict(tuple(part.strip() for part in line.split("=", 1))
                    for line in lines[start + 1:stop])
    epochs, states = [], []
    for line in lines[stop + 1:]:
        words = line.split()
        assert len(words) == 7, line
        year, month, day, hour, minute, second = _EPOCH.match(words[0]).groups()
        epochs.append(erfa.dtf2d("TDB", int(year), int(month), int(day), int(hour),
                                 int(minute), float(second)))
        states.append([float(w) for w in words[1:]])
    return header, metadata, epochs, np.array(states)


def de421_icrf_km(segment, jd1, jd2):
    """DE421's heliocentric ICRF state, km and km/s, read by jplephem directly."""
    import de421
    from jplephem import Ephemeris

    eph = Ephemeris(de421)
    body = eph.position_and_velocity(segment, jd1, jd2)
    sun = eph.position_and_velocity("sun", jd1, jd2)
    return np.concatenate([body[0] - sun[0], (body[1] - sun[1]) / 86400.0]).ravel()


def test_mars_written_and_read_back_is_de421(tmp_path):
    # Epochs on whole minutes print exactly, so each state read back is compared with
    # DE421 at the epoch the file states.
    start = 2462000.5
    days = np.arange(0.0, 400.0, 7.0) + 13.0 / 1440.0
    jd1 = np.full(days.shape, start)
    states = states_km_km_s(ecliptic_state("mars", jd1, jd2=days))
    path = tmp_path / "out" / "trajectory.oem"
    write_oem(path, "E-SAIL TEST", jd1, states, jd2=days)
    header, metadata, epochs, read = read_kvn(path)
    assert header["CCSDS_OEM_VERS"] == "2.0" and header["ORIGINATOR"] == "esail_opt"
    assert metadata["CENTER_NAME"] == "SUN" and metadata["REF_FRAME"] == "ICRF"
    assert metadata["TIME_SYSTEM"] == "TDB" and metadata["OBJECT_NAME"] == "E-SAIL TEST"
    assert len(epochs) == days.size
    worst_mm = worst_micron_s = 0.0
    for (e1, e2), row, day in zip(epochs, read, days):
        assert abs((e1 - start) + e2 - day) * 86400 < 1e-6  # the epoch, to a microsecond
        reference = de421_icrf_km("mars", e1, e2)
        worst_mm = max(worst_mm, np.linalg.norm(row[:3] - reference[:3]) / MM_KM)
        worst_micron_s = max(worst_micron_s, np.linalg.norm(row[3:] - reference[3:]) / MICRON_S_KM_S)
    assert worst_mm < 1.0 and worst_micron_s < 1.0
    print(f"Mars via OEM vs DE421 ICRF: {worst_mm:.3f} mm, {worst_micron_s:.2e} micron/s")


def test_any_states_round_trip_to_a_millimetre(tmp_path):
    # A small body's states (out of the ecliptic by 6 deg) at epochs that do not fall on
    # whole microseconds: the file rounds each epoch to the microsecond, the state is the
    # one given; rotated to the ecliptic here, they are the states written.
    days = np.linspace(0.0, 700.0, 301) + 0.123456789
    jd1 = np.full(days.shape, 2462502.5)
    states = states_km_km_s(BENNU.ecliptic_state(jd1, jd2=days))
    path = tmp_path / "trajectory.oem"
    write_oem(path, "BENNU-LIKE", jd1, states, jd2=days, object_id="2030-001A")
    _header, metadata, epochs, read = read_kvn(path)
    assert metadata["OBJECT_ID"] == "2030-001A"
    c, s = math.cos(EPS), math.sin(EPS)
    to_ecliptic = np.array([[1, 0, 0], [0, c, s], [0, -s, c]])
    position = to_ecliptic @ read[:, :3].T
    velocity = to_ecliptic @ read[:, 3:].T
    position_mm = np.linalg.norm(position - states[:3], axis=0).max() / MM_KM
    velocity_micron_s = np.linalg.norm(velocity - states[3:], axis=0).max() / MICRON_S_KM_S
    assert position_mm < 1.0 and velocity_micron_s < 1.0
    offsets = np.array([((e1 - 2462502.5) + e2 - d) * 86400e6 for (e1, e2), d in zip(epochs, days)])
    assert np.abs(offsets).max() <= 0.5 + 1e-3  # microseconds: rounding, and a JD's float
    print(f"round trip: {position_mm:.3f} mm, {velocity_micron_s:.2e} micron/s, "
          f"epochs within {np.abs(offsets).max():.3f} microseconds")
    # The oem package reads its own file too, the same numbers.
    from oem import OrbitEphemerisMessage

    message = OrbitEphemerisMessage.open(path)
    np.testing.assert_array_equal(np.array([st.vector for st in message.states]), read)


def test_iso_epochs(tmp_path):
    epochs = ["2031-01-01T00:00", "2031-01-02T06:00:00.5", "2031-01-03 TDB"]
    jd = np.array([2462867.5, 2462868.75 + 0.5 / 86400, 2462869.5])
    states = states_km_km_s(ecliptic_state("venus", jd))
    path = tmp_path / "v.oem"
    write_oem(path, "V", epochs, states)
    _h, _m, read_epochs, read = read_kvn(path)
    # One float of a Julian date (the ISO path) resolves 40 microseconds.
    assert max(abs(a + b - j) * 86400 for (a, b), j in zip(read_epochs, jd)) < 5e-5
    assert read.shape == (3, 6)


def test_write_is_whole_or_nothing(tmp_path, monkeypatch):
    path = tmp_path / "trajectory.oem"
    path.write_text("the old file\n")
    states = states_km_km_s(ecliptic_state("earth", np.array([2462000.5, 2462001.5])))

    class Failing:
        def save_as(self, name, file_format):
            with open(name, "w") as half:
                half.write("CCSDS_OEM_VERS = 2.0\n")
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(oem_module, "_message", lambda *args: Failing())
    with pytest.raises(OSError):
        write_oem(path, "X", [2462000.5, 2462001.5], states)
    assert path.read_text() == "the old file\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trajectory.oem"]


@pytest.mark.parametrize("change, message", [
    ({"states": np.zeros((3, 2))}, r"^oem\.states has shape \(3, 2\); expected \(6, N\)"),
    ({"states": np.full((6, 2), np.nan)}, r"^oem\.states holds a value that is not finite"),
    ({"epochs": [2462000.5]}, r"^oem\.epochs has 1 dates for 2 states"),
    ({"epochs": [2462001.5, 2462000.5]}, r"^oem\.epochs must increase strictly"),
    ({"epochs": [2462000.5, 2462000.5 + 1e-12]}, r"^oem\.epochs must increase strictly"),
    ({"epochs": ["2030-01-01", "2030-02-30"]}, r"^oem\.epochs\[1\] = "),
    ({"epochs": [2462000.5, float("inf")]}, r"^oem\.epochs holds a date that is not finite"),
    ({"object_name": ""}, r"^oem\.object_name = '' must be a non-empty one-line string"),
    ({"object_name": "a\nb"}, r"^oem\.object_name"),
    ({"jd2": [0.0, 1.0, 2.0]}, r"^oem\.jd2 has 3 values for 2 epochs"),
])
def test_bad_input_names_the_field(tmp_path, change, message):
    arguments = {"epochs": [2462000.5, 2462001.5], "states": np.ones((6, 2)),
                 "object_name": "X", "jd2": 0.0}
    arguments.update(change)
    path = tmp_path / "t.oem"
    with pytest.raises(InputError, match=message):
        write_oem(path, arguments["object_name"], arguments["epochs"], arguments["states"],
                  jd2=arguments["jd2"])
    assert not list(tmp_path.iterdir())


# ------------------------------------------------- schema 5's states (app.schema)

def test_state_fields_are_au_and_km_s_in_the_ecliptic():
    import json

    from esail_opt.app.schema import STATE_KEYS, state_fields, state_from_fields

    jd = np.array([2462000.5, 2462100.5, 2462200.5])
    state = ecliptic_state("mars", jd)
    fields = json.loads(json.dumps(state_fields(state)))
    assert tuple(fields) == STATE_KEYS
    c, s = math.cos(EPS), math.sin(EPS)
    to_ecliptic = np.array([[1, 0, 0], [0, c, s], [0, -s, c]])
    for k, j in enumerate(jd):
        reference = de421_icrf_km("mars", j, 0.0)
        position_au = to_ecliptic @ reference[:3] / 149597870.7
        velocity_km_s = to_ecliptic @ reference[3:]
        got_au = np.array([fields[key][k] for key in STATE_KEYS[:3]])
        got_km_s = np.array([fields[key][k] for key in STATE_KEYS[3:]])
        assert np.abs(got_au - position_au).max() < 1e-14  # au: 1.5 mm
        assert np.abs(got_km_s - velocity_km_s).max() < 1e-12  # km/s
    one = state_fields(state[:, 0])
    assert all(isinstance(one[key], float) for key in STATE_KEYS)
    np.testing.assert_allclose(state_from_fields(one, "x"), state[:, 0], rtol=1e-15, atol=0)
    np.testing.assert_allclose(state_from_fields(fields, "x"), state, rtol=1e-15, atol=0)
    with pytest.raises(InputError, match=r"^solution\.json: departure_state\.vz_km_s is missing"):
        state_from_fields({key: 1.0 for key in STATE_KEYS[:5]}, "solution.json: departure_state")
    with pytest.raises(InputError, match=r"^s\.y_au = 'a' is not a finite number"):
        state_from_fields(dict(one, y_au="a"), "s")
    with pytest.raises(InputError, match=r"^s: x_au, .* differ in length"):
        state_from_fields(dict(fields, x_au=[1.0]), "s")


def test_a_flight_that_goes_back_in_time_is_published_without_an_oem(tmp_path):
    """The last iterate of a solve that found no point can hold a segment of negative
    duration (Earth-Mars leaving 2029-11-03 at 3 mm/s^2, minimum time on 20 segments,
    did): its flight is no ephemeris, so the set is published without trajectory.oem
    instead of the write failing.  The same solution flown forward writes its OEM."""
    import dataclasses
    from pathlib import Path

    from esail_opt.app.solution import Solution

    sol = Solution.load(Path(__file__).parents[1] / "results" / "earth_mars_2035"
                        / "solution.json")
    days = list(sol.trajectory_cvodes.t_days)
    days[5], days[6] = days[6], days[5]
    backwards = dataclasses.replace(sol, trajectory_cvodes=dataclasses.replace(
        sol.trajectory_cvodes, t_days=days))
    written = backwards.write(tmp_path / "back", plots=False)
    assert [p.name for p in written] == ["solution.json", "schedule.csv"]
    assert sorted(p.name for p in (tmp_path / "back").iterdir()) == sorted(
        p.name for p in written)
    assert "trajectory.oem" in {p.name for p in sol.write(tmp_path / "ahead", plots=False)}


def test_an_intercepts_oem_says_its_position_miss_alone(tmp_path):
    """An intercept meets the body's position at any relative speed: it has no velocity
    miss, and its OEM's comments give the position miss and bound alone (a verified
    Ceres fly-by on 8 segments once failed to write its files over that missing miss)."""
    import esail_opt as eo
    from esail_opt.app.solution import solve

    problem = eo.Problem(name="ceres_flyby",
                         departure=eo.BodyDeparture(body="earth", date="2034-02-10"),
                         sail=eo.Sail(ac_mm_s2=1.5),
                         segments=eo.Segments(count=8, sub_arcs=4, equal=False),
                         objective=eo.MinTime(), target=eo.BodyIntercept(body=eo.CERES))
    sol = solve(problem)
    assert sol.verified and sol.verification.target_miss_v_m_s is None
    sol.write(tmp_path, plots=False)
    comments = [line for line in (tmp_path / "trajectory.oem").read_text().splitlines()
                if line.startswith("COMMENT")]
    miss = sol.verification.target_miss_r_km
    assert f"COMMENT miss at arrival: {miss:.6g} km (an intercept, at any relative " \
           "speed) from the target; verifier's own error" in "\n".join(comments)
    assert f"COMMENT tolerance: {sol.tolerance.position_km:.6g} km" in comments


@pytest.mark.slow
def test_a_polished_flights_oem_is_that_flight_and_meets_mars(tmp_path):
    """After ``--polish`` trajectory.oem is the polished flight: read back and
    interpolated by the ``oem`` package (the Hermite interpolation each data segment
    states), it follows that schedule flown here by DOP853 on the turning plane's
    equations from DE421's Earth, mid-segment, to a metre; its last state meets DE421's
    Mars within the miss its comments state; and it names the object it was told."""
    from astropy.time import Time
    from oem import OrbitEphemerisMessage

    import esail_opt as eo
    from esail_opt.optimisation import pipeline
    from esail_opt.optimisation.problem_file import load_problem
    from test_optimisation3d import AU_KM as AU, TU_DAYS, de421_ecliptic
    from test_rectified3d import fly_turning_dop853

    problem = load_problem("problems/earth_mars_min_ac.py")
    run = pipeline.solve(problem, polish=True)
    assert run.polish.verified, run.polish.note
    sol = eo.Solution.of(run)
    sol.write(tmp_path, plots=False, object_name="ESAIL-1", object_id="2031-999A")
    path = tmp_path / "trajectory.oem"
    message = OrbitEphemerisMessage.open(path)
    segments = list(message)
    exact = run.polish.result
    assert len(segments) == exact.alpha.size
    meta = segments[0].metadata
    assert (meta["OBJECT_NAME"], meta["OBJECT_ID"]) == ("ESAIL-1", "2031-999A")
    assert meta["INTERPOLATION"] == "HERMITE"

    jd0 = 2451545.0 + exact.epoch * TU_DAYS
    ac = problem.sail.ac * exact.ac_scale
    kappa = exact.throttle
    y = de421_ecliptic("earthmoon", jd0)
    c, s = math.cos(EPS), math.sin(EPS)
    to_icrf = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    km_s = AU / (TU_DAYS * 86400)
    start = 0.0
    worst = 0.0
    for k, (alpha, delta, duration) in enumerate(zip(exact.alpha, exact.delta,
                                                     exact.durations)):
        a_k = ac * kappa[k]
        mid = fly_turning_dop853(y, a_k, [alpha], [delta], [duration / 2], rtol=1e-13)
        when = Time(jd0, (start + duration / 2) * TU_DAYS, format="jd", scale="tdb")
        read = message(when)
        worst = max(worst, np.linalg.norm(np.asarray(read.position) - to_icrf @ mid[:3] * AU))
        y = fly_turning_dop853(y, a_k, [alpha], [delta], [duration], rtol=1e-13)
        start += duration
    assert worst < 1e-3, f"{worst * 1e3:.3f} m"

    # The last state written, at its epoch as written: the arrival rounded to the
    # microsecond may fall either side of the flight's summed durations.
    final = list(segments[-1].states)[-1]
    mars = de421_ecliptic("mars", final.epoch.tdb.jd1 + final.epoch.tdb.jd2)
    check = sol.polish.verification
    stated_km = check.target_miss_r_km + check.verifier_error_r_km
    assert f"miss at arrival: {check.target_miss_r_km:.6g} km" in path.read_text()
    # The epoch is written to the microsecond: 4 cm at Mars's 24 km/s.
    miss = np.linalg.norm(np.asarray(final.position) - to_icrf @ mars[:3] * AU)
    assert miss < stated_km + 4e-5, f"{miss * 1e3:.3f} m against {stated_km * 1e3:.3f} m"
    assert np.linalg.norm(np.asarray(final.velocity) - to_icrf @ mars[3:] * km_s) < 1e-6
