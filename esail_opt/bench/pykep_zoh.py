"""``esail-opt-bench pykep``: the main job in three dimensions against a pykep 3
zero-order-hold script of the same fixed-date transfer, whole processes side by side.

The main job is ``esail-opt solve problems/earth_mars_min_ac.py --polish``, timed with
``--no-plots`` and with its figures.  The baseline is what a pykep 3 user writes for that
transfer: pykep's zero-order-hold leg (``pykep.leg.zoh``: segments flown forward and backward
by heyoka, one mismatch where they meet, its gradient from heyoka's variational equations),
a pygmo problem around it and pygmo's Ipopt.  Both sides aim at the same DE421 states
(``bodies.lookup.ecliptic_state_at``) and fly the same E-sail thrust (:func:`dynamics`, not
pykep's free thrust vector): 40 segments of pitch, clock and throttle boxed as the problem
boxes them, one a_c the objective.

Decisions, each one a pykep user would make:

* segments of equal duration, the leg's time grid (the main job's segments sweep equal
  angles; the grids alone make the optima differ, by 7e-5 of a_c here);
* a_c a fourth control held equal on every segment, its derivative the sum of the leg's
  own control gradients;
* the leg cut in the middle (:data:`CUT`): at pykep's examples' 0.6 the solve took over ten
  times as long or ran out of iterations;
* mismatch rows in metres and metres per TU, so that :data:`IPOPT`'s ``constr_viol_tol`` of
  1 cm holds the flown miss to centimetres;
* Ipopt's limited-memory Hessian (pygmo's problem has none) with a memory longer than the
  121 variables: the default 6 pairs took a minute, 150 or more under 4 s;
* a constant-attitude guess (:data:`GUESS_PITCH_DEG`, clock 0, full throttle, the seed a_c):
  the solve's time depends on that pitch, the optimum does not.

pykep 3.0.1 cannot be imported (its wheel lacks data files its ``__init__`` reads, and its
core bundles a libheyoka that conflicts with heyoka.py's), so :func:`zoh_class` loads only
the pure-Python leg, by path.  :func:`main` is the baseline's process; pykep, heyoka and
pygmo are the ``bench`` extra.
"""

import importlib.util
import json
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

#: The transfer both sides solve (a shipped problem file).
PROBLEM = "earth_mars_min_ac"
#: Where the leg's forward and backward halves meet, as a fraction of its segments.
CUT = 0.5
#: Pitch of the constant-attitude guess, deg, in the baseline's fastest band (15 to 30 deg)
#: so that it is timed at its best: at 45, the main job's seed, it took over 20 times as long.
GUESS_PITCH_DEG = 20.0
#: pygmo's Ipopt options (module docstring); the mismatch rows are in metres.
IPOPT = {"tol": 1e-8, "constr_viol_tol": 0.01, "max_iter": 3000,
         "hessian_approximation": "limited-memory", "limited_memory_max_history": 200,
         "print_level": 0, "sb": "yes"}
#: The packages the baseline needs (pykep for its leg's file only).
PACKAGES = ("pykep", "heyoka", "pygmo")
#: The answers the bench compares: a_c within this relative difference counts.
AC_AGREEMENT = 1e-3
#: The issue's targets: the baseline's time over the main job's, without and with figures.
TARGETS = {"ratio_without_figures": 1.5, "ratio_with_figures": 1.0}
#: Ipopt's return codes as pygmo gives them (``ipopt.get_last_opt_result``).
_IPOPT_STATUS = {0: "Solve_Succeeded", 1: "Solved_To_Acceptable_Level",
                 2: "Infeasible_Problem_Detected", 3: "Search_Direction_Becomes_Too_Small",
                 4: "Diverging_Iterates", 5: "User_Requested_Stop", 6: "Feasible_Point_Found",
                 -1: "Maximum_Iterations_Exceeded", -2: "Restoration_Failed",
                 -3: "Error_In_Step_Computation", -4: "Maximum_CpuTime_Exceeded"}


def _zoh_path():
    """Path of the installed ``pykep/leg/_zoh.py``, found without importing pykep (or None)."""
    spec = importlib.util.find_spec("pykep")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0]) / "leg" / "_zoh.py"


