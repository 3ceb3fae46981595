"""``esail-opt-bench lowthrust``: Earth-Mars at a_c = 0.1 mm/s^2 (about 6.5 revolutions)
by closed-form shooting, CVODES-arc shooting and collocation, timed in one run."""

import math
import statistics
import time
from pathlib import Path

from esail_opt.bench.timing import (
    equal_lengths, print_table, runs_of, shooting_methods, timed_nlps)
from esail_opt.optimisation.problem_file import shipped_problem

#: The shipped problem this bench solves.
PROBLEM = "earth_mars_low_thrust"
#: The collocation optimum of that transfer, ``earth_mars_low`` of
#: ``tests/reference/collocation_min_time.json`` (``runtime_seconds``: its whole multistart),
#: copied as an installed package has no ``tests/``; ``tests/test_bench_problems.py`` checks it.
EARTH_MARS_LOW_REFERENCE = {
    "ac_mm_s2": 0.1,
    "rf_au": 1.524,
    "tof_days": 3329.616487062407,
    "intervals": 547,
    "intervals_fine": 1094,
    "runtime_seconds": 160.6611323940001,
}

#: Constant pitch of the collocation's start, deg: the same as the shooting NLPs' seed.
GUESS_DEG = 45.0
#: CPU cap of each timed collocation solve, s: never cuts one short (the multistart's 30 s would).
NO_CPU_CAP = 1e5
#: The JSON's ``how``: what each time covers.
HOW = ("wall time of solver construction + Ipopt solve (MUMPS, exact Hessian) on one "
       "machine in one run; shooting NLPs share N, equal segment lengths, the seed and the "
       "Ipopt options; collocation = esail_opt.bench.collocation's Radau IIA from a "
       "constant-pitch +45 deg start, search mesh then the reference's N and 2N meshes "
       "(all three stages timed); tof flown on Eqs. 1-2 "
       "(CVODES for the shooting schedules, DOP853 for the collocation control), with the "
       "target misses of those flights; reference_multistart_seconds is the stored "
       "reference's whole multistart + refinement, for context")


def _shooting(problem, runs):
    """Both shooting NLPs from one seed, each verified on CVODES: the ``closed_form_*``
    and ``cvodes_*`` fields of the JSON, and the seed's time."""
    from esail_opt.optimisation.seed import initial_guess
    from esail_opt.optimisation.verify import verify
    from esail_opt.physics import constants as units

    start = time.perf_counter()
    guess = initial_guess(problem)
    data = {"seed_seconds": time.perf_counter() - start, "segments": guess.alpha.size}
    methods = shooting_methods()
    for name, label in (("closed_form", "closed-form"), ("cvodes", "CVODES")):
        print(f"bench lowthrust: {problem.name}, N = {guess.alpha.size} x "
              f"{problem.segments.sub_arcs} sub-arcs; solving with {label} arcs ...", flush=True)
        timed = timed_nlps(problem, guess, {name: methods[name]}, runs)[name]
        result = timed["result"]
        check = verify(problem, result)
        data.update({
            f"{name}_seconds": timed["seconds"],
            f"{name}_iterations": timed["iterations"],
            f"{name}_status": timed["status"],
            f"{name}_tof_days": units.time_to_days(float(check.cvodes[4, -1])),
            f"{name}_target_miss_r_km": check.misses["target_miss_r_km"],
            f"{name}_target_miss_v_m_s": check.misses["target_miss_v_m_s"],
            f"{name}_revolutions": float(result.nodes[1, -1] / (2 * math.pi)),
        })
    return data


def _collocation_solve(seed, ac, radius):
    """The collocation's path to its answer from one start, timed: search mesh, reporting
    mesh, twice it (the reference's meshes), each warm-started from the last, NLP
    construction counted.  Returns (fine solution dict, per-stage [{"intervals",
    "iterations", "status", "seconds"}], total seconds)."""
    from esail_opt.bench import collocation as colloc

    stages = []

    def stage(n, guess):
        start = time.perf_counter()
        sol = colloc.Transcription(n, ac, radius, max_cpu_seconds=NO_CPU_CAP).solve(guess)
        stages.append({"intervals": n, "iterations": int(sol["iterations"]),
                       "status": sol["status"], "seconds": time.perf_counter() - start})
        return sol

    search = stage(colloc.intervals_for(seed.tf, radius, colloc.INTERVALS_PER_REV_SEARCH,
                                        colloc.MIN_INTERVALS_SEARCH), seed)
    n = colloc.intervals_for(search["tf"], radius, colloc.INTERVALS_PER_REV_REPORT,
                             colloc.MIN_INTERVALS_REPORT)
    report = stage(n, colloc.solution_guess(search))
    fine = stage(2 * n, colloc.solution_guess(report))
    return fine, stages, sum(st["seconds"] for st in stages)


