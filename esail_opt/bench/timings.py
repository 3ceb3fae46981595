"""The timing benchmarks (``esail_opt.bench`` merges their ``BENCHES`` with the others).

Each one times its subject against a baseline measured in the same run (machines are
shared and noisy, so only ratios mean anything), prints a table and writes
``<out>/<name>.json``.  ``BENCHES`` maps a name to ``fn(out_dir, repeats)``, which
returns the path it wrote."""

import statistics
import time


def median_seconds(fn, repeats):
    """Median wall time of ``repeats`` calls of ``fn()`` after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def print_table(title, rows):
    """Print ``rows`` of (label, value, unit) under a title, aligned."""
    print(title)
    width = max(len(label) for label, _, _ in rows)
    for label, value, unit in rows:
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        print(f"  {label:<{width}}  {text} {unit}".rstrip())


BENCHES = {}


def propagate(out, repeats):
    """The paper's 10-year orbit raising (Sec. 3) three ways, timed in one run.

    * the rectified closed form: 20 arcs of six months on its own clock, one
      compiled Function call returning the 20 states at the rectification points;
    * CVODES at 1e-12 on Eqs. 1-2, the same schedule, the same 20 states;
    * Ref. [10]'s model at the same 20 times;
    * and, for context, the closed form with the same arcs given by their angles
      (no root on its clock, as the optimiser uses it) and, since this case never
      changes attitude, CVODES in one call with 20 output times (no restarts).

    Each time is the median of ``repeats`` calls made with arguments already in
    the form the Function takes, so only the evaluation is measured.  Accuracy is
    the distance between final positions against CVODES after 10 years (the
    closed form with 20 arcs runs about 11 deg ahead in theta; that dominates its
    km error), with the radial and angular parts beside it.
    """
    import math
    from pathlib import Path

    import numpy as np

    from esail_opt.app.files import write_json
    from esail_opt.physics import constants as units
    from esail_opt.physics.thrust import radial_transverse
    from esail_opt.propagation.rectified import rectified_function
    from esail_opt.propagation.ref10 import ref10_function
    from esail_opt.propagation.simulate import schedule_function
    from esail_opt.propagation.simulate import segment_integrator as simulate_segment

    arcs, years, ac_mm_s2, alpha_deg = 20, 10.0, 0.1, 45.0
    ac, alpha = units.accel_from_mm_s2(ac_mm_s2), math.radians(alpha_deg)
    horizon = units.time_from_years(years)
    x0 = np.array([1.0, 0.0, 0.0, 1.0, 0.0])
    row = np.ones((1, arcs))
    args = (x0, ac * row, alpha * row, horizon / arcs * row)
    closed = rectified_function(arcs, 1, "time")
    cvodes = schedule_function(arcs, 1, "time")
    R, T = (float(v) for v in radial_transverse(alpha))
    times = horizon / arcs * np.arange(1, arcs + 1)[None, :]
    ref10 = ref10_function(arcs)

    # The attitude never changes in this case, so CVODES could also fly all 10
    # years in one call with 20 output times (no restarts); timed too, for honesty,
    # though the schedule form above is the one that serves any pitch schedule.
    single = simulate_segment(arcs, "time")
    single_args = (x0, ac, alpha, horizon)
    # The optimiser's form: the same 20 arcs given by their angles (found by the
    # timed run), so no root on the clock is needed; the same 20 states result.
    by_angle = rectified_function(arcs, 1, "theta")
    angles = np.diff(np.r_[0.0, np.array(closed(*args)[0])[1]])[None, :]
    angle_args = (x0, ac * row, alpha * row, angles)
    seconds = {
        "closed_form": median_seconds(lambda: closed(*args), repeats),
        "closed_form_theta_lengths": median_seconds(lambda: by_angle(*angle_args), repeats),
        "cvodes": median_seconds(lambda: cvodes(*args), repeats),
        "cvodes_single_call": median_seconds(lambda: single(*single_args), repeats),
        "ref10": median_seconds(lambda: ref10(times, 1.0, ac, R, T, 0.0), repeats),
    }
    states = {
        "closed_form": np.array(closed(*args)[0]),
        "cvodes": np.array(cvodes(*args)),
        "ref10": np.array(ref10(times, 1.0, ac, R, T, 0.0)),
    }

    def position_km(a, b):
        """Distance between the planar positions (r, theta) of two states, km."""
        gap = math.sqrt(a[0] ** 2 + b[0] ** 2 - 2 * a[0] * b[0] * math.cos(a[1] - b[1]))
        return units.length_to_km(gap)

    truth = states["cvodes"][:, -1]
    final = {key: states[key][:, -1] for key in ("closed_form", "ref10")}
    data = {
        "case": {"ac_mm_s2": ac_mm_s2, "alpha_deg": alpha_deg, "r0_au": 1.0, "years": years,
                 "arcs": arcs, "rectifications": arcs - 1, "states_compared": arcs,
                 "cvodes_tolerance": 1e-12},
        "repeats": repeats,
        "closed_form_seconds": seconds["closed_form"],
        "cvodes_seconds": seconds["cvodes"],
        "ref10_seconds": seconds["ref10"],
        "ratio_cvodes_over_closed_form": seconds["cvodes"] / seconds["closed_form"],
        "ratio_cvodes_over_ref10": seconds["cvodes"] / seconds["ref10"],
        "closed_form_theta_lengths_seconds": seconds["closed_form_theta_lengths"],
        "ratio_cvodes_over_closed_form_theta_lengths":
            seconds["cvodes"] / seconds["closed_form_theta_lengths"],
        "closed_form_theta_lengths_max_diff_km": units.length_to_km(float(np.max(np.abs(
            np.array(by_angle(*angle_args)[0])[0] - states["closed_form"][0])))),
        "cvodes_single_call_seconds": seconds["cvodes_single_call"],
        "ratio_cvodes_single_call_over_closed_form":
            seconds["cvodes_single_call"] / seconds["closed_form"],
        "cvodes_single_call_max_diff_km": units.length_to_km(float(np.max(np.abs(
            np.array(single(*single_args))[0] - states["cvodes"][0])))),
        "closed_form_final_err_km": position_km(final["closed_form"], truth),
        "ref10_final_err_km": position_km(final["ref10"], truth),
        "closed_form_final_err_r_km": units.length_to_km(abs(final["closed_form"][0] - truth[0])),
        "ref10_final_err_r_km": units.length_to_km(abs(final["ref10"][0] - truth[0])),
        "closed_form_final_err_theta_deg": math.degrees(abs(final["closed_form"][1] - truth[1])),
        "ref10_final_err_theta_deg": math.degrees(abs(final["ref10"][1] - truth[1])),
        "closed_form_max_err_r_km": units.length_to_km(
            float(np.max(np.abs(states["closed_form"][0] - states["cvodes"][0])))),
        "note": "medians of one Function call each, same run and machine; errors against "
                "CVODES at the 20 rectification times; *_final_err_km is the distance between "
                "final positions",
    }
    print_table("bench propagate: 10-year orbit raising, 20 arcs (19 rectifications), "
                f"median of {repeats}", [
                    ("closed form (rectified, compiled)", 1e6 * data["closed_form_seconds"], "us"),
                    ("closed form, same arcs given by angle",
                     1e6 * data["closed_form_theta_lengths_seconds"], "us"),
                    ("CVODES 1e-12", 1e6 * data["cvodes_seconds"], "us"),
                    ("Ref. [10]", 1e6 * data["ref10_seconds"], "us"),
                    ("CVODES 1e-12, one call (no restarts)",
                     1e6 * data["cvodes_single_call_seconds"], "us"),
                    ("ratio CVODES / closed form", data["ratio_cvodes_over_closed_form"], ""),
                    ("ratio CVODES one call / closed form",
                     data["ratio_cvodes_single_call_over_closed_form"], ""),
                    ("closed form final position error", data["closed_form_final_err_km"], "km"),
                    ("Ref. [10] final position error", data["ref10_final_err_km"], "km"),
                ])
    path = Path(out) / "propagate.json"
    write_json(path, data)
    return path


BENCHES["propagate"] = propagate


def _timed_nlps(problem, guess, segments, runs):
    """Solve the NLP of ``problem`` from ``guess`` once per segment Function, timed.

    Parameters
    ----------
    problem : Problem
    guess : transcription.Guess
        Shared by every segment Function, so only the arcs differ.
    segments : dict
        Name -> segment Function (``transcription.closed_form_segment`` or
        ``cvodes_segment``).
    runs : int
        Timed solves per Function; the median counts.

    Returns
    -------
    dict
        Name -> {"seconds", "iterations", "status", "objective", "result"}: the median
        wall time of ``nlpsol`` construction plus the Ipopt solve (MUMPS, exact Hessian),
        and the last run's :class:`~esail_opt.optimisation.ipopt.NLPResult`.
    """
    from esail_opt.optimisation.ipopt import solve_transcription
    from esail_opt.optimisation.transcription import transcribe

    out = {}
    for name, segment in segments.items():
        tr = transcribe(problem, segment, guess)
        times = []
        for _ in range(runs):
            start = time.perf_counter()
            result = solve_transcription(tr)
            times.append(time.perf_counter() - start)
        out[name] = {"seconds": statistics.median(times), "iterations": result.iterations,
                     "status": result.status, "objective": result.objective,
                     "result": result}
    return out


def _shooting_segments(problem):
    """The closed-form and the CVODES-arc segment Functions of ``problem``'s NLP."""
    from esail_opt.optimisation.transcription import closed_form_segment, cvodes_segment

    seg = problem.segments
    return {
        "closed_form": closed_form_segment(seg.sub_arcs, problem.sail.coefficients,
                                           seg.extrapolate),
        "cvodes": cvodes_segment(seg.sub_arcs, problem.sail.coefficients),
    }