def missing():
    """None if the baseline can run, else the one line that says what is missing and how
    to get it.  Nothing is imported: pykep's own import fails."""
    absent = [name for name in PACKAGES if importlib.util.find_spec(name) is None]
    if absent:
        return (f"{', '.join(absent)} not installed; the pykep baseline needs pykep 3, "
                "heyoka and pygmo: pip install 'esail_opt[bench]'")
    path = _zoh_path()
    if path is None or not path.is_file():
        return f"pykep has no zero-order-hold leg at {path}; the baseline needs pykep 3"
    return None


def versions():
    """The installed versions of :data:`PACKAGES` (None for one that is missing)."""
    from importlib import metadata

    found = {}
    for name in PACKAGES:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = None
    return found


def zoh_class():
    """pykep's ``leg.zoh`` class, ``pykep/leg/_zoh.py`` loaded by path once a process."""
    name = "esail_opt_bench_pykep_leg_zoh"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, _zoh_path())
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        sys.modules[name] = module
    return sys.modules[name].zoh


def dynamics(coefficients):
    """The E-sail in three dimensions as heyoka's ODE system, canonical units (mu = 1,
    r_E = 1 au): state [x, y, z, vx, vy, vz]; runtime parameters ``par[0..3]`` = pitch
    alpha, clock delta (rad), throttle kappa and a_c.  The thrust a_c kappa / r (R r_hat +
    T t_hat + N h_hat) is ``physics.dynamics.rhs_cartesian`` under
    ``physics.thrust.radial_transverse_normal``, written again as a pykep user writes it
    (the tests check they agree).  Returns (list of (variable, derivative), the variables).
    """
    import heyoka as hy

    b1, b2 = coefficients
    x, y, z, vx, vy, vz = hy.make_vars("x", "y", "z", "vx", "vy", "vz")
    alpha, delta, kappa, ac = (hy.par[k] for k in range(4))
    r2 = hy.sum([x**2, y**2, z**2])
    r = hy.sqrt(r2)
    rv = hy.sum([x * vx, y * vy, z * vz])
    hx, hy_, hz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    h = hy.sqrt(hy.sum([hx**2, hy_**2, hz**2]))
    push = ac * kappa / r
    along_r = push * (b1 + b2 * hy.cos(2.0 * alpha)) / r
    across = b2 * hy.sin(2.0 * alpha)
    along_t = push * across * hy.cos(delta) / (h * r)
    along_h = push * across * hy.sin(delta) / h
    gravity = -1.0 / (r2 * r)
    rates = [(gravity + along_r) * p + along_t * (v * r2 - p * rv) + along_h * n
             for p, v, n in ((x, vx, hx), (y, vy, hy_), (z, vz, hz))]
    variables = [x, y, z, vx, vy, vz]
    return list(zip(variables, [vx, vy, vz, *rates])), variables


def integrators(coefficients):
    """heyoka's integrator of :func:`dynamics` and its first-order variational one (with
    respect to the state and the four parameters), as pykep's leg takes them; compact
    mode, as pykep builds its own."""
    import heyoka as hy

    system, variables = dynamics(coefficients)
    pars = [0.0, 0.0, 1.0, 0.0]
    ta = hy.taylor_adaptive(system, [1.0, 0.0, 0.0, 0.0, 1.0, 0.0], pars=pars,
                            compact_mode=True)
    var = hy.var_ode_sys(system, variables + [hy.par[k] for k in range(4)], 1)
    return ta, hy.taylor_adaptive(var, pars=pars, compact_mode=True)


def transfer(problem):
    """The fixed-date transfer of ``problem``: a dict of the departure and arrival states
    (Cartesian, canonical), time of flight (TU), segments, bounds and thrust coefficients.
    ValueError, naming the problem, unless it is a 3-D minimum-a_c rendezvous from a body
    on a fixed date with no excess speed, in a fixed count of segments."""
    import numpy as np

    from esail_opt.bodies import lookup
    from esail_opt.optimisation.goals import BodyRendezvous, MinAcceleration

    departure = problem.departure
    if not (problem.three_d() and isinstance(problem.objective, MinAcceleration)
            and isinstance(problem.target, BodyRendezvous) and not problem.free_date()
            and getattr(departure, "vinf_km_s", None) == 0.0
            and problem.segments.count is not None):
        raise ValueError(f"{problem.name}: the pykep baseline transcribes a minimum-a_c "
                         "rendezvous in three dimensions from a body on a fixed date, "
                         "with no excess speed, in a fixed number of segments only")
    t0, tof = problem.epoch(), problem.fixed_tof()
    throttle = problem.throttle_bounds() or (1.0, 1.0)
    return {
        "start": np.asarray(lookup.ecliptic_state_at(departure.body, t0, "departure.body"),
                            float),
        "end": np.asarray(lookup.ecliptic_state_at(problem.target.body, t0 + tof,
                                                   "target.body"), float),
        "tof": tof, "segments": int(problem.segments.count),
        "alpha": problem.alpha_bounds(), "clock": problem.clock_bounds(),
        "throttle": throttle, "coefficients": tuple(problem.sail.coefficients),
        "seed_ac": problem.sail.ac,
    }


