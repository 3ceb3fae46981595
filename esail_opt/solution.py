"""A solved problem, in the boundary's units: JSON and CSV writing and reading, a summary.

:func:`solve` is the whole data path of a run -- Problem -> NLP -> Ipopt -> CVODES
verification -> :class:`Solution` -- and is what ``esail-opt solve`` and scripts call.
A Solution is a plain dict underneath (``.data``), exactly what ``solution.json`` holds,
so one loaded back from disk prints and plots like a fresh one.
"""

import csv
import functools
import io
import json
import math
from pathlib import Path

import casadi as ca
import numpy as np

from esail_opt.files import atomic_path, json_ready, write_json
from esail_opt.optimisation import problem as pb
from esail_opt.optimisation import polish as exact_refinement
from esail_opt.optimisation.solve import solve_problem
from esail_opt.optimisation.verify import verify
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_from_polar

SCHEDULE_FIELDS = ("t_days", "theta_deg", "alpha_deg", "duration_days", "dtheta_deg")
#: The column a throttled problem adds: kappa per segment, in [0, 1].  Unthrottled
#: schedules leave it out, so their files stay as they were.
THROTTLE_FIELD = "throttle"


@functools.lru_cache(maxsize=None)
def _elements_function():
    """Osculating (a, e) of one polar state as a Function, so it maps over columns
    (classical_from_polar itself is written for one state)."""
    x = ca.SX.sym("x", 4)
    a, e = classical_from_polar(x)[:2]
    return ca.Function("elements", [x], [a, e])


def _polar_dict(x):
    """Polar state(s) (4 or 4 x M), canonical -> boundary units, with osculating a and e."""
    x = np.asarray(x, float)
    cols = x.reshape(4, -1)
    a, e = (np.array(v).ravel() for v in _elements_function().map(cols.shape[1])(cols))
    out = {"r_au": cols[0], "theta_deg": np.degrees(cols[1]),
           "vr_km_s": units.speed_to_km_s(cols[2]), "vtheta_km_s": units.speed_to_km_s(cols[3]),
           "a_au": a, "e": e}
    if x.ndim == 1:
        return {k: float(v[0]) for k, v in out.items()}
    return {k: np.asarray(v).tolist() for k, v in out.items()}


def _trajectory(xs):
    out = _polar_dict(xs[:4])
    out["t_days"] = units.time_to_days(np.asarray(xs[4])).tolist()
    return out


def _objective_meaning(objective):
    if isinstance(objective, pb.MinTime):
        return "time of flight, TU (minimised)"
    if isinstance(objective, pb.MaxRadius):
        return "-(final r), au (minimised)"
    if isinstance(objective, pb.MaxEnergy):
        return "-(final energy v^2/2 - 1/r), canonical (minimised)"
    return "user expression of the final state, canonical (minimised)"


def _target_dict(target):
    if target is None:
        return None
    out = {"kind": type(target).__name__}
    out.update({k: getattr(target, k) for k in target.__dataclass_fields__})
    return out


