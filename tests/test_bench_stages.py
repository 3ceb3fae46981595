"""The stages bench: exclusive stage times that partition the time they cover."""

import itertools

from esail_opt.bench import stages


def test_stage_clock_charges_each_moment_once():
    """Nested stages on a clock that ticks one second a reading: each second is
    charged to the innermost open stage (or ``other``), an Ipopt frame's own time
    excludes the build inside it, and the totals sum to the clock's elapsed time."""
    ticks = itertools.count()
    clock = stages.StageClock(clock=lambda: float(next(ticks)))  # start: 0
    with clock.stage("ipopt") as ipopt:      # 1: other 1
        with clock.stage("nlp_build"):       # 2: ipopt 1
            pass                             # 3: nlp_build 1
        with clock.step("probes"):
            assert clock.steps == ["probes"]
    # 4: ipopt 1 more
    assert ipopt[1] == 2.0
    assert clock.totals["ipopt"] == 2.0 and clock.totals["nlp_build"] == 1.0
    assert clock.elapsed() == 5.0           # 5: other 1 more
    assert clock.totals["other"] == 2.0
    assert sum(clock.totals.values()) == 5.0


def test_stages_of_a_planar_solve_fit_in_its_process():
    """A real solve (the planar Earth-Mars MinAcceleration with the polish, no
    figures) in a fresh process: no stage is negative, the stages and the start-up
    sum to the parent's wall time of the process and never exceed it, each Ipopt call
    is in the ipopt stage, and the answer is the shipped one."""
    record = stages.measure("earth_mars_min_ac_planar", plots=False)
    times = record["stages"]
    assert set(times) == set(stages.STAGES)
    assert all(seconds >= 0 for seconds in times.values())
    assert sum(times.values()) <= record["process_seconds"]
    assert record["child_seconds"] <= record["process_seconds"]
    assert abs(sum(times.values()) - record["child_seconds"]) < 1e-6
    calls = record["ipopt_calls"]
    assert abs(sum(c["seconds"] for c in calls) - times["ipopt"]) < 1e-6
    assert [c["step"] for c in calls][:3] == ["answer", "probes", "probes"]
    assert calls[-1]["step"] == "polish"
    assert times["imports"] > 0 and times["ipopt"] > 0 and times["verification"] > 0
    assert times["figures"] == 0 and times["figures_import"] == 0
    assert record["verified"]
    assert abs(record["objective"] - 0.15486576197895655) < 1e-6 * 0.155
