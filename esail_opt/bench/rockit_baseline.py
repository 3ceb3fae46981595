"""``esail-opt-bench rockit``: the main job against a generic RK4 multiple-shooting script
of the same transfer, both as whole processes.

The main job is ``esail-opt solve problems/earth_mars_min_time.py --polish``.  The baseline
(:func:`build`) is what a user of a general optimal-control toolkit writes, the toolkit used
as rockit's own examples use it: ``Ocp`` with a free final time, the polar states under
Eqs. 1-2, one pitch per each of N = 60 equal intervals boxed to the sail's bounds, the
target's end conditions, ``MultipleShooting(N=60, M=4, intg='rk')`` and Ipopt with ``expand``.

Its guess is a spiral at the problem's seed pitch (:func:`_spiral_guess`).  With the pitch
boxed, multiple shooting finds the optimum's jump through alpha_n = -90 = +90 deg from some
guesses only, so the guess's time of flight decides which optimum Ipopt reaches:
:data:`GUESS_TOF_DAYS` reaches the main job's, and the comparison is void unless the two
times of flight agree within :data:`TOF_AGREEMENT`.

:func:`main` is the baseline's process: ``main([PROBLEM])`` solves and prints one JSON line
(:func:`solve`'s record, its import and solve times); ``main(["--figures", DIR])`` draws
the two figures of ``DIR/solution.json`` and prints how long that took.  rockit is the
``bench`` extra.
"""

import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: The transfer both sides solve (a shipped problem file).
PROBLEM = "earth_mars_min_time"
#: rockit's transcription: intervals, RK4 steps per interval.
INTERVALS = 60
STEPS = 4
#: Time of flight of the spiral guess, days.
GUESS_TOF_DAYS = 400.0
#: Relative agreement of the two times of flight below which the comparison counts.
TOF_AGREEMENT = 0.005
#: Fewest pairs of processes a run times.
MIN_PAIRS = 5


def rockit_missing():
    """None if rockit imports, else the one line that says how to get it."""
    import importlib.util

    if importlib.util.find_spec("rockit") is None:
        return ("rockit is not installed; this bench needs it: pip install rockit-meco "
                "(or the package's 'bench' extra)")
    return None


def _spiral_guess(ocp, states, alpha, problem, tf):
    """Set the spiral guess on rockit's grid of N + 1 points: r linear in time from the
    departure to the target radius over ``tf``, circular speed, the angle at the local
    circular rate, v_r constant, and the problem's seed pitch (+-45 deg by default)."""
    import numpy as np

    x0 = problem.x0()[:4]
    tau = np.linspace(0.0, 1.0, INTERVALS + 1)
    r = x0[0] + (problem.aim_radius_au() - x0[0]) * tau
    theta = x0[1] + np.r_[0.0, np.cumsum(np.diff(tau) * tf * r[:-1] ** -1.5)]
    vr = np.full_like(tau, (r[-1] - r[0]) / tf)
    for state, values in zip(states, (r, theta, vr, r ** -0.5)):
        ocp.set_initial(state, values)
    seed = problem.guess_alpha_deg
    if seed is None:
        seed = 45.0 if r[-1] >= r[0] else -45.0
    ocp.set_initial(alpha, math.radians(seed))


def build(problem):
    """rockit's OCP of ``problem``; returns (ocp, states, alpha): the four states r, theta,
    v_r, v_theta and the pitch.  ValueError unless the departure is fixed, the sail
    unthrottled, the target has end conditions and the objective is minimum time."""
    import casadi as ca
    from rockit import FreeTime, MultipleShooting, Ocp

    from esail_opt.physics import constants as units
    from esail_opt.physics.dynamics import rhs
    from esail_opt.physics.thrust import radial_transverse

    if (problem.dated() or problem.throttled() or problem.target is None
            or problem.fixed_tof() is not None or problem.tracks_body()):
        raise ValueError(f"{problem.name}: the rockit baseline transcribes a minimum-time "
                         "transfer from a fixed state to a fixed orbit only")
    tf = units.time_from_days(GUESS_TOF_DAYS)
    ocp = Ocp(T=FreeTime(tf))
    states = [ocp.state() for _ in range(4)]
    x, alpha = ca.vertcat(*states), ocp.control()
    R, T = radial_transverse(alpha, problem.sail.coefficients)
    for state, rate in zip(states, ca.vertsplit(rhs(x, problem.sail.ac, R, T))):
        ocp.set_der(state, rate)
    ocp.subject_to(ocp.at_t0(x) == problem.x0()[:4])
    for condition in problem.target.constraints(ocp.at_tf(x), ocp.T, 0.0):
        ocp.subject_to(condition == 0)
    lo, hi = problem.alpha_bounds()
    ocp.subject_to(lo <= (alpha <= hi))
    ocp.subject_to(ocp.T >= 0)
    ocp.add_objective(ocp.T)
    _spiral_guess(ocp, states, alpha, problem, tf)
    ocp.solver("ipopt", {"expand": True, "print_time": False,
                         "ipopt.print_level": 0, "ipopt.sb": "yes"})
    ocp.method(MultipleShooting(N=INTERVALS, M=STEPS, intg="rk"))
    return ocp, states, alpha