def _collocation(problem, runs):
    """The collocation's ``collocation_*`` fields: median time of ``runs`` solves from
    the constant-pitch start, the last solution's record and its DOP853 flight."""
    from esail_opt.bench import collocation as colloc
    from esail_opt.physics import constants as units

    ac, radius = problem.sail.ac, problem.target.radius_au
    start = time.perf_counter()
    seed = colloc.constant_pitch_guess(ac, radius, GUESS_DEG)
    guess_seconds = time.perf_counter() - start
    totals = []
    for _ in range(runs):
        sol, stages, seconds = _collocation_solve(seed, ac, radius)
        totals.append(seconds)
    check = colloc.verify(sol, ac, radius)
    return {
        "collocation_guess_seconds": guess_seconds,
        "collocation_seconds": statistics.median(totals),
        "collocation_stages": stages,
        "collocation_intervals": sol["N"],
        "collocation_iterations": sum(st["iterations"] for st in stages),
        "collocation_status": sol["status"],
        "collocation_tof_days": units.time_to_days(sol["tf"]),
        "collocation_target_miss_r_km": float(check["miss_r_km"]),
        "collocation_target_miss_v_m_s": float(check["miss_v_m_s"]),
        "collocation_revolutions": float(colloc.revolutions(sol)),
    }


def _print(data):
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
    print_table(f"bench lowthrust: Earth-Mars, a_c = {data['ac_mm_s2']:g} mm/s^2, "
                f"N = {data['segments']} x {data['sub_arcs']} sub-arcs", rows)



def run(out, repeats):
    """Three optimisers on the low-thrust Earth-Mars transfer; writes ``lowthrust.json``.

    * closed-form multiple shooting: the shipped :data:`PROBLEM` (its per-revolution
      segment count, resolved by the seed), one equal-length NLP;
    * CVODES-arc multiple shooting: the same NLP, N, guess and Ipopt options, each segment
      one CVODES integration of Eqs. 1-2 in theta at 1e-12 (``segment_methods.CVODES``);
    * the collocation reference (:mod:`.collocation`) along its own path from the
      constant-pitch +45 deg start (:func:`_collocation_solve`).  Its multistart, which only
      guards against other basins, is not timed; a single cold solve on the fine mesh is
      no substitute, as it stops at a discrete KKT point that does not fly.

    Each time is the median over ``runs_of(repeats)`` runs of the wall time of solver
    construction plus Ipopt solve; the seeds (timed apart) and the shooting NLP's MX graph
    are built outside it.  Each time of flight comes with its verified target miss (CVODES
    for the shooting schedules, DOP853 for the collocation control).  Returns the path.
    """
    from esail_opt.app.outputs import write_json

    problem = equal_lengths(shipped_problem(PROBLEM))
    reference = EARTH_MARS_LOW_REFERENCE
    radius = problem.target.radius_au
    if (reference["ac_mm_s2"], reference["rf_au"]) != (problem.sail.ac_mm_s2, radius):
        raise RuntimeError(f"{problem.name} and the collocation reference are not the "
                           "same transfer")
    runs = runs_of(repeats)
    data = {"problem": problem.name, "ac_mm_s2": problem.sail.ac_mm_s2, "rf_au": radius,
            "sub_arcs": problem.segments.sub_arcs,
            "segments_per_revolution": problem.segments.per_revolution, "runs": runs}
    data.update(_shooting(problem, runs))
    print("bench lowthrust: solving by collocation (search mesh, then the reference's "
          "meshes) ...", flush=True)
    data.update(_collocation(problem, runs))
    data.update({
        "reference_tof_days": reference["tof_days"],
        "reference_intervals": [reference["intervals"], reference["intervals_fine"]],
        "reference_multistart_seconds": reference["runtime_seconds"],
        "ratio_cvodes_over_closed_form": data["cvodes_seconds"] / data["closed_form_seconds"],
        "ratio_collocation_over_closed_form": (data["collocation_seconds"]
                                               / data["closed_form_seconds"]),
    })
    for name in ("closed_form", "cvodes", "collocation"):
        data[f"{name}_tof_error_vs_reference"] = (data[f"{name}_tof_days"]
                                                  / reference["tof_days"] - 1)
    data["how"] = HOW
    _print(data)
    path = Path(out) / "lowthrust.json"
    write_json(path, data)
    return path