def _equal_lengths(problem):
    """One NLP, one start: a free-length problem is normally solved in two stages (equal
    lengths, then free); the benchmarks time the single equal-length NLP."""
    import dataclasses

    return dataclasses.replace(
        problem, segments=dataclasses.replace(problem.segments, equal=True))


def _solve_case(problem_file, repeats):
    """Time one problem's NLP with closed-form arcs and with CVODES arcs (see :func:`solve`)."""
    from esail_opt.optimisation.problem_file import load_problem
    from esail_opt.optimisation.transcription import initial_guess

    problem = _equal_lengths(load_problem(problem_file))
    seg = problem.segments
    guess = initial_guess(problem)
    runs = max(1, min(repeats, 3))
    case = {"problem": problem.name, "segments": guess.alpha.size, "sub_arcs": seg.sub_arcs,
            "extrapolate": seg.extrapolate, "runs": runs}
    for name, timed in _timed_nlps(problem, guess, _shooting_segments(problem), runs).items():
        case[f"{name}_seconds"] = timed["seconds"]
        case[f"{name}_iterations"] = timed["iterations"]
        case[f"{name}_status"] = timed["status"]
        case[f"{name}_objective"] = timed["objective"]
    case["ratio"] = case["cvodes_seconds"] / case["closed_form_seconds"]
    return case


