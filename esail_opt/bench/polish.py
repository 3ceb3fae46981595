"""``esail-opt-bench polish``: closed-form solve + exact polish against a cold CVODES
multiple shooting started from the same seed."""

import dataclasses
import time
from pathlib import Path

from esail_opt.bench.timing import print_table
from esail_opt.optimisation.problem_file import shipped_problem

#: Shipped problems of the polish benchmark, with their own N and sub-arcs.
PROBLEMS = ("earth_venus_min_time", "earth_mars_min_time")
#: Ipopt iteration budget of the cold start: four times what the warm polish needs, so
#: that a cold start that stalls is seen as such.
COLD_MAX_ITER = 1000


def _flown_success(problem, result):
    """Converged, and the schedule flown on CVODES reaches the target to 1 m and 1 mm/s."""
    from esail_opt.optimisation.polish import TOLERANCE
    from esail_opt.optimisation.verify import verify, within

    misses = verify(problem, result).misses
    r, v = misses.get("target_miss_r_km"), misses.get("target_miss_v_m_s")
    return result.converged and within(misses, TOLERANCE), {"position_km": r, "velocity_m_s": v}


def _record(case, side, problem, result, seconds):
    """Put one path's time, Ipopt record, flown time of flight and success in ``case``."""
    import numpy as np

    from esail_opt.physics import constants as units

    case[f"{side}_seconds"] = seconds
    case[f"{side}_status"] = result.status
    case[f"{side}_tof_days"] = (units.time_to_days(float(np.sum(result.durations)))
                                if result.converged else None)
    case[f"{side}_success"], case[f"{side}_target_miss"] = _flown_success(problem, result)


def _polish_case(problem):
    """Closed form + polish against cold exact shooting, both from the same seed."""
    import numpy as np

    from esail_opt.optimisation.polish import exact_guess, polish, polish_options
    from esail_opt.optimisation.ipopt import solve_problem, solve_transcription
    from esail_opt.optimisation.segment_methods import CVODES
    from esail_opt.optimisation.seed import initial_guess
    from esail_opt.optimisation.transcription import transcribe

    seed = initial_guess(problem)
    case = {"problem": problem.name, "segments": seed.alpha.size,
            "sub_arcs": problem.segments.sub_arcs, "equal_segments": problem.segments.equal}

    start = time.perf_counter()
    result, tr = solve_problem(problem, guess=seed)
    case["closed_form_seconds"] = time.perf_counter() - start
    case["closed_form_iterations"] = result.iterations
    start = time.perf_counter()
    exact, _ = polish(problem, result)
    case["polish_seconds"] = time.perf_counter() - start
    case["polish_iterations"] = exact.iterations
    _record(case, "warm", problem, exact, case["closed_form_seconds"] + case["polish_seconds"])

    start = time.perf_counter()
    durations = np.diff(np.r_[0.0, seed.nodes[4]])
    cold_start = exact_guess(problem, problem.x0(), dataclasses.replace(seed, lengths=durations))
    cold_tr = transcribe(problem, CVODES(in_time=True), cold_start)
    cold = solve_transcription(cold_tr, polish_options(max_iter=COLD_MAX_ITER))
    case["cold_iterations"] = cold.iterations
    _record(case, "cold", problem, cold, time.perf_counter() - start)
    case["ratio"] = ratio(case)
    return case


def ratio(case):
    """cold_seconds / warm_seconds, or None when either side failed: a failed side has
    no time to a solution, and the time it took to fail would flatter the other."""
    if not (case["cold_success"] and case["warm_success"]):
        return None
    return case["cold_seconds"] / case["warm_seconds"]


def _outcome(case, side):
    ok = "success" if case[f"{side}_success"] else "FAILED"
    tof = case[f"{side}_tof_days"]
    return (f"s ({case[f'{side}_status']}, {ok}"
            + (f", tof {tof:.3f} d)" if tof is not None else ")"))


def _print(case):
    print_table(f"polish: {case['problem']}, N = {case['segments']} x "
                f"{case['sub_arcs']} sub-arcs", [
                    ("closed form", case["closed_form_seconds"],
                     f"s, {case['closed_form_iterations']} it"),
                    ("+ polish", case["polish_seconds"], f"s, {case['polish_iterations']} it"),
                    ("warm total", case["warm_seconds"], _outcome(case, "warm")),
                    ("cold CVODES shooting", case["cold_seconds"],
                     f"{_outcome(case, 'cold')}, {case['cold_iterations']} it"),
                    ("ratio", "n/a" if case["ratio"] is None else case["ratio"],
                     "(cold / warm)" if case["ratio"] is not None
                     else "(one side failed: no time to a solution to compare)")])


def run(out, repeats):
    """Warm (closed form, then polish) against cold exact shooting; writes ``polish.json``.

    For each of :data:`PROBLEMS`, as shipped, both paths start from the same seed
    (``seed.initial_guess``): warm is the closed-form NLP (``solve_problem``) then the
    polish; cold is the polish's own NLP (at most :data:`COLD_MAX_ITER` iterations), its
    nodes flown by CVODES so that continuity holds at the start.  Success and ``ratio`` as
    in :func:`_flown_success` and :func:`ratio`.  Wall times of building and solving, one
    run each (``repeats`` is unused: a cold start takes minutes).  Returns the path written.
    """
    from esail_opt.app.outputs import write_json

    solved = []
    for name in PROBLEMS:
        print(f"bench polish: {name} ...", flush=True)
        solved.append(_polish_case(shipped_problem(name)))
    data = {"cases": solved, "cold_max_iter": COLD_MAX_ITER,
            "how": ("one run each, wall time of building + solving; warm = closed-form solve "
                    "+ polish, cold = exact CVODES-in-time NLP from the constant-pitch seed; "
                    "success = Solve_Succeeded and CVODES target miss < 1 m and 1 mm/s; "
                    "ratio = cold_seconds / warm_seconds, null when either side failed")}
    for case in solved:
        _print(case)
    path = Path(out) / "polish.json"
    write_json(path, data)
    return path