class Transfer:
    """pygmo's problem of the transfer (:func:`transfer`) on pykep's zoh leg: decision vector
    [a_c] + [alpha_k, delta_k, kappa_k for each segment k]; fitness [a_c] + the leg's six
    mismatch components in metres; gradient the leg's control columns (``compute_mc_grad``),
    a_c's summed over the segments."""

    def __init__(self, case, tas, zoh):
        import numpy as np

        self.case, self.n = case, case["segments"]
        self.tgrid = np.linspace(0.0, case["tof"], self.n + 1)
        self.leg = zoh(case["start"].tolist(), [0.0] * (4 * self.n), case["end"].tolist(),
                       self.tgrid.tolist(), CUT, tas, dim_dynamics=6, dim_controls=4)

    def get_bounds(self):
        (a_lo, a_hi), (c_lo, c_hi), (k_lo, k_hi) = (self.case[key] for key in
                                                    ("alpha", "clock", "throttle"))
        return ([0.0] + [a_lo, c_lo, k_lo] * self.n,
                [10.0 * self.case["seed_ac"]] + [a_hi, c_hi, k_hi] * self.n)

    def get_nec(self):
        return 6

    def guess(self):
        """The constant-attitude guess: :data:`GUESS_PITCH_DEG`, clock 0, full throttle."""
        full = self.case["throttle"][1]
        return [self.case["seed_ac"]] + [math.radians(GUESS_PITCH_DEG), 0.0, full] * self.n

    def _set(self, x):
        import numpy as np

        controls = np.empty((self.n, 4))
        controls[:, :3] = np.reshape(x[1:], (self.n, 3))
        controls[:, 3] = x[0]
        self.leg.controls = controls.ravel().tolist()

    def fitness(self, x):
        from esail_opt.physics import constants as units

        self._set(x)
        return [x[0]] + [d * units.AU for d in self.leg.compute_mismatch_constraints()]

    def has_gradient(self):
        return True

    def gradient(self, x):
        import numpy as np

        from esail_opt.physics import constants as units

        self._set(x)
        _, _, controls, _ = self.leg.compute_mc_grad()
        controls = np.asarray(controls).reshape(6, self.n, 4) * units.AU
        grad = np.zeros((7, 1 + 3 * self.n))
        grad[0, 0] = 1.0
        grad[1:, 0] = controls[:, :, 3].sum(axis=1)
        grad[1:, 1:] = controls[:, :, :3].reshape(6, 3 * self.n)
        return grad.ravel()

    def fly(self, x):
        """The schedule ``x`` flown forward from the departure over every segment by the
        leg's integrator; returns the arrival state (Cartesian, canonical)."""
        ta = self.leg.ta
        ta.time, ta.state[:] = 0.0, self.case["start"]
        for k in range(self.n):
            ta.pars[:4] = [x[1 + 3 * k], x[2 + 3 * k], x[3 + 3 * k], x[0]]
            ta.propagate_until(self.tgrid[k + 1])
        return ta.state.copy()