class Solution:
    """A solved problem: what ``solution.json`` holds, with reading, writing and printing.

    Parameters
    ----------
    data : dict
        The JSON content (see :func:`solve` for its fields).
    """

    def __init__(self, data):
        self.data = data

    # -- access
    @property
    def converged(self):
        return bool(self.data["converged"])

    @property
    def tof_days(self):
        return self.data["tof_days"]

    def __getitem__(self, key):
        return self.data[key]

    # -- files
    @classmethod
    def load(cls, path):
        """Read a ``solution.json`` back."""
        return cls(json.loads(Path(path).read_text()))

    def schedule_csv(self, polished=False):
        """The schedule as CSV text, one row per segment (same rows as ``schedule``, or
        with ``polished`` as ``polish["schedule"]``)."""
        rows = self.data["polish"]["schedule"] if polished else self.data["schedule"]
        fields = SCHEDULE_FIELDS + ((THROTTLE_FIELD,) if rows and THROTTLE_FIELD in rows[0]
                                    else ())
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: f"{row[k]:.10g}" for k in fields})
        return buf.getvalue()

    def write(self, out_dir, plots=True):
        """Write solution.json, schedule.csv (and schedule_polished.csv after a polish)
        and (optionally) the two PNGs, each atomically.

        Returns the list of paths written.
        """
        out = Path(out_dir)
        written = [out / "solution.json", out / "schedule.csv"]
        write_json(written[0], self.data)
        with atomic_path(written[1]) as tmp:
            tmp.write_text(self.schedule_csv())
        if "schedule" in self.data.get("polish", {}):
            written.append(out / "schedule_polished.csv")
            with atomic_path(written[-1]) as tmp:
                tmp.write_text(self.schedule_csv(polished=True))
        if plots:
            from esail_opt import plots as plotting

            written += plotting.write_plots(self, out)
        return written

    # -- printing
    def summary(self):
        d = self.data
        v = d["verification"]
        lines = [
            f"{d['problem']['name']}: {d['status']} ({'converged' if d['converged'] else 'NOT converged'}), "
            f"{d['iterations']} iterations, {d['solve_seconds']:.2f} s",
            f"  tof {d['tof_days']:.3f} d (closed form), {len(d['schedule'])} segments x "
            f"{d['problem']['sub_arcs']} sub-arcs",
            "  final (closed form): r {r_au:.6f} au, theta {theta_deg:.3f} deg, a {a_au:.6f} au, "
            "e {e:.5f}".format(**d["final_state"]),
        ]
        if v.get("error"):
            lines.append(f"  verification: {v['error']}")
        else:
            cv = v["cvodes_final_state"]
            lines.append(f"  CVODES: r {cv['r_au']:.6f} au, a {cv['a_au']:.6f} au, e {cv['e']:.5f}; "
                         f"miss vs NLP {v['miss_r_km']:.4g} km, {v['miss_v_m_s']:.4g} m/s, "
                         f"{v['miss_theta_deg']:.4g} deg")
            if v.get("target_miss_r_km") is not None:
                extra = (f", {v['target_miss_v_m_s']:.4g} m/s"
                         if v.get("target_miss_v_m_s") is not None else "")
                lines.append(f"  CVODES miss vs target: {v['target_miss_r_km']:.4g} km{extra}")
        lines += self._polish_lines()
        return "\n".join(lines)

    def _polish_lines(self):
        """Summary lines of the exact refinement, if there was one."""
        p = self.data.get("polish")
        if p is None:
            return []
        if p.get("status") is None:
            return [f"  polish: {p['note']}"]
        lines = [f"  polish: {p['status']} ({'converged' if p['converged'] else 'NOT converged'}), "
                 f"{p['iterations']} iterations, {p['seconds']:.2f} s; exact tof "
                 f"{p['tof_days']:.3f} d (closed form {self.data['tof_days']:.3f} d)"]
        v = p["verification"]
        if v.get("error") is None:
            line = (f"  polished CVODES miss vs NLP {v['miss_r_m']:.3g} m, "
                    f"{v['miss_v_mm_s']:.3g} mm/s")
            if v.get("target_miss_r_m") is not None:
                line += f"; vs target {v['target_miss_r_m']:.3g} m"
                if v.get("target_miss_v_mm_s") is not None:
                    line += f", {v['target_miss_v_mm_s']:.3g} mm/s"
            lines.append(line)
        lines.append(f"  polish: {p['note']}")
        return lines

    def __str__(self):
        return self.summary()

    def plot(self, out_dir=None):
        """Draw trajectory.png and timeline.png figures; write them if ``out_dir`` is given."""
        from esail_opt import plots as plotting

        if out_dir is not None:
            return plotting.write_plots(self, out_dir)
        return plotting.trajectory_figure(self), plotting.timeline_figure(self)