#: Problems of the solve benchmark: short arcs at a high acceleration, then the paper's
#: low-acceleration orbit raising, where each CVODES arc needs more steps.
SOLVE_PROBLEMS = ("earth_venus_min_time.py", "orbit_raising_10yr.py")


def solve(out, repeats):
    """The optimiser's NLP with closed-form arcs against the same NLP with CVODES arcs.

    For each problem in ``SOLVE_PROBLEMS`` (shipped files, their own N and sub-arcs, with
    equal segment lengths so that each side is one NLP from one start) both NLPs have the same variables, bounds, constraints (the CVODES one's q3 rows are
    constant), initial guess and Ipopt options (MUMPS, exact Hessian); only the segment
    Function differs: the Richardson-extrapolated closed-form chain, or one CVODES
    integration of Eqs. 1-2 in theta at 1e-12 with CasADi's sensitivities.  Each is timed
    from ``nlpsol`` construction to the end of the solve, the median of
    ``min(repeats, 3)`` runs.  ``ratio`` is cvodes_seconds / closed_form_seconds.  The
    top-level keys are the first problem's; ``cases`` holds all.
    """
    from pathlib import Path

    from esail_opt.app.files import write_json

    folder = Path(__file__).resolve().parents[2] / "problems"
    cases = [_solve_case(folder / name, repeats) for name in SOLVE_PROBLEMS]
    keys = ("closed_form_seconds", "cvodes_seconds", "closed_form_iterations",
            "cvodes_iterations", "ratio")
    data = {key: cases[0][key] for key in keys}
    data["problem"] = cases[0]["problem"]
    data["cases"] = cases
    data["how"] = ("median wall time of nlpsol construction + solve; same problem, N, "
                   "initial guess and Ipopt options; ratio = cvodes_seconds / "
                   "closed_form_seconds")
    for case in cases:
        print_table(f"solve: {case['problem']}, N = {case['segments']} x {case['sub_arcs']} "
                    f"sub-arcs, median of {case['runs']}", [
                        (name, case[f"{key}_seconds"],
                         f"s, {case[f'{key}_iterations']} it, {case[f'{key}_status']}, "
                         f"objective {case[f'{key}_objective']:.9g}")
                        for name, key in (("closed form", "closed_form"), ("CVODES arcs", "cvodes"))
                    ] + [("ratio", case["ratio"], "(CVODES / closed form)")])
    path = Path(out) / "solve.json"
    write_json(path, data)
    return path