def solve(problem):
    """Solve :func:`build`'s OCP; returns a JSON-ready record: ``status``, ``iterations``,
    ``tof_days``, ``alpha_rad`` (the N pitches) and ``duration_tu`` (every interval's
    length, TU).  A failed solve is returned with its status, not raised."""
    import numpy as np

    from esail_opt.physics import constants as units

    ocp, _, alpha = build(problem)
    try:
        sol = ocp.solve()
    except RuntimeError:
        sol = ocp.non_converged_solution
    stats = sol.stats
    tf = float(sol.value(ocp.T))
    _, pitch = sol.sample(alpha, grid="control")
    return {"status": stats["return_status"], "iterations": int(stats["iter_count"]),
            "tof_days": units.time_to_days(tf),
            "alpha_rad": [float(a) for a in np.ravel(pitch)[:INTERVALS]],
            "duration_tu": tf / INTERVALS}


def fly(problem, record):
    """Fly ``record``'s schedule (:func:`solve`) on Eqs. 1-2 with CVODES at the verifier's
    tolerance; returns the target miss (``target_miss_r_km``, ``target_miss_v_m_s``)."""
    import numpy as np

    from esail_opt.optimisation.verify import target_miss
    from esail_opt.propagation.simulate import VERIFY_TOLERANCE, simulate

    alphas = np.asarray(record["alpha_rad"], float)
    lengths = np.full(alphas.size, record["duration_tu"])
    flown = simulate(problem.x0()[:4], alphas, lengths, problem.sail.ac,
                     coefficients=problem.sail.coefficients, tol=VERIFY_TOLERANCE)
    return target_miss(problem.target, flown[:4, -1], flown[4, -1])


def _figures_seconds(folder):
    """Draw the figures of ``folder``'s solution.json in this process; returns (seconds
    from the first import of the drawing code, matplotlib's included, to the files
    written; seconds of the drawing and writing alone)."""
    start = time.perf_counter()
    import matplotlib.pyplot  # noqa: F401  (what the first figure of a process imports)

    from esail_opt.app import plots
    from esail_opt.app.solution import Solution

    solution = Solution.load(Path(folder) / "solution.json")
    drawing = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="esail_bench_rockit_fig_") as out:
        plots.write_plots(solution, out)
    end = time.perf_counter()
    return end - start, end - drawing


def _timed(command):
    """Run ``command`` as a whole process; returns (wall s, CPU s, exit status, stdout).
    Both sides get one OpenBLAS thread unless the environment says otherwise (``esail-opt``'s
    own default): a second thread spinning in the baseline's MUMPS would only add CPU time."""
    import os
    import resource

    env = dict(os.environ)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          env=env)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, done.returncode, done.stdout


def _own_process(*args):
    """A fresh interpreter running :func:`main` with ``args`` (``-m`` would import this
    module twice: once as a member of the benches' package, which lists it)."""
    return [sys.executable, "-c", "import sys; from esail_opt.bench.rockit_baseline "
            "import main; sys.exit(main(sys.argv[1:]))", *args]


def _commands(problem_file, out):
    """The two processes: the main job as a user runs it, and the baseline's script."""
    script = Path(sys.executable).with_name("esail-opt")
    main_job = ([str(script)] if script.exists() else
                [sys.executable, "-c", "from esail_opt.app.cli import console; console()"])
    return {"esail_opt": main_job + ["solve", str(problem_file), "--polish", "--out", out],
            "rockit": _own_process(PROBLEM)}