def _schedule(result, throttled=False):
    """Per-segment rows (boundary units) of an NLP result's schedule; with ``throttled``
    each row also carries its ``throttle`` kappa."""
    starts_t = np.r_[0.0, np.cumsum(result.durations)[:-1]]
    starts_th = np.r_[result.x_start[1], result.nodes[1, :-1]]
    rows = [
        {"t_days": units.time_to_days(t), "theta_deg": math.degrees(th),
         "alpha_deg": math.degrees(al), "duration_days": units.time_to_days(dt),
         "dtheta_deg": math.degrees(ln)}
        for t, th, al, dt, ln in zip(starts_t, starts_th, result.alpha, result.durations,
                                     result.lengths)
    ]
    if throttled:
        for row, kappa in zip(rows, result.throttle):
            row[THROTTLE_FIELD] = float(kappa)
    return rows


def _metres(km):
    return None if km is None else 1e3 * km


def _polish_data(problem, exact, check):
    """The ``polish`` object of solution.json: the exact optimum and its verification.

    Misses are in metres and mm/s, the scale of the bounds (1 m, 1 mm/s) they are held
    to; ``verified`` is True only when Ipopt converged and both the miss against the
    polished NLP's final state and the miss against the target are within them.
    """
    m = check.misses
    vs_nlp = {"position_m": _metres(m["miss_r_km"]),
              "velocity_mm_s": _metres(m["miss_v_m_s"])}
    vs_target = {"position_m": _metres(m["target_miss_r_km"]),
                 "velocity_mm_s": _metres(m["target_miss_v_m_s"])}
    verification = {"miss_r_m": vs_nlp["position_m"], "miss_v_mm_s": vs_nlp["velocity_mm_s"],
                    "miss_theta_deg": m["miss_theta_deg"],
                    "target_miss_r_m": vs_target["position_m"],
                    "target_miss_v_mm_s": vs_target["velocity_mm_s"], "error": check.error}
    if "target_miss_e" in m:
        verification["target_miss_e"] = m["target_miss_e"]
    if check.error is None:
        verification["cvodes_final_state"] = _polar_dict(check.cvodes[:4, -1])
        verification["cvodes_tof_days"] = units.time_to_days(float(check.cvodes[4, -1]))
    within_nlp = exact_refinement.meets_bounds(vs_nlp)
    # No target: nothing to miss.  An (a, e) target's position miss is the error of a.
    within_target = problem.target is None or exact_refinement.meets_bounds(vs_target)
    verified = exact.converged and within_nlp and within_target
    problems = []
    if not exact.converged:
        problems.append(f"Ipopt did not converge ({exact.status})")
    if check.error is not None:
        problems.append(check.error)
    else:
        if not within_nlp:
            problems.append("the CVODES flight misses the polished NLP's final state by "
                            f"{vs_nlp['position_m']:.3g} m, {vs_nlp['velocity_mm_s']:.3g} mm/s")
        if not within_target:
            extra = (f", {vs_target['velocity_mm_s']:.3g} mm/s"
                     if vs_target["velocity_mm_s"] is not None else "")
            problems.append(f"the CVODES flight misses the target by "
                            f"{vs_target['position_m']:.3g} m{extra}")
    bounds = (f"{exact_refinement.MISS_BOUND_M:g} m and "
              f"{exact_refinement.MISS_BOUND_MM_S:g} mm/s")
    note = (f"exact: verified miss below {bounds}" if verified else
            f"NOT exact to {bounds}: " + "; ".join(problems))
    return {
        "status": exact.status, "converged": exact.converged, "outcome": exact.outcome,
        "iterations": exact.iterations, "seconds": exact.solve_seconds,
        "constraint_violation": exact.constraint_violation,
        "objective": exact.objective,
        "tof_days": units.time_to_days(float(np.sum(exact.durations))),
        "bounds": {"position_m": exact_refinement.MISS_BOUND_M,
                   "velocity_mm_s": exact_refinement.MISS_BOUND_MM_S},
        "within_bounds_vs_nlp": within_nlp, "within_bounds_vs_target": within_target,
        "verified": verified, "note": note,
        "schedule": _schedule(exact, problem.sail.throttle),
        "final_state": _polar_dict(exact.nodes[:, -1]),
        "verification": verification,
    }