def solve(problem):
    """Solve ``problem``'s transfer with pygmo's Ipopt on pykep's leg; returns a JSON-ready
    record: ``status`` (Ipopt's), ``converged`` (Solve_Succeeded and the mismatch within
    ``constr_viol_tol``), ``fevals`` and ``gevals`` (pygmo's counts), ``ac``, ``ac_mm_s2``,
    ``mismatch_m`` (the largest row), ``miss_m`` and ``miss_m_s`` (:meth:`Transfer.fly`
    against the arrival state), ``alpha_rad``, ``clock_rad``, ``throttle``, ``duration_tu``,
    ``build_seconds`` (integrators and leg) and ``solve_seconds``.  A failed solve is
    returned with its status, not raised.
    """
    import numpy as np
    import pygmo as pg

    from esail_opt.physics import constants as units

    case = transfer(problem)
    start = time.perf_counter()
    udp = Transfer(case, integrators(case["coefficients"]), zoh_class())
    built = time.perf_counter()
    ipopt = pg.ipopt()
    for key, value in IPOPT.items():
        setter = {str: ipopt.set_string_option, int: ipopt.set_integer_option,
                  float: ipopt.set_numeric_option}[type(value)]
        setter(key, value)
    population = pg.population(pg.problem(udp))
    population.push_back(udp.guess())
    population = pg.algorithm(ipopt).evolve(population)
    solved = time.perf_counter()
    x = np.asarray(population.champion_x, float)
    rows = np.abs(np.asarray(population.champion_f[1:], float))
    code = ipopt.get_last_opt_result()
    status = _IPOPT_STATUS.get(code, f"Ipopt return code {code}")
    miss = udp.fly(x) - case["end"]
    return {
        "status": status,
        "converged": bool(status == "Solve_Succeeded"
                          and rows.max() <= IPOPT["constr_viol_tol"]),
        "fevals": int(population.problem.get_fevals()),
        "gevals": int(population.problem.get_gevals()),
        "ac": float(x[0]), "ac_mm_s2": float(x[0] * units.ACC_UNIT_MM_S2),
        "mismatch_m": float(rows.max()),
        "miss_m": float(np.linalg.norm(miss[:3]) * units.AU),
        "miss_m_s": float(units.speed_to_m_s(np.linalg.norm(miss[3:]))),
        "alpha_rad": x[1::3].tolist(), "clock_rad": x[2::3].tolist(),
        "throttle": x[3::3].tolist(), "duration_tu": case["tof"] / case["segments"],
        "build_seconds": built - start, "solve_seconds": solved - built,
    }


def fly(problem, record):
    """Fly ``record``'s schedule (:func:`solve`) from the departure on the package's 3-D
    verifier (CVODES, turning-plane equations, the verifier's tolerance), judging it as the
    main job's is; returns its target miss, ``cvodes_miss_m`` and ``cvodes_miss_m_s``."""
    import numpy as np

    from esail_opt.propagation.simulate import VERIFY_TOLERANCE, simulate3d

    case = transfer(problem)
    n = len(record["alpha_rad"])
    flown = simulate3d(case["start"], record["alpha_rad"], record["clock_rad"],
                       np.full(n, record["duration_tu"]), record["ac"],
                       throttles=record["throttle"], coefficients=case["coefficients"],
                       tol=VERIFY_TOLERANCE)
    miss = problem.target.miss3d(flown[:6, -1], flown[6, -1], problem.epoch())
    return {"cvodes_miss_m": miss["target_miss_r_km"] * 1e3,
            "cvodes_miss_m_s": miss["target_miss_v_m_s"]}


# ------------------------------------------------------------------------- the bench

def _own_process(*args):
    """A fresh interpreter running :func:`main` (``-m`` would import this module twice:
    once as a member of the benches' package, which lists it)."""
    return [sys.executable, "-c", "import sys; from esail_opt.bench.pykep_zoh "
            "import main; sys.exit(main(sys.argv[1:]))", *args]


def _commands(problem_file, out):
    """The three processes of a round: the main job without and with figures, the baseline."""
    script = Path(sys.executable).with_name("esail-opt")
    main_job = ([str(script)] if script.exists() else
                [sys.executable, "-c", "from esail_opt.app.cli import console; console()"])
    solve = main_job + ["solve", str(problem_file), "--polish", "--out"]
    return {"esail_opt": solve + [str(Path(out) / "no_plots"), "--no-plots"],
            "esail_opt_figures": solve + [str(Path(out) / "figures")],
            "pykep": _own_process(PROBLEM)}


def _last_line(stdout):
    """The baseline's JSON record: the last line of its output (Ipopt may print before)."""
    return json.loads(stdout.strip().splitlines()[-1])