BENCHES["solve"] = solve


#: Problems of the polish benchmark, with the shipped N and sub-arcs.
POLISH_PROBLEMS = ("earth_venus_min_time.py", "earth_mars_min_time.py")
#: Ipopt iteration budget of the cold start: a fifth of the solve's default, and four
#: times what the warm polish needs, so that a cold start that stalls is seen as such.
COLD_MAX_ITER = 1000


def _flown_success(problem, result):
    """Converged, and the schedule flown on CVODES reaches the target to 1 m and 1 mm/s."""
    from esail_opt.optimisation.exact import TOLERANCE
    from esail_opt.optimisation.verify import verify, within

    misses = verify(problem, result, samples=1).misses
    r, v = misses.get("target_miss_r_km"), misses.get("target_miss_v_m_s")
    metres = {"position_m": None if r is None else 1e3 * r,
              "velocity_mm_s": None if v is None else 1e3 * v}
    return result.converged and within(misses, TOLERANCE), metres


def _polish_case(problem_file):
    """Closed form + polish against cold exact shooting, both from the same seed."""
    import numpy as np

    from esail_opt.optimisation.exact import exact_guess, polish, polish_options
    from esail_opt.optimisation.problem_file import load_problem
    from esail_opt.optimisation.ipopt import solve_problem, solve_transcription
    from esail_opt.optimisation.transcription import (
        cvodes_time_segment, initial_guess, transcribe)
    from esail_opt.physics import constants as units

    problem = load_problem(problem_file)
    seed = initial_guess(problem)
    case = {"problem": problem.name, "segments": seed.alpha.size,
            "sub_arcs": problem.segments.sub_arcs, "equal_segments": problem.segments.equal}

    start = time.perf_counter()
    result, tr = solve_problem(problem, guess=seed)
    case["closed_form_seconds"] = time.perf_counter() - start
    case["closed_form_iterations"] = result.iterations
    start = time.perf_counter()
    exact, _ = polish(problem, result, tr.guess.revolutions_k)
    case["polish_seconds"] = time.perf_counter() - start
    case["polish_iterations"] = exact.iterations
    case["warm_seconds"] = case["closed_form_seconds"] + case["polish_seconds"]
    case["warm_status"] = exact.status
    case["warm_tof_days"] = units.time_to_days(float(np.sum(exact.durations)))
    case["warm_success"], case["warm_target_miss"] = _flown_success(problem, exact)

    start = time.perf_counter()
    durations = np.diff(np.r_[0.0, seed.nodes[4]])
    cold_start = exact_guess(problem, problem.x0(), seed.alpha, durations, seed.nodes,
                             seed.nu0, seed.revolutions_k)
    cold_tr = transcribe(problem, cvodes_time_segment(problem.sail.coefficients), cold_start,
                         independent="time")
    cold = solve_transcription(cold_tr, polish_options(max_iter=COLD_MAX_ITER))
    case["cold_seconds"] = time.perf_counter() - start
    case["cold_iterations"] = cold.iterations
    case["cold_status"] = cold.status
    case["cold_tof_days"] = (units.time_to_days(float(np.sum(cold.durations)))
                             if cold.converged else None)
    case["cold_success"], case["cold_target_miss"] = _flown_success(problem, cold)
    case["ratio"] = case["cold_seconds"] / case["warm_seconds"]
    return case


