"""``esail-opt-bench precision``: solve time against verified accuracy, per method.

Methods are compared by the work each needs to reach a given accuracy, not at one setting
each: a method fast at a coarse setting may need a slow one to be as accurate.  The work is
the wall time of a whole ``solve_problem`` (seed, NLP construction, Ipopt); the precision is
``target_miss_r_km`` of the schedule flown on Eqs. 1-2 by CVODES (``optimisation.verify``).
The methods (:class:`Method`) are the closed form (also with the error control's
correction), RK4 segments and CVODES segments, each NLP with equal segment lengths and the
same Ipopt options.
"""

import dataclasses
import math
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from esail_opt.bench.timing import equal_lengths, print_table, runs_of
from esail_opt.optimisation.problem_file import shipped_problem

#: Target misses at which the curves are read, km, with their JSON keys.
MISSES_KM = {"1e6": 1e6, "1e5": 1e5, "1e4": 1e4}
#: The method every other one is compared with (the ratios' denominator).
BASELINE = "closed_form"
#: Methods with fixed keys in each ``at_miss_km`` entry (null when never reached).
REPORTED = ("closed_form", "rk4", "cvodes")


@dataclass(frozen=True)
class Method:
    """One method at one setting; points of the same ``name`` form one curve.  ``settings``
    is recorded with the point: ``segments`` (N, or None when set per revolution: the solved
    N is recorded then) and ``steps`` (closed-form sub-arcs, RK4 steps per segment, None for
    an adaptive integrator); other keys only label the progress line.  ``solve(problem) ->
    NLPResult`` is everything timed; it applies its own setting to the equal-length problem.
    """

    name: str
    settings: dict
    solve: Callable = field(repr=False)


@dataclass(frozen=True)
class Case:
    """A problem (solved with equal segment lengths whatever its own setting) and the
    :class:`Method` tuple run on it."""

    problem: object
    methods: tuple


def _with_count(problem, segments=None, per_revolution=None, sub_arcs=None):
    """``problem`` with N fixed (``segments``) or per revolution, and its sub-arcs."""
    seg = problem.segments
    if per_revolution is not None:
        seg = dataclasses.replace(seg, count=None, per_revolution=per_revolution)
    elif segments is not None:
        seg = dataclasses.replace(seg, count=segments, per_revolution=None)
    if sub_arcs is not None:
        seg = dataclasses.replace(seg, sub_arcs=sub_arcs)
    return dataclasses.replace(problem, segments=seg)


def closed_form(segments=None, sub_arcs=3, per_revolution=None):
    """The package's own closed-form NLP (default segment) at one setting."""

    def solve(problem):
        from esail_opt.optimisation.ipopt import solve_problem

        variant = _with_count(problem, segments, per_revolution, sub_arcs)
        return solve_problem(variant)[0]

    return Method("closed_form", {"segments": segments, "steps": sub_arcs,
                                  "per_revolution": per_revolution}, solve)


def corrected(segments=None, sub_arcs=3, per_revolution=None, rounds=1):
    """The closed-form NLP followed by ``rounds`` rounds of the error control's defect
    correction (``optimisation.error_control``), asked for 1 m so that it never stops early:
    the closed form as ``esail-opt solve`` uses it."""

    def solve(problem):
        from esail_opt.optimisation.problem import Tolerance
        from esail_opt.optimisation.error_control import control_error
        from esail_opt.optimisation.ipopt import solve_problem

        variant = dataclasses.replace(_with_count(problem, segments, per_revolution, sub_arcs),
                                      tolerance=Tolerance(position_km=1e-3))
        result, tr = solve_problem(variant)
        if not result.outcome.found:
            return result
        return control_error(variant, result, tr, max_rounds=rounds).result

    return Method("corrected", {"segments": segments, "steps": sub_arcs,
                                "per_revolution": per_revolution, "rounds": rounds}, solve)