def solve(problem, segments=None, progress=None, samples=16, polish=False):
    """Solve ``problem`` and verify it on CVODES: the whole data path of one run.

    Parameters
    ----------
    problem : esail_opt.Problem
    segments : int, optional
        Override the problem's number of control segments N (>= 1).
    progress : callable, optional
        ``progress(text)`` is called at each stage (the CLI shows it on stderr).
    samples : int
        Plot samples per segment.
    polish : bool
        Then refine the closed-form optimum on exact CVODES arcs in time
        (:func:`esail_opt.optimisation.polish.polish`) and verify that schedule too.

    Returns
    -------
    Solution
        Its ``data`` has: ``problem`` (name and settings; ``segments`` is the count N
        used, also when ``segments_per_revolution`` set it), ``status`` (Ipopt's return
        status), ``converged`` (True only for "Solve_Succeeded"), ``acceptable`` (True for
        "Solved_To_Acceptable_Level", which is *not* counted as converged), ``outcome``
        ("converged", "acceptable", "infeasible" or "failed"), ``objective`` and
        ``objective_meaning``, ``tof_days``, ``iterations``, ``solve_seconds``,
        ``constraint_violation``, ``schedule`` (per segment ``t_days`` and ``theta_deg``
        at its start, ``alpha_deg``, ``duration_days``, ``dtheta_deg``, and with
        ``Sail(throttle=True)`` ``throttle``, kappa in [0, 1]), ``final_state``
        (closed form: ``r_au``, ``theta_deg``, ``vr_km_s``, ``vtheta_km_s``, ``a_au``,
        ``e``), ``verification`` (``miss_r_km``, ``miss_v_m_s``, ``miss_theta_deg`` of
        CVODES against the NLP's final state; ``target_miss_r_km``/``target_miss_v_m_s``
        of CVODES against the target; ``cvodes_final_state``), and ``trajectory``
        (closed-form and CVODES samples for the plots).

        With ``polish``, also ``objective_closed_form`` (= ``objective``),
        ``objective_exact``, ``tof_days_exact``, ``trajectory["polished"]`` (the CVODES
        flight of the polished schedule) and ``polish``: ``status``, ``converged``,
        ``outcome``, ``iterations``, ``seconds``, ``constraint_violation``,
        ``objective``, ``tof_days``, ``schedule``, ``final_state`` (the polished NLP's),
        ``verification`` (``miss_r_m``, ``miss_v_mm_s`` against the polished NLP's final
        state, ``target_miss_r_m``, ``target_miss_v_mm_s`` against the target, of the
        schedule flown from the departure in one CVODES chain), ``bounds`` (1 m,
        1 mm/s), ``within_bounds_vs_nlp``, ``within_bounds_vs_target``, ``verified``
        and ``note`` (says plainly when the polished schedule is not exact).  The other
        fields stay those of the closed-form optimum.
    """
    from esail_opt.errors import InputError

    if segments is not None:
        if isinstance(segments, bool) or not isinstance(segments, int) or segments < 1:
            raise InputError(f"segments = {segments!r} is outside [1, inf)")
        problem = problem.with_segments(segments)
    say = progress or (lambda text: None)
    seg = problem.segments
    count = (f"{seg.count} segments" if seg.per_revolution is None
             else f"{seg.per_revolution} segments per revolution")
    say(f"{problem.name}: building the NLP ({count} x {seg.sub_arcs} sub-arcs)")
    result, tr = solve_problem(problem)
    say(f"{problem.name}: {result.status} after {result.iterations} iterations; verifying on CVODES")
    return solution_of(problem, result, tr.guess.revolutions_k, samples, polish, say)