def measure(rounds, problem_file, out):
    """Time ``rounds`` rounds of the three processes, the order turned by one each round,
    after one untimed run of each so that no timed run fills a cache (compiled arcs, heyoka's
    integrators, file pages) for the others; returns the per-round lists and last outputs."""
    from esail_opt.bench.rockit_baseline import _timed

    sides = ("esail_opt", "esail_opt_figures", "pykep")
    runs = {side: [] for side in sides}
    outputs = {}
    print("bench pykep: one untimed run of each ...", flush=True)
    for command in _commands(problem_file, out).values():
        _timed(command)
    for k in range(rounds):
        commands = _commands(problem_file, out)
        order = sides[k % 3:] + sides[:k % 3]
        print(f"bench pykep: round {k + 1}/{rounds} ...", flush=True)
        for side in order:
            wall, cpu, status, stdout = _timed(commands[side])
            runs[side].append({"wall_s": wall, "cpu_s": cpu, "exit_status": status})
            if side == "pykep" and stdout.strip():
                own = _last_line(stdout)
                runs[side][-1].update({key: own[key] for key in
                                       ("import_seconds", "build_seconds", "solve_seconds")})
            outputs[side] = stdout
    return runs, outputs


def _ours(folder):
    """The main job's answer from its polished ``solution.json`` in ``folder``."""
    polished = json.loads((Path(folder) / "solution.json").read_text())["polish"]
    check = polished["verification"]
    return {"ac_mm_s2": polished["ac_mm_s2_required"], "converged": polished["converged"],
            "miss_m": check["target_miss_r_km"] * 1e3,
            "miss_m_s": check["target_miss_v_m_s"]}


def _median(runs, key):
    return statistics.median(run[key] for run in runs)


def summarise(problem, runs, outputs, out):
    """The bench's record from :func:`measure`'s runs (see :func:`run`)."""
    ours = pykep = None
    if all(run["exit_status"] == 0 for run in runs["esail_opt"]):
        ours = _ours(Path(out) / "no_plots")
    if all(run["exit_status"] == 0 for run in runs["pykep"]):
        record = _last_line(outputs["pykep"])
        pykep = {key: record[key] for key in ("ac_mm_s2", "miss_m", "miss_m_s", "status",
                                              "converged", "fevals", "gevals",
                                              "mismatch_m")}
        pykep.update(fly(problem, record))
    agree = None if not (ours and pykep) else abs(pykep["ac_mm_s2"] / ours["ac_mm_s2"] - 1)
    void = agree is None or agree > AC_AGREEMENT
    data = {"problem": problem.name, "rounds": len(runs["pykep"]), "versions": versions(),
            "ipopt_options": IPOPT, "cut": CUT}
    for side in runs:
        data[f"{side}_median_wall_s"] = _median(runs[side], "wall_s")
        data[f"{side}_median_cpu_s"] = _median(runs[side], "cpu_s")
    for key in ("import_seconds", "build_seconds", "solve_seconds"):
        data[f"pykep_median_{key[:-8]}_s"] = (_median(runs["pykep"], key) if pykep
                                              else None)
    for name, side in (("without_figures", "esail_opt"), ("with_figures", "esail_opt_figures")):
        paired = [p["wall_s"] / e["wall_s"] for e, p in zip(runs[side], runs["pykep"])]
        ratio = None if void else statistics.median(paired)
        data[f"paired_ratios_{name}"] = paired
        data[f"ratio_{name}"] = ratio
        data[f"target_{name}_met"] = None if ratio is None else ratio >= TARGETS[f"ratio_{name}"]
    data.update(targets=TARGETS, ac_relative_difference=agree, ac_agreement_bound=AC_AGREEMENT,
                comparison_void=void, esail_opt=ours, pykep=pykep, runs=runs)
    return data