def measure(pairs, problem_file, out):
    """Time ``pairs`` pairs of the two processes, alternating which goes first, each pair
    followed by the main job's figures in a process of their own, after one untimed run of
    each so that no timed run fills a cache (compiled arcs on disk, file pages) for the
    others; returns the per-pair lists and the last runs' outputs."""
    runs = {"esail_opt": [], "rockit": [], "figures": []}
    outputs = {}
    print("bench rockit: one untimed run of each ...", flush=True)
    for command in _commands(problem_file, out).values():
        _timed(command)
    for k in range(pairs):
        commands = _commands(problem_file, out)
        order = ("esail_opt", "rockit") if k % 2 == 0 else ("rockit", "esail_opt")
        print(f"bench rockit: pair {k + 1}/{pairs} ...", flush=True)
        for side in order:
            wall, cpu, status, stdout = _timed(commands[side])
            runs[side].append({"wall_s": wall, "cpu_s": cpu, "exit_status": status})
            if side == "rockit" and status == 0:
                own = json.loads(stdout)
                runs[side][-1].update(import_s=own["import_seconds"],
                                      solve_s=own["solve_seconds"])
            outputs[side] = stdout
        _, _, status, stdout = _timed(_own_process("--figures", out))
        runs["figures"].append(json.loads(stdout) if status == 0 else None)
    return runs, outputs


def _median(runs, key):
    return statistics.median(run[key] for run in runs)


def _sides(problem, runs, outputs, out):
    """Each side's objective and flown miss, from its last run; None where it failed."""
    esail, rockit = None, None
    if all(run["exit_status"] == 0 for run in runs["esail_opt"]):
        polished = json.loads((Path(out) / "solution.json").read_text())["polish"]
        check = polished["verification"]
        esail = {"tof_days": polished["tof_days"],
                 "target_miss_r_km": check["target_miss_r_km"],
                 "target_miss_v_m_s": check["target_miss_v_m_s"]}
    if all(run["exit_status"] == 0 for run in runs["rockit"]):
        record = json.loads(outputs["rockit"])
        rockit = {key: record[key] for key in ("tof_days", "status", "iterations")}
        rockit.update(fly(problem, record))
    return esail, rockit


def summarise(problem, runs, outputs, out):
    """The bench's record from :func:`measure`'s runs (see :func:`run`)."""
    esail, rockit = _sides(problem, runs, outputs, out)
    agree = None
    if esail and rockit:
        agree = abs(rockit["tof_days"] / esail["tof_days"] - 1.0)
    void = agree is None or agree > TOF_AGREEMENT
    paired = [r["wall_s"] / e["wall_s"] for e, r in zip(runs["esail_opt"], runs["rockit"])]
    paired_cpu = [r["cpu_s"] / e["cpu_s"] for e, r in zip(runs["esail_opt"], runs["rockit"])]
    figures = [f for f in runs["figures"] if f is not None] or None
    return {
        "problem": problem.name, "pairs": len(paired),
        "esail_opt_median_wall_s": _median(runs["esail_opt"], "wall_s"),
        "rockit_median_wall_s": _median(runs["rockit"], "wall_s"),
        "ratio_rockit_over_esail_opt": None if void else statistics.median(paired),
        "ratio_cpu_rockit_over_esail_opt": None if void else statistics.median(paired_cpu),
        "esail_opt_median_cpu_s": _median(runs["esail_opt"], "cpu_s"),
        "rockit_median_cpu_s": _median(runs["rockit"], "cpu_s"),
        "rockit_median_import_s": None if rockit is None else _median(runs["rockit"],
                                                                       "import_s"),
        "rockit_median_solve_s": None if rockit is None else _median(runs["rockit"],
                                                                      "solve_s"),
        "paired_ratios": paired,
        "tof_relative_difference": agree, "tof_agreement_bound": TOF_AGREEMENT,
        "comparison_void": void,
        "esail_opt": esail, "rockit": rockit,
        "figures_median_s": figures and statistics.median(f["figures_seconds"] for f in figures),
        "figures_drawing_median_s": figures and statistics.median(f["drawing_seconds"]
                                                                  for f in figures),
        "runs": runs,
    }


