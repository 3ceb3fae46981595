"""``esail-opt-bench solve``: the optimiser's NLP with closed-form arcs against the same
NLP with CVODES arcs, timed in one run."""

from pathlib import Path

from esail_opt.bench.timing import (
    equal_lengths, print_table, runs_of, shooting_methods, timed_nlps)
from esail_opt.optimisation.problem_file import shipped_problem

#: Shipped problems of the solve benchmark: short arcs at a high acceleration, then the
#: paper's low-acceleration orbit raising, where each CVODES arc needs more steps.
PROBLEMS = ("earth_venus_min_time", "orbit_raising_10yr")


def _solve_case(problem, repeats):
    """Time one problem's NLP with closed-form arcs and with CVODES arcs (see :func:`run`)."""
    from esail_opt.optimisation.seed import initial_guess

    problem = equal_lengths(problem)
    seg = problem.segments
    guess = initial_guess(problem)
    runs = runs_of(repeats)
    case = {"problem": problem.name, "segments": guess.alpha.size, "sub_arcs": seg.sub_arcs,
            "extrapolate": seg.extrapolate, "runs": runs}
    for name, timed in timed_nlps(problem, guess, shooting_methods(), runs).items():
        for key in ("seconds", "iterations", "status", "objective"):
            case[f"{name}_{key}"] = timed[key]
    case["ratio"] = case["cvodes_seconds"] / case["closed_form_seconds"]
    return case


def _print(case):
    rows = [(name, case[f"{key}_seconds"],
             f"s, {case[f'{key}_iterations']} it, {case[f'{key}_status']}, "
             f"objective {case[f'{key}_objective']:.9g}")
            for name, key in (("closed form", "closed_form"), ("CVODES arcs", "cvodes"))]
    print_table(f"solve: {case['problem']}, N = {case['segments']} x {case['sub_arcs']} "
                f"sub-arcs, median of {case['runs']}",
                rows + [("ratio", case["ratio"], "(CVODES / closed form)")])


def run(out, repeats):
    """The shooting NLP on closed-form arcs against CVODES arcs; writes ``solve.json``.

    For each of :data:`PROBLEMS` (equal segment lengths: one NLP from one start) the two NLPs
    share all but the segment Function: the chain of closed-form arcs, or one CVODES
    integration of Eqs. 1-2 in theta at 1e-12, each timed by :func:`.timing.timed_nlps` over
    ``runs_of(repeats)`` runs; ``ratio`` is cvodes_seconds / closed_form_seconds.  The
    top-level keys are the first problem's; ``cases`` holds all.  Returns the path written.
    """
    from esail_opt.app.outputs import write_json

    solved = [_solve_case(shipped_problem(name), repeats) for name in PROBLEMS]
    keys = ("closed_form_seconds", "cvodes_seconds", "closed_form_iterations",
            "cvodes_iterations", "ratio")
    data = {key: solved[0][key] for key in keys}
    data["problem"] = solved[0]["problem"]
    data["cases"] = solved
    data["how"] = ("median wall time of nlpsol construction + solve; same problem, N, "
                   "initial guess and Ipopt options; ratio = cvodes_seconds / "
                   "closed_form_seconds")
    for case in solved:
        _print(case)
    path = Path(out) / "solve.json"
    write_json(path, data)
    return path