def polish_bench(out, repeats):
    """Closed-form solve + exact polish against a cold CVODES multiple shooting.

    For each problem in ``POLISH_PROBLEMS`` (shipped N and sub-arcs, free or equal
    segments as shipped) both paths start from the same constant-pitch seed
    (``transcription.initial_guess``):

    * warm: the closed-form NLP (``solve_problem``: equal lengths, then free), then
      the polish on CVODES arcs in time warm-started from it;
    * cold: the polish's own NLP (CVODES arcs in time, same Ipopt options, at most
      ``COLD_MAX_ITER`` iterations) started directly from the seed, its nodes flown
      by CVODES so continuity holds at the start.

    Success means Ipopt converged (Solve_Succeeded) and the schedule flown on CVODES
    reaches the target within 1 m and 1 mm/s.  Wall times cover building and solving
    (and, for the cold start, flying its seed); one run each (``repeats`` is not
    used: a cold start takes minutes).  ``ratio`` is cold_seconds / warm_seconds.
    """
    from pathlib import Path

    from esail_opt.app.files import write_json

    folder = Path(__file__).resolve().parents[2] / "problems"
    cases = []
    for name in POLISH_PROBLEMS:
        print(f"bench polish: {name} ...", flush=True)
        cases.append(_polish_case(folder / name))
    data = {"cases": cases, "cold_max_iter": COLD_MAX_ITER,
            "how": ("one run each, wall time of building + solving; warm = closed-form solve "
                    "+ polish, cold = exact CVODES-in-time NLP from the constant-pitch seed; "
                    "success = Solve_Succeeded and CVODES target miss < 1 m and 1 mm/s; "
                    "ratio = cold_seconds / warm_seconds")}
    for case in cases:
        def outcome(side):
            ok = "success" if case[f"{side}_success"] else "FAILED"
            tof = case[f"{side}_tof_days"]
            return (f"s ({case[f'{side}_status']}, {ok}"
                    + (f", tof {tof:.3f} d)" if tof is not None else ")"))
        print_table(f"polish: {case['problem']}, N = {case['segments']} x "
                    f"{case['sub_arcs']} sub-arcs", [
                        ("closed form", case["closed_form_seconds"],
                         f"s, {case['closed_form_iterations']} it"),
                        ("+ polish", case["polish_seconds"], f"s, {case['polish_iterations']} it"),
                        ("warm total", case["warm_seconds"], outcome("warm")),
                        ("cold CVODES shooting", case["cold_seconds"],
                         f"{outcome('cold')}, {case['cold_iterations']} it"),
                        ("ratio", case["ratio"], "(cold / warm)")])
    path = Path(out) / "polish.json"
    write_json(path, data)
    return path


BENCHES["polish"] = polish_bench