def rk4(segments=None, steps=1, per_revolution=None):
    """The same NLP with RK4 segments of ``steps`` steps each."""

    def solve(problem):
        from esail_opt.optimisation.ipopt import solve_problem
        from esail_opt.optimisation.segment_methods import RK4

        variant = _with_count(problem, segments, per_revolution)
        return solve_problem(variant, RK4(steps))[0]

    return Method("rk4", {"segments": segments, "steps": steps,
                          "per_revolution": per_revolution}, solve)


def cvodes(segments=None, per_revolution=None):
    """The same NLP with each segment one CVODES integration (1e-12) of Eqs. 1-2 in theta.
    Its q3 rows are constants, so one row per segment keeps the NLP smallest; the
    sub-arcs kept only shape the seed (the same as RK4's)."""

    def solve(problem):
        from esail_opt.optimisation.ipopt import solve_problem
        from esail_opt.optimisation.segment_methods import CVODES

        variant = _with_count(problem, segments, per_revolution)
        return solve_problem(variant, CVODES(margins=1))[0]

    return Method("cvodes", {"segments": segments, "steps": None,
                             "per_revolution": per_revolution}, solve)


#: The shipped problems of the two transfers, in the order of :func:`cases`.
PROBLEMS = ("earth_mars_min_time", "earth_mars_low_thrust")


def cases():
    """The two transfers of :data:`PROBLEMS` with their methods and settings, a tuple of
    :class:`Case` loaded when called, so that importing the benches reads no file.

    At 1 mm/s^2 N is a total; at 0.1 mm/s^2 (about 6.5 revolutions) it is per revolution,
    as in the shipped problem.  Both run down to coarse settings, since a curve must start
    above a miss to be read there rather than only bounded; 10 x 3 is the closed form's
    coarsest at 1 mm/s^2 because fewer sub-arcs break the strain cap
    (``error_control.STRAIN_CAP``) and the seed adds them back.  CVODES segments are exact at
    any N and slow, so they run at two.
    """
    high_ac, low_ac = (shipped_problem(name) for name in PROBLEMS)
    return (
        Case(high_ac, (
            closed_form(segments=10, sub_arcs=3),
            *(closed_form(segments=n, sub_arcs=s) for n in (20, 40, 60) for s in (1, 3)),
            *(corrected(segments=n, sub_arcs=3, rounds=k) for n in (20, 40) for k in (1, 2)),
            *(rk4(segments=n, steps=m) for n in (10, 20, 30, 60, 100) for m in (1, 2, 4)),
            cvodes(segments=20), cvodes(segments=40),
        )),
        Case(low_ac, (
            *(closed_form(per_revolution=k, sub_arcs=s) for k in (2, 3, 4, 8, 16, 24)
              for s in (1, 2)),
            *(corrected(per_revolution=k, sub_arcs=2, rounds=r) for k in (8, 16) for r in (1, 2)),
            *(rk4(per_revolution=k, steps=m) for k in (2, 3, 4, 8, 16, 24) for m in (1, 2, 4)),
            cvodes(per_revolution=4), cvodes(per_revolution=8),
        )),
    )


# ------------------------------------------------------------------ reading the curves


def envelope(points):
    """The lower-left envelope of (seconds, miss_km) points, each point that every faster one
    misses by more (a miss of None, failed, left out): a list of (seconds, miss), seconds
    strictly increasing, miss strictly decreasing."""
    kept = []
    # Ties in time: the more accurate first, so the other is dropped as dominated.
    for seconds, miss in sorted((p for p in points if p[1] is not None),
                                key=lambda p: (p[0], p[1])):
        if not kept or miss < kept[-1][1]:
            kept.append((float(seconds), float(miss)))
    return kept


