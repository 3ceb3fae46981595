"""Benchmarks.  Each one times its subject against a baseline measured in the same run
(machines are shared and noisy, so only ratios mean anything), prints a table and
writes ``<out>/<name>.json``.  ``BENCHES`` maps a name to ``fn(out_dir, repeats)``,
which returns the path it wrote."""

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

    from esail_opt.files import write_json
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


def _solve_case(problem_file, repeats):
    """Time one problem's NLP with closed-form arcs and with CVODES arcs (see :func:`solve`)."""
    import dataclasses

    import casadi as ca

    from esail_opt.optimisation.problem_file import load_problem
    from esail_opt.optimisation.solve import ipopt_options
    from esail_opt.optimisation.transcription import (
        closed_form_segment, cvodes_segment, initial_guess, transcribe)

    problem = load_problem(problem_file)
    # One NLP, one start: equal lengths (a free-length problem is normally solved in two
    # stages, equal then free; the benchmark times the single equal-length NLP).
    problem = dataclasses.replace(
        problem, segments=dataclasses.replace(problem.segments, equal=True))
    seg = problem.segments
    guess = initial_guess(problem)
    segments = {
        "closed_form": closed_form_segment(seg.sub_arcs, problem.sail.coefficients,
                                           seg.extrapolate),
        "cvodes": cvodes_segment(seg.sub_arcs, problem.sail.coefficients),
    }
    runs = max(1, min(repeats, 3))
    case = {"problem": problem.name, "segments": seg.count, "sub_arcs": seg.sub_arcs,
            "extrapolate": seg.extrapolate, "runs": runs}
    for name, segment in segments.items():
        tr = transcribe(problem, segment, guess)
        times, stats, objective = [], None, None
        for _ in range(runs):
            start = time.perf_counter()
            solver = ca.nlpsol("bench_" + name, "ipopt", tr.nlp, ipopt_options())
            sol = solver(x0=tr.x0, lbx=tr.lbx, ubx=tr.ubx, lbg=tr.lbg, ubg=tr.ubg)
            times.append(time.perf_counter() - start)
            stats, objective = solver.stats(), float(sol["f"])
        case[f"{name}_seconds"] = statistics.median(times)
        case[f"{name}_iterations"] = int(stats["iter_count"])
        case[f"{name}_status"] = stats["return_status"]
        case[f"{name}_objective"] = objective
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

    from esail_opt.files import write_json

    folder = Path(__file__).resolve().parents[1] / "problems"
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