def _collocation_module():
    """Import the independent collocation reference script (tests/reference/collocation.py)
    by its path: it is a script, not part of the package, and only this benchmark runs it.

    Raises
    ------
    InputError
        If the script is not there (an installed package without the repository's tests).
    """
    import importlib.util
    from pathlib import Path

    from esail_opt.errors import InputError

    path = Path(__file__).resolve().parents[2] / "tests" / "reference" / "collocation.py"
    if not path.is_file():
        raise InputError(f"bench lowthrust needs the collocation reference script {path}, "
                         "which is not there (run from a repository checkout)")
    spec = importlib.util.spec_from_file_location("esail_collocation_reference", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


#: The low-thrust benchmark's problem file and its entry in the collocation reference.
LOWTHRUST_PROBLEM = "earth_mars_low_thrust.py"
LOWTHRUST_REFERENCE = "earth_mars_low"
#: Constant pitch of the collocation's start, deg: the same as the shooting NLPs' seed.
LOWTHRUST_GUESS_DEG = 45.0


def lowthrust(out, repeats):
    """Earth-Mars at a_c = 0.1 mm/s^2 (about 6.5 revolutions): three optimisers, one run.

    * closed-form multiple shooting: the shipped ``problems/earth_mars_low_thrust.py``
      (its per-revolution segment count, resolved by the seed), one equal-length NLP;
    * CVODES-arc multiple shooting: the same NLP, N, initial guess and Ipopt options,
      each segment one CVODES integration of Eqs. 1-2 in theta at 1e-12 with CasADi's
      sensitivities (``transcription.cvodes_segment``);
    * the collocation reference (``tests/reference/collocation.py``, imported from its
      path), along the script's own path from one start (:func:`_collocation_solve`):
      the constant-pitch +45 deg flight (the shooting seed's pitch) solved on the search
      mesh, re-solved on the reporting mesh and on twice it, the meshes of the stored
      reference.  Its multistart over other starts is not timed (it only guards against
      other basins; ``reference_multistart_seconds`` is its stored total).  A single
      cold solve straight on the fine mesh was tried and is no substitute: it took
      29.6 s (227 iterations) and stopped at a discrete KKT point whose control misses
      the target by 11,000 km when flown (3335.53 d), the artefact the script's
      docstring describes.

    Each time is wall time of solver construction plus the Ipopt solve (all three
    collocation stages), the median of ``min(repeats, 3)`` runs per method.  The seeds
    (timed and recorded separately) and the shooting NLP's MX graph (milliseconds) are
    built outside the timing.  Every result is verified: the shooting
    schedules are flown on Eqs. 1-2 by CVODES (``optimisation.verify``), the collocation
    control by the script's own DOP853 re-integration; a time of flight is reported with
    the verified miss of the target beside it.
    """
    import json
    import math
    from pathlib import Path

    from esail_opt.app.files import write_json
    from esail_opt.optimisation.problem_file import load_problem
    from esail_opt.optimisation.transcription import initial_guess
    from esail_opt.optimisation.verify import verify
    from esail_opt.physics import constants as units

    folder = Path(__file__).resolve().parents[2] / "problems"
    problem = _equal_lengths(load_problem(folder / LOWTHRUST_PROBLEM))
    colloc = _collocation_module()
    reference = json.loads(colloc.OUTPUT.read_text())[LOWTHRUST_REFERENCE]
    radius = problem.target.radius_au
    if (reference["ac_mm_s2"], reference["rf_au"]) != (problem.sail.ac_mm_s2, radius):
        raise RuntimeError(f"{LOWTHRUST_PROBLEM} and the reference case "
                           f"{LOWTHRUST_REFERENCE} are not the same transfer")

    start = time.perf_counter()
    guess = initial_guess(problem)
    guess_seconds = time.perf_counter() - start
    n = guess.alpha.size
    print(f"bench lowthrust: {problem.name}, N = {n} x {problem.segments.sub_arcs} sub-arcs; "
          "solving with closed-form arcs ...", flush=True)
    segments = _shooting_segments(problem)
    runs = max(1, min(repeats, 3))
    shooting = _timed_nlps(problem, guess, {"closed_form": segments["closed_form"]}, runs)
    print("bench lowthrust: solving with CVODES arcs ...", flush=True)
    shooting.update(_timed_nlps(problem, guess, {"cvodes": segments["cvodes"]}, runs))

    data = {"problem": problem.name, "ac_mm_s2": problem.sail.ac_mm_s2, "rf_au": radius,
            "segments": n, "sub_arcs": problem.segments.sub_arcs,
            "segments_per_revolution": problem.segments.per_revolution,
            "runs": runs,
            "seed_seconds": guess_seconds}
    for name, timed in shooting.items():
        result = timed["result"]
        check = verify(problem, result)
        data[f"{name}_seconds"] = timed["seconds"]
        data[f"{name}_iterations"] = timed["iterations"]
        data[f"{name}_status"] = timed["status"]
        data[f"{name}_tof_days"] = units.time_to_days(float(check.cvodes[4, -1]))
        data[f"{name}_target_miss_r_km"] = check.misses["target_miss_r_km"]
        data[f"{name}_target_miss_v_m_s"] = check.misses["target_miss_v_m_s"]
        data[f"{name}_revolutions"] = float(result.nodes[1, -1] / (2 * math.pi))

    print("bench lowthrust: solving by collocation (search mesh, then the reference's "
          "meshes) ...", flush=True)
    ac = problem.sail.ac
    start = time.perf_counter()
    seed = colloc.constant_pitch_guess(ac, radius, LOWTHRUST_GUESS_DEG)
    data["collocation_guess_seconds"] = time.perf_counter() - start
    totals = []
    for _ in range(runs):
        sol, stages, seconds = _collocation_solve(colloc, seed, ac, radius)
        totals.append(seconds)
    check = colloc.verify(sol, ac, radius)
    data.update({
        "collocation_seconds": statistics.median(totals),
        "collocation_stages": stages,
        "collocation_intervals": sol["N"],
        "collocation_iterations": sum(st["iterations"] for st in stages),
        "collocation_status": sol["status"],
        "collocation_tof_days": units.time_to_days(sol["tf"]),
        "collocation_target_miss_r_km": float(check["miss_r_km"]),
        "collocation_target_miss_v_m_s": float(check["miss_v_m_s"]),
        "collocation_revolutions": float(colloc.revolutions(sol)),
        "reference_tof_days": reference["tof_days"],
        "reference_intervals": [reference["intervals"], reference["intervals_fine"]],
        "reference_multistart_seconds": reference["runtime_seconds"],
    })
    data["ratio_cvodes_over_closed_form"] = data["cvodes_seconds"] / data["closed_form_seconds"]
    data["ratio_collocation_over_closed_form"] = (data["collocation_seconds"]
                                                  / data["closed_form_seconds"])
    for name in ("closed_form", "cvodes", "collocation"):
        data[f"{name}_tof_error_vs_reference"] = (data[f"{name}_tof_days"]
                                                  / reference["tof_days"] - 1)
    data["how"] = (
        "wall time of solver construction + Ipopt solve (MUMPS, exact Hessian) on one "
        "machine in one run; shooting NLPs share N, equal segment lengths, the seed and the "
        "Ipopt options; collocation = tests/reference/collocation.py's Radau IIA from a "
        "constant-pitch +45 deg start, search mesh then the reference's N and 2N meshes "
        "(all three stages timed); tof flown on Eqs. 1-2 "
        "(CVODES for the shooting schedules, DOP853 for the collocation control), with the "
        "target misses of those flights; reference_multistart_seconds is the stored "
        "reference's whole multistart + refinement, for context")
    rows = []
    for label, key in (("closed-form shooting", "closed_form"), ("CVODES-arc shooting", "cvodes"),
                       ("collocation", "collocation")):
        off = 100 * data[f"{key}_tof_error_vs_reference"]
        rows.append((label, data[f"{key}_seconds"],
                     f"s, {data[f'{key}_iterations']} it, {data[f'{key}_status']}, tof "
                     f"{data[f'{key}_tof_days']:.4f} d ({off:+.4f} %), "
                     f"miss {data[f'{key}_target_miss_r_km']:.4g} km "
                     f"{data[f'{key}_target_miss_v_m_s']:.3g} m/s"))
    rows += [("ratio CVODES / closed form", data["ratio_cvodes_over_closed_form"], ""),
             ("ratio collocation / closed form", data["ratio_collocation_over_closed_form"], ""),
             ("collocation reference tof", f"{data['reference_tof_days']:.4f}", "d")]
    print_table(f"bench lowthrust: Earth-Mars, a_c = {problem.sail.ac_mm_s2:g} mm/s^2, "
                f"N = {n} x {problem.segments.sub_arcs} sub-arcs", rows)
    path = Path(out) / "lowthrust.json"
    write_json(path, data)
    return path


BENCHES["lowthrust"] = lowthrust


def _collocation_solve(colloc, seed, ac, radius):
    """The collocation script's path to its answer, from one start, timed.

    Search mesh (sized by the script for the seed's time of flight), then the reporting
    mesh sized for that solution, then twice it (the script's refinement study, whose
    fine solution is the stored reference), each warm-started from the last through the
    script's ``solution_guess``.  Every stage's NLP construction counts.  The script caps
    each solve at 30 s of CPU for its multistart; the cap is lifted so that a slow stage
    is measured rather than cut short.

    Returns
    -------
    tuple
        (fine solution dict, per-stage [{"intervals", "iterations", "status",
        "seconds"}], total seconds).
    """
    colloc.MAX_CPU_SECONDS = 1e5
    stages = []
    total = 0.0

    def stage(n, guess):
        nonlocal total
        start = time.perf_counter()
        sol = colloc.Transcription(n, ac, radius).solve(guess)
        seconds = time.perf_counter() - start
        total += seconds
        stages.append({"intervals": n, "iterations": int(sol["iterations"]),
                       "status": sol["status"], "seconds": seconds})
        return sol

    search = stage(colloc.intervals_for(seed.tf, radius, colloc.INTERVALS_PER_REV_SEARCH,
                                        colloc.MIN_INTERVALS_SEARCH), seed)
    n = colloc.intervals_for(search["tf"], radius, colloc.INTERVALS_PER_REV_REPORT,
                             colloc.MIN_INTERVALS_REPORT)
    report = stage(n, colloc.solution_guess(search))
    fine = stage(2 * n, colloc.solution_guess(report))
    return fine, stages, total


SWEEP_PROBLEM = '''
import esail_opt as eo

problem = eo.Problem(
    name="bench_sweep_earth_mars",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=20, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
)
'''
SWEEP_PARAM = "ac_mm_s2=0.6:1.6:8"


def sweep(out, repeats):
    """Sweep wall time on a process pool of 1 worker against 2, the same sweep, one run.

    The family is Earth-Mars minimum time at 20 segments x 2 sub-arcs over 8 values of
    a_c in [0.6, 1.6] mm/s^2 (a few seconds of Ipopt each), so the members outweigh the
    pool's start-up (each spawned worker imports CasADi once).  The wall time covers
    the whole ``sweep.run``: pool start, every member, pool shutdown.  With ``repeats``
    above 1 the two pool sizes alternate (at most 3 runs each) and the medians count,
    so that a burst of load on a shared machine hits both alike.  Whether the two
    pools return the same numbers is recorded as well.
    """
    import os
    import tempfile
    from pathlib import Path

    from esail_opt.app import sweep as family
    from esail_opt.app.files import write_json

    runs = max(1, min(repeats, 3))
    seconds = {1: [], 2: []}
    member_sums = {1: [], 2: []}
    rows = {}
    # Two workers can only help if two CPUs are free: the load is recorded so that a
    # ratio near 1 on a busy shared machine reads as what it is.
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="esail_bench_sweep_") as tmp:
        path = Path(tmp) / "bench_sweep_earth_mars.py"
        path.write_text(SWEEP_PROBLEM)
        for run in range(runs):
            for workers in (1, 2):
                print(f"bench sweep: run {run + 1}/{runs}, {workers} worker(s) ...", flush=True)
                start = time.perf_counter()
                result = family.run(path, SWEEP_PARAM, workers=workers)
                seconds[workers].append(time.perf_counter() - start)
                member_sums[workers].append(sum(r["seconds"] for r in result["rows"]))
                rows[workers] = [{k: v for k, v in row.items() if k != "seconds"}
                                 for row in result["rows"]]
    one, two = statistics.median(seconds[1]), statistics.median(seconds[2])
    data = {
        "case": {"problem": "Earth-Mars minimum time, 1 au -> 1.524 au, 20 segments x 2 "
                            "sub-arcs", "param": SWEEP_PARAM, "members": len(rows[1])},
        "runs": runs,
        "cpus": os.cpu_count(),
        "one_worker_seconds": one,
        "two_workers_seconds": two,
        "ratio": one / two,
        "one_worker_runs_seconds": seconds[1],
        "two_workers_runs_seconds": seconds[2],
        "member_seconds_sum_one_worker": statistics.median(member_sums[1]),
        "member_seconds_sum_two_workers": statistics.median(member_sums[2]),
        "load_average_1_5_15_before": list(load_before),
        "load_average_1_5_15_after": list(os.getloadavg()),
        "converged": sum(1 for r in rows[1] if r["converged"]),
        "identical_rows": rows[1] == rows[2],
        "how": "wall time of esail_opt.app.sweep.run (spawned process pool start, all members, "
               "shutdown), median over alternating runs, same machine and run; ratio = "
               "one_worker_seconds / two_workers_seconds (2 would be perfect scaling)",
    }
    print_table(f"bench sweep: {data['case']['members']} members, median of {runs}", [
        ("1 worker", one, "s"),
        ("2 workers", two, "s"),
        ("ratio 1 / 2 workers", data["ratio"], ""),
        ("sum of member times, 1 worker", data["member_seconds_sum_one_worker"], "s"),
        ("load average before / after", f"{load_before[0]:.2f} / {os.getloadavg()[0]:.2f}", ""),
        ("identical rows", str(data["identical_rows"]), ""),
    ])
    path = Path(out) / "sweep.json"
    write_json(path, data)
    return path


BENCHES["sweep"] = sweep