def seconds_at_miss(points, target):
    """Seconds at which one method's (seconds, miss_km) ``points`` reach a miss of ``target``
    km (> 0), read on their :func:`envelope`; None if no point reaches it.  With B the
    fastest point with miss <= ``target`` and A the envelope point before it, the time is
    interpolated linearly in (log seconds, log miss), the usual reading of a work-precision
    curve; when B is the fastest point it is B's own time, as extrapolating below the
    fastest setting measured would not be sound.
    """
    front = envelope(points)
    for i, (s_b, m_b) in enumerate(front):
        if m_b > target:
            continue
        if i == 0 or m_b <= 0.0:
            return s_b
        s_a, m_a = front[i - 1]
        frac = (math.log(target) - math.log(m_a)) / (math.log(m_b) - math.log(m_a))
        return math.exp(math.log(s_a) + frac * (math.log(s_b) - math.log(s_a)))
    return None


def at_miss(points, names=REPORTED):
    """The ``at_miss_km`` entry of one case: each method's seconds at each target miss
    and each other method's ratio to :data:`BASELINE` (None where either is None)."""
    names = list(dict.fromkeys(list(names) + [p["method"] for p in points]))
    curves = {name: [(p["seconds"], p["miss_km"]) for p in points if p["method"] == name]
              for name in names}
    out = {}
    for key, target in MISSES_KM.items():
        row = {f"{name}_seconds": seconds_at_miss(curves[name], target) for name in names}
        base = row[f"{BASELINE}_seconds"]
        for name in names:
            if name != BASELINE:
                other = row[f"{name}_seconds"]
                row[f"ratio_{name}_over_{BASELINE}"] = (
                    None if other is None or base is None else other / base)
        out[key] = row
    return out


# ------------------------------------------------------------------ running


def _warm_up():
    """Load Ipopt's and CVODES's plugins and the closed form's Functions before any
    timing, so that the first point timed does not pay for the process's start-up."""
    import casadi as ca

    from esail_opt.propagation.simulate import simulate

    x = ca.MX.sym("x")
    ca.nlpsol("warm_up", "ipopt", {"x": x, "f": (x - 1) ** 2},
              {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False})(x0=0)
    simulate([1.0, 0.0, 0.0, 1.0], [0.5], [0.1], 1e-3, length_in="theta")


def _label(settings):
    return ", ".join(f"{k} {v}" for k, v in settings.items() if v is not None)


def run_point(problem, method, runs):
    """Solve with ``method`` ``runs`` times, verify the last result and print a progress line
    to stderr.  Returns ``{"method", "segments", "steps", "seconds", "miss_km", "status"}``:
    the median wall time of ``method.solve``; the CVODES flight's distance to the target
    orbit (km; None when Ipopt did not converge or the flight failed); Ipopt's return
    status, or what failed.
    """
    from esail_opt.optimisation.verify import verify
    from esail_opt.physics import constants as units

    times, result, status = [], None, None
    for _ in range(runs):
        start = time.perf_counter()
        try:
            result = method.solve(problem)
        except Exception as err:  # a setting that cannot be built or solved is a point too
            times.append(time.perf_counter() - start)
            result, status = None, f"error: {type(err).__name__}: {err}".splitlines()[0]
            break
        times.append(time.perf_counter() - start)
    miss, detail = None, ""
    segments = method.settings.get("segments")
    if result is not None:
        status = result.status
        segments = int(result.alpha.size)
        detail = (f", {result.iterations} it, tof "
                  f"{units.time_to_days(float(sum(result.durations))):.2f} d")
        if result.converged:
            check = verify(problem, result)
            if check.error is not None:
                status = check.error
            else:
                miss = check.misses["target_miss_r_km"]
    point = {"method": method.name, "segments": segments,
             "steps": method.settings.get("steps"),
             "seconds": statistics.median(times), "miss_km": miss, "status": status}
    text = "failed" if miss is None else f"{miss:.3g} km"
    print(f"bench precision: {problem.name}: {method.name} ({_label(method.settings)}, "
          f"N = {segments}): {point['seconds']:.3g} s, miss {text}, {status}{detail}",
          file=sys.stderr, flush=True)
    return point