def _print(data):
    from esail_opt.bench.timing import print_table

    esail, rockit = data["esail_opt"] or {}, data["rockit"] or {}
    ratio = data["ratio_rockit_over_esail_opt"]
    print_table(f"bench rockit: {data['problem']}, medians of {data['pairs']} pairs", [
        ("esail-opt solve --polish", data["esail_opt_median_wall_s"],
         f"s wall, tof {esail.get('tof_days', float('nan')):.3f} d"),
        (f"rockit, N = {INTERVALS}, M = {STEPS}, RK4", data["rockit_median_wall_s"],
         f"s wall, tof {rockit.get('tof_days', float('nan')):.3f} d, flown miss "
         f"{rockit.get('target_miss_r_km', float('nan')):.3g} km"),
        ("  of which rockit's import, its build and solve",
         f"{data['rockit_median_import_s'] or math.nan:.3g} s,",
         f"{data['rockit_median_solve_s'] or math.nan:.3g} s"),
        ("ratio (paired, rockit / esail-opt)", "void" if ratio is None else ratio, ""),
        ("CPU ratio (paired)", "void" if ratio is None
         else data["ratio_cpu_rockit_over_esail_opt"], ""),
        ("figures in a fresh process, with imports", data["figures_median_s"] or "n/a", "s"),
        ("  of which drawing and writing", data["figures_drawing_median_s"] or "n/a", "s"),
        ("load average (1 min) before, after", data["load_average"], ""),
    ])
    if data["comparison_void"]:
        print(f"bench rockit: comparison void: a side failed, or the times of flight differ "
              f"by more than {TOF_AGREEMENT:.1%}")


def run(out, repeats):
    """Time the two whole processes side by side (:func:`measure`, ``max(repeats,
    MIN_PAIRS)`` pairs, wall and CPU time with children); writes ``rockit.json``, returns its
    path.  The ratio is the median over pairs of rockit's wall time over the main job's;
    None (the comparison void) unless every run of both exited 0 and the times of flight
    agree within :data:`TOF_AGREEMENT`.  rockit's miss is its schedule flown (:func:`fly`),
    the main job's its polished verification's.  Raises InputError without rockit.
    """
    import importlib.resources
    import os

    from esail_opt.app.outputs import write_json
    from esail_opt.errors import InputError
    from esail_opt.optimisation.problem_file import SHIPPED_PACKAGE, shipped_problem

    missing = rockit_missing()
    if missing:
        raise InputError(missing)
    problem = shipped_problem(PROBLEM)
    load = [os.getloadavg()[0]]
    with importlib.resources.as_file(importlib.resources.files(SHIPPED_PACKAGE)
                                     / f"{PROBLEM}.py") as problem_file, \
            tempfile.TemporaryDirectory(prefix="esail_bench_rockit_") as tmp:
        runs, outputs = measure(max(repeats, MIN_PAIRS), problem_file, tmp)
        data = summarise(problem, runs, outputs, tmp)
    data["load_average"] = load + [os.getloadavg()[0]]
    data["how"] = ("whole processes, alternating; `esail-opt solve PROBLEM.py --polish "
                   "--out TMP` against `rockit_baseline.main()` in a fresh interpreter; "
                   "ratio = median over pairs of rockit's wall time / esail-opt's; figures: "
                   "the two figures drawn from solution.json in a fresh process, matplotlib's "
                   "import included")
    _print(data)
    path = Path(out) / "rockit.json"
    write_json(path, data)
    return path


def main(argv=None):
    """The baseline's process (see the module docstring); returns the exit status."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--figures"]:
        total, drawing = _figures_seconds(argv[1])
        print(json.dumps({"figures_seconds": total, "drawing_seconds": drawing}))
        return 0
    start = time.perf_counter()
    missing = rockit_missing()
    if missing:
        print(f"esail_opt.bench.rockit_baseline: {missing}", file=sys.stderr)
        return 2
    import rockit  # noqa: F401  (timed apart: it is most of the script's start-up)

    from esail_opt.optimisation.problem_file import shipped_problem

    imported = time.perf_counter()
    record = solve(shipped_problem(argv[0] if argv else PROBLEM))
    record.update(import_seconds=imported - start,
                  solve_seconds=time.perf_counter() - imported)
    print(json.dumps(record))
    return 0 if record["status"] == "Solve_Succeeded" else 1


if __name__ == "__main__":
    sys.exit(main())