def solution_of(problem, result, revolutions_k=0, samples=16, polish=False, progress=None,
                theta_window=None):
    """The :class:`Solution` of a closed-form optimum already found: its CVODES
    verification and, with ``polish``, its exact refinement (see :func:`solve`, which
    is this after the solve; the global search calls it for each optimum it keeps).

    ``revolutions_k`` is the rendezvous turn count of the NLP (``Transcription.guess``),
    and ``theta_window`` the final-angle box (rad) it was solved in, which the polish keeps.
    """
    say = progress or (lambda text: None)
    seg = problem.segments
    # The count actually used: with a per-revolution rule the seed propagation fixed it.
    n, sub = result.alpha.size, seg.sub_arcs
    check = verify(problem, result, samples)
    schedule = _schedule(result, problem.sail.throttle)
    verification = {k: v for k, v in check.misses.items()}
    verification["error"] = check.error
    if check.error is None:
        verification["cvodes_final_state"] = _polar_dict(check.cvodes[:4, -1])
        verification["cvodes_tof_days"] = units.time_to_days(float(check.cvodes[4, -1]))
    dep = problem.departure
    data = {
        "problem": {
            "name": problem.name, "description": problem.description,
            "ac_mm_s2": problem.sail.ac_mm_s2, "coefficients": list(problem.sail.coefficients),
            "alpha_bounds_deg": [problem.sail.alpha_min_deg, problem.sail.alpha_max_deg],
            "segments": n, "segments_per_revolution": seg.per_revolution,
            "sub_arcs": sub, "equal_segments": seg.equal,
            "objective": type(problem.objective).__name__,
            "target": _target_dict(problem.target),
            "departure": {"kind": type(dep).__name__,
                          **{k: getattr(dep, k) for k in dep.__dataclass_fields__}},
            "departure_state": _polar_dict(result.x_start),
            "r_min_au": problem.path.r_min_au, "q3_margin": problem.path.q3_margin,
        },
        "status": result.status,
        "converged": result.converged,
        "acceptable": result.outcome == "acceptable",
        "outcome": result.outcome,
        "objective": result.objective,
        "objective_meaning": _objective_meaning(problem.objective),
        "tof_days": units.time_to_days(float(np.sum(result.durations))),
        "iterations": result.iterations,
        "stages": [{"status": st, "iterations": it} for st, it in result.stages],
        "solve_seconds": result.solve_seconds,
        "constraint_violation": result.constraint_violation,
        "min_q3": float(np.min(result.q3)),
        "schedule": schedule,
        "final_state": _polar_dict(result.nodes[:, -1]),
        "verification": verification,
        "trajectory": {
            "closed_form": _trajectory(check.closed_form),
            "cvodes": _trajectory(check.cvodes) if check.error is None else None,
        },
    }
    if problem.sail.throttle:
        # Only a throttled problem names its bounds: an unthrottled solution.json is
        # exactly what it was before throttles existed.
        data["problem"]["throttle_bounds"] = [problem.sail.throttle_min, problem.sail.throttle_max]
    # A closed form that found no optimum has nothing worth refining.
    if polish and result.outcome in ("converged", "acceptable"):
        say(f"{problem.name}: polishing on exact CVODES arcs in time ({n} segments)")
        exact, _ = exact_refinement.polish(problem, result, revolutions_k,
                                           theta_window=theta_window)
        say(f"{problem.name}: polish {exact.status} after {exact.iterations} iterations; "
            "verifying on CVODES")
        exact_check = verify(problem, exact, samples)
        data["objective_closed_form"] = result.objective
        data["objective_exact"] = exact.objective
        data["tof_days_exact"] = units.time_to_days(float(np.sum(exact.durations)))
        data["polish"] = _polish_data(problem, exact, exact_check)
        data["trajectory"]["polished"] = (_trajectory(exact_check.cvodes)
                                          if exact_check.error is None else None)
    elif polish:
        data["polish"] = {"status": None, "converged": False, "verified": False,
                          "note": f"NOT polished: the closed-form solve ended {result.status}"}
    return Solution(json_ready(data))