def run_case(case, runs):
    """All methods of one case; returns its JSON entry (``problem``, ``ac_mm_s2``,
    ``points``, ``at_miss_km``)."""
    problem = equal_lengths(case.problem)
    points = [run_point(problem, method, runs) for method in case.methods]
    return {"problem": problem.name, "ac_mm_s2": problem.sail.ac_mm_s2, "points": points,
            "at_miss_km": at_miss(points)}


def draw_precision(case, ax=None,
                   xlabel="solve time [s] (seed + NLP construction + Ipopt)",
                   ylabel="verified target miss [km] (CVODES flight)"):
    """Draw one case's log-log work-precision diagram on ``ax`` (default: a new Figure's)
    and return the axes: every point, each method's envelope as a line, the target misses
    as horizontal lines.  ``case`` is an entry of ``precision.json``'s ``cases``
    (:func:`run_case`), or any dict with its ``problem``, ``ac_mm_s2`` and ``points``."""
    if ax is None:
        from matplotlib.figure import Figure

        ax = Figure(figsize=(6.0, 4.8)).subplots()
    styles = {"closed_form": ("o", "C0"), "rk4": ("s", "C1"), "cvodes": ("^", "C2")}
    names = list(dict.fromkeys(p["method"] for p in case["points"]))
    for i, name in enumerate(names):
        marker, colour = styles.get(name, ("D", f"C{3 + i}"))
        mine = [p for p in case["points"] if p["method"] == name]
        ok = [(p["seconds"], p["miss_km"]) for p in mine if p["miss_km"] is not None]
        failed = len(mine) - len(ok)
        label = f"{name} ({failed} of {len(mine)} failed)" if failed else name
        if ok:
            ax.plot(*zip(*ok), marker, color=colour, alpha=0.45, ms=5)
        front = envelope(ok)
        if front:
            ax.plot(*zip(*front), "-", marker=marker, color=colour, label=label)
        else:
            ax.plot([], [], marker, color=colour, label=label)
    for key, miss in MISSES_KM.items():
        ax.axhline(miss, color="0.5", lw=0.8, ls="--")
        ax.annotate(f"{key} km", (1.0, miss), xycoords=("axes fraction", "data"),
                    ha="right", va="bottom", fontsize=8, color="0.4")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(f"{case['problem']}, a_c = {case['ac_mm_s2']:g} mm/s^2")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return ax


def precision_figure(cases):
    """One :func:`draw_precision` panel per case, side by side, on a new Figure."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0 * len(cases), 4.8))
    for ax, case in zip(fig.subplots(1, len(cases), squeeze=False)[0], cases):
        draw_precision(case, ax)
    fig.tight_layout()
    return fig


def run(out, repeats):
    """Every point of :func:`cases` by :func:`run_point` (median of ``runs_of(repeats)``),
    each curve read by :func:`at_miss`; writes ``<out>/precision.json`` and
    ``<out>/precision.png`` and returns the JSON's path."""
    from esail_opt.app.outputs import save_figure, write_json

    runs = runs_of(repeats)
    _warm_up()
    solved = [run_case(case, runs) for case in cases()]
    for case in solved:
        rows = []
        for key, row in case["at_miss_km"].items():
            for name, value in row.items():
                if value is None:
                    rows.append((f"{key} km: {name}", "never", ""))
                else:
                    rows.append((f"{key} km: {name}", float(value),
                                 "s" if name.endswith("_seconds") else ""))
        print_table(f"bench precision: {case['problem']}, a_c = {case['ac_mm_s2']:g} mm/s^2, "
                    f"median of {runs}", rows)
    path = Path(out) / "precision.json"
    write_json(path, {"cases": solved})
    save_figure(precision_figure(solved), Path(out) / "precision.png")
    return path