def _print(data):
    from esail_opt.bench.timing import print_table

    if "skipped" in data:
        print(f"bench pykep: baseline skipped: {data['skipped']}")
        return
    ours, pykep = data["esail_opt"] or {}, data["pykep"] or {}
    nan = float("nan")

    def ratio(name):
        value = data[f"ratio_{name}"]
        return "void" if value is None else value

    print_table(f"bench pykep: {data['problem']}, medians of {data['rounds']} rounds", [
        ("esail-opt solve --polish --no-plots", data["esail_opt_median_wall_s"],
         f"s wall, a_c {ours.get('ac_mm_s2', nan):.6f} mm/s^2, miss "
         f"{ours.get('miss_m', nan):.3g} m"),
        ("esail-opt solve --polish (figures)", data["esail_opt_figures_median_wall_s"],
         "s wall"),
        (f"pykep zoh leg, pygmo Ipopt, cut {CUT}", data["pykep_median_wall_s"],
         f"s wall, a_c {pykep.get('ac_mm_s2', nan):.6f} mm/s^2, miss "
         f"{pykep.get('miss_m', nan):.3g} m (CVODES {pykep.get('cvodes_miss_m', nan):.3g} m)"),
        ("  of which imports, build, solve",
         f"{data['pykep_median_import_s'] or nan:.3g} s,",
         f"{data['pykep_median_build_s'] or nan:.3g} s, "
         f"{data['pykep_median_solve_s'] or nan:.3g} s"),
        ("ratio without figures (paired, pykep / esail-opt)", ratio("without_figures"),
         f"target {TARGETS['ratio_without_figures']}"),
        ("ratio with figures (paired)", ratio("with_figures"),
         f"target {TARGETS['ratio_with_figures']}"),
        ("load average (1 min) before, after", data["load_average"], ""),
    ])
    if data["comparison_void"]:
        print(f"bench pykep: comparison void: a side failed, or the a_c differ by more "
              f"than {AC_AGREEMENT:g}")


def run(out, repeats):
    """Time the three whole processes side by side (:func:`measure`, ``repeats`` rounds,
    wall and CPU time with children); writes ``pykep.json``, returns its path.

    Each ratio is the median over rounds of pykep's wall time over the main job's, without
    and with figures; None (the comparison void) unless every run of both exited 0 and the
    two a_c agree within :data:`AC_AGREEMENT`.  Both answers are kept: a_c in mm/s^2 and the
    miss in metres (pykep's also flown by CVODES, :func:`fly`).  Without the baseline's
    packages ``pykep.json`` holds ``{"skipped": reason}``.
    """
    import importlib.resources
    import os

    from esail_opt.app.outputs import write_json
    from esail_opt.optimisation.problem_file import SHIPPED_PACKAGE, shipped_problem

    path = Path(out) / "pykep.json"
    reason = missing()
    if reason:
        data = {"problem": PROBLEM, "skipped": reason, "versions": versions()}
        _print(data)
        write_json(path, data)
        return path
    problem = shipped_problem(PROBLEM)
    load = [os.getloadavg()[0]]
    with importlib.resources.as_file(importlib.resources.files(SHIPPED_PACKAGE)
                                     / f"{PROBLEM}.py") as problem_file, \
            tempfile.TemporaryDirectory(prefix="esail_bench_pykep_") as tmp:
        runs, outputs = measure(repeats, problem_file, tmp)
        data = summarise(problem, runs, outputs, tmp)
    data["load_average"] = load + [os.getloadavg()[0]]
    data["how"] = ("whole processes, the order turned each round; `esail-opt solve "
                   "PROBLEM.py --polish --out TMP --no-plots`, the same with its figures, "
                   "and `pykep_zoh.main()` in a fresh interpreter; ratio = median over "
                   "rounds of pykep's wall time / esail-opt's")
    _print(data)
    write_json(path, data)
    return path


def main(argv=None):
    """The baseline's process: solve ``argv[0]`` (default :data:`PROBLEM`), print one JSON
    line (:func:`solve`'s record with ``import_seconds``); exit status 0 converged,
    1 not, 2 the baseline's packages missing."""
    argv = sys.argv[1:] if argv is None else argv
    start = time.perf_counter()
    reason = missing()
    if reason:
        print(f"esail_opt.bench.pykep_zoh: {reason}", file=sys.stderr)
        return 2
    import heyoka  # noqa: F401  (timed apart: the script's start-up)
    import pygmo  # noqa: F401

    from esail_opt.optimisation.problem_file import shipped_problem

    zoh_class()
    problem = shipped_problem(argv[0] if argv else PROBLEM)
    imported = time.perf_counter()
    record = solve(problem)
    record["import_seconds"] = imported - start
    print(json.dumps(record))
    return 0 if record["converged"] else 1


if __name__ == "__main__":
    sys.exit(main())
