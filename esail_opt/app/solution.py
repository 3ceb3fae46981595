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

from esail_opt.app import schema
from esail_opt.app.files import json_ready, publish, write_json
from esail_opt.bodies import dates, lookup
from esail_opt.optimisation import exact as exact_refinement
from esail_opt.optimisation import scan
from esail_opt.optimisation.refine import MAX_SUB_ARCS, refine
from esail_opt.optimisation.transcription import initial_guess, sub_arcs_within_cap
from esail_opt.optimisation.ipopt import solve_problem
from esail_opt.optimisation.verify import verify, within
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_from_polar

SCHEDULE_FIELDS = ("t_days", "theta_deg", "alpha_deg", "duration_days", "dtheta_deg")
#: The column a throttled problem adds: kappa per segment, in [0, 1].  Unthrottled
#: schedules leave it out, so their files stay as they were.
THROTTLE_FIELD = "throttle"
#: The closed form's local error per segment, km (absent from polished schedules).
LOCAL_ERROR_FIELD = "local_error_km"
#: Every file :meth:`Solution.write` may put in its folder: the set that a new write
#: replaces whole (anything else in the folder is the user's and stays).
SOLUTION_FILES = ("solution.json", "schedule.csv", "schedule_polished.csv",
                  "trajectory.png", "timeline.png")


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


def _fields(obj):
    """A problem part's kind and fields; a body is given by its name."""
    out = {"kind": type(obj).__name__}
    out.update({k: getattr(obj, k) for k in obj.__dataclass_fields__})
    if "body" in out:
        out["body"] = lookup.describe(out["body"])
    return out


def _target_dict(target):
    return None if target is None else _fields(target)


def _calendar_data(problem, result, check):
    """The dated part of solution.json: departure and arrival dates (ISO 8601, TDB),
    the bodies with their sources, the planes' distances the 2-D model ignores, and
    what a MinAcceleration objective found.  Empty for problems off the calendar."""
    out = {}
    if problem.objective.free_acceleration:
        out["ac_mm_s2_required"] = problem.sail.ac_mm_s2 * result.ac_scale
    if not problem.dated():
        return out
    dep = problem.departure
    start_jd = dates.jd_from_tu(result.epoch)
    tof = float(np.sum(result.durations))
    out["departure_date"] = dates.iso_from_jd(start_jd)
    out["arrival_date"] = dates.iso_from_jd(dates.jd_from_tu(result.epoch + tof))
    z0 = lookup.polar_state(dep.body, start_jd)[1]
    out["departure_body"] = {"name": lookup.name(dep.body), "source": lookup.source(dep.body),
                             "out_of_plane_km": units.length_to_km(abs(z0)),
                             "vinf_km_s": dep.vinf_km_s,
                             # The NLP's angle is unbounded: reported in [-180, 180).
                             "vinf_angle_deg": (math.degrees(result.vinf_angle) + 180) % 360
                             - 180}
    target = problem.target
    if target is not None and getattr(target, "body", None) is not None:
        m = check.misses
        out["target_body"] = {"name": lookup.name(target.body),
                              "source": lookup.source(target.body),
                              "kind": type(target).__name__,
                              "out_of_plane_km": m.get("out_of_plane_km"),
                              "relative_speed_km_s": m.get("relative_speed_km_s")}
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
    def verified(self):
        """Converged, and the flight on Eqs. 1-2 meets the tolerance (and, after a
        polish, the polish's 1 m and 1 mm/s as well)."""
        polished = self.data.get("polish")
        return bool(self.data["verified"]) and (polished is None or bool(polished["verified"]))

    @property
    def tof_days(self):
        return self.data["tof_days"]

    def __getitem__(self, key):
        return self.data[key]

    # -- files
    @classmethod
    def load(cls, path):
        """Read a ``solution.json`` back; one of another schema version is refused with
        an InputError that says so."""
        data = json.loads(Path(path).read_text())
        schema.check(data, path)
        return cls(data)

    def schedule_csv(self, polished=False):
        """The schedule as CSV text, one row per segment (same rows as ``schedule``, or
        with ``polished`` as ``polish["schedule"]``), every number to the digit, so that
        flying the file reproduces the flight that was verified.  (At 10 significant
        digits a polished 2500-day schedule, flown from the CSV, ended 3.5 m from its
        target where the same schedule at full precision ends 8 mm from it.)"""
        rows = self.data["polish"]["schedule"] if polished else self.data["schedule"]
        fields = SCHEDULE_FIELDS + tuple(f for f in (THROTTLE_FIELD, LOCAL_ERROR_FIELD)
                                         if rows and f in rows[0])
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: repr(float(row[k])) for k in fields})
        return buf.getvalue()

    def write(self, out_dir, plots=True):
        """Write solution.json, schedule.csv (and schedule_polished.csv after a polish)
        and (optionally) the two PNGs into ``out_dir``, as one set
        (:func:`esail_opt.app.files.publish`): a reader of the folder sees the previous
        run's files or these, never a mix, and files of the user's own stay.

        Returns the list of paths written.

        Raises
        ------
        OutputError
            The folder cannot be written (one line; the old set stays as it was).
        """
        out = Path(out_dir)
        with publish(out, family=SOLUTION_FILES) as stage:
            names = ["solution.json", "schedule.csv"]
            write_json(stage / names[0], self.data)
            (stage / names[1]).write_text(self.schedule_csv())
            if "schedule" in self.data.get("polish", {}):
                names.append("schedule_polished.csv")
                (stage / names[-1]).write_text(self.schedule_csv(polished=True))
            if plots:
                from esail_opt.app import plots as plotting

                names += [p.name for p in plotting.write_plots(self, stage)]
        return [out / name for name in names]

    # -- printing
    def summary(self):
        d = self.data
        v = d["verification"]
        rounds = d["refinement"]["rounds"]
        lines = [
            f"{d['problem']['name']}: {d['status']} ({'converged' if d['converged'] else 'NOT converged'}), "
            f"{d['iterations']} iterations, {d['solve_seconds']:.2f} s, "
            f"{max(len(rounds) - 1, 0)} refinement round(s)",
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
        lines.append(f"  {d['verification_note']}")
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
            # At the polish's scale a km reads better as metres.
            line = (f"  polished CVODES miss vs NLP {1e3 * v['miss_r_km']:.3g} m, "
                    f"{1e3 * v['miss_v_m_s']:.3g} mm/s")
            if v.get("target_miss_r_km") is not None:
                line += f"; vs target {1e3 * v['target_miss_r_km']:.3g} m"
                if v.get("target_miss_v_m_s") is not None:
                    line += f", {1e3 * v['target_miss_v_m_s']:.3g} mm/s"
            lines.append(line)
        lines.append(f"  polish: {p['note']}")
        return lines

    def __str__(self):
        return self.summary()

    def plot(self, out_dir=None):
        """Draw trajectory.png and timeline.png figures; write them if ``out_dir`` is given."""
        from esail_opt.app import plots as plotting

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


def _verification_data(check):
    """The ``verification`` object of solution.json (closed form and polish alike)."""
    out = dict(check.misses)
    out["error"] = check.error
    if check.error is None:
        out["cvodes_final_state"] = _polar_dict(check.cvodes[:4, -1])
        out["cvodes_tof_days"] = units.time_to_days(float(check.cvodes[4, -1]))
    return out


def _polish_data(problem, exact, check):
    """The ``polish`` object of solution.json: the exact optimum and its verification.

    ``verified`` is True only when Ipopt converged and the flight, its verifier's error
    included, is within the polish's bounds (1 m, 1 mm/s) of both the target and the
    polished NLP's final state.
    """
    m = check.misses
    within_all, note = check.judge(problem, exact_refinement.TOLERANCE, against_nlp=True)
    verified = exact.converged and within_all
    if not exact.converged:
        note = f"NOT verified: Ipopt did not converge ({exact.status}); {note}"
    elif verified:
        note = f"exact: {note}"
    return {
        "status": exact.status, "converged": exact.converged, "outcome": exact.outcome,
        "iterations": exact.iterations, "seconds": exact.solve_seconds,
        "constraint_violation": exact.constraint_violation,
        "objective": exact.objective,
        "tof_days": units.time_to_days(float(np.sum(exact.durations))),
        "bounds": {"position_km": exact_refinement.TOLERANCE.position_km,
                   "velocity_m_s": exact_refinement.TOLERANCE.velocity_m_s},
        "within_bounds_vs_nlp": within(m, exact_refinement.TOLERANCE, "nlp"),
        "within_bounds_vs_target": problem.target is None or within(m, exact_refinement.TOLERANCE),
        "verified": verified, "note": note,
        "schedule": _schedule(exact, problem.throttled()),
        "final_state": _polar_dict(exact.nodes[:4, -1]),
        "verification": _verification_data(check),
    }


def solve(problem, segments=None, progress=None, samples=16, polish=False):
    """Solve ``problem``, refine it until its flight on Eqs. 1-2 meets the problem's
    tolerance, and verify it: the whole data path of one run.

    Parameters
    ----------
    problem : esail_opt.Problem
    segments : int, optional
        Override the problem's number of control segments N (>= 1).
    progress : callable, optional
        ``progress(text)`` is called at each stage and every few seconds of Ipopt.
    samples : int
        Plot samples per segment.
    polish : bool
        Then refine the optimum on the exact Eqs. 1-2 in time
        (:func:`esail_opt.optimisation.exact.polish`) and verify that schedule too.

    Returns
    -------
    Solution
        Its ``data`` is what ``solution.json`` holds, as :mod:`esail_opt.app.schema`
        writes down.
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
    guess = None
    if problem.free_date():
        problem, guess = scan.seed_free_date(problem, say)
    if guess is None:
        guess = initial_guess(problem)
        problem = sub_arcs_within_cap(problem, guess, MAX_SUB_ARCS)
    say(f"{problem.name}: building the NLP ({count} x {problem.segments.sub_arcs} sub-arcs)")
    # A free date's guess is already the optimum of its best date: no staging from it.
    result, tr = solve_problem(problem, guess=guess, progress=say,
                               staged=not problem.free_date())
    starts = []
    if result.outcome not in ("converged", "acceptable"):
        result, tr, starts = _other_starts(problem, result, tr, say)
    say(f"{problem.name}: {result.status} after {result.iterations} iterations; "
        "refining until the flight meets the tolerance")
    return solution_of(problem, result, tr, samples=samples, polish=polish, progress=say,
                       starts=starts, sub_arcs_requested=seg.sub_arcs)


def _other_starts(problem, result, tr, say):
    """Ipopt's "infeasible" from one start is a local statement: before giving up, try
    the starts the global search would (other turn counts on a rendezvous body, other
    constant-pitch seeds of an orbit transfer), and keep the first that converges.

    Returns the (result, transcription) to go on with and one record per start tried.
    """
    from esail_opt.optimisation import multistart

    records = [{"label": "the problem's own seed", "status": result.status,
                "iterations": result.iterations}]
    if problem.target is None or getattr(problem.departure, "free_anomaly", False):
        return result, tr, records
    for start in multistart.fallback_starts(problem, tr.guess):
        say(f"{problem.name}: {result.status}; trying {start.label}")
        other, other_tr = solve_problem(problem, guess=start.guess, progress=say)
        records.append({"label": start.label, "status": other.status,
                        "iterations": other.iterations})
        if other.outcome in ("converged", "acceptable"):
            other.iterations += sum(r["iterations"] for r in records[:-1])
            return other, other_tr, records
    return result, tr, records


def solution_of(problem, result, tr=None, samples=16, polish=False, progress=None,
                starts=None, sub_arcs_requested=None):
    """The :class:`Solution` of a closed-form optimum already found: its error control
    (``optimisation.refine``), its CVODES verification and, with ``polish``, its exact
    refinement (see :func:`solve`, which is this after the solve; the global search
    calls it for each optimum it keeps).

    ``tr`` is the optimum's NLP (the refinement re-solves it warm; without it a new one
    is built; either way the refinement and the polish keep ``result``'s revolution
    class), ``starts`` the records of the starts tried before this one, and
    ``sub_arcs_requested`` the problem file's sub-arcs when the seed already raised them.
    """
    requested = sub_arcs_requested or problem.segments.sub_arcs
    say = progress or (lambda text: None)
    refined = None
    if result.outcome in ("converged", "acceptable"):
        refined = refine(problem, result, tr, say)
        iterations = result.iterations + sum(r["iterations"] for r in refined.history[1:])
        seconds = result.solve_seconds + refined.history[-1]["seconds"]
        problem, result, tr = refined.problem, refined.result, refined.transcription
        result.iterations, result.solve_seconds = iterations, seconds
    check = verify(problem, result, samples,
                   defects=None if refined is None else refined.defects)
    verified, note = check.judge(problem)
    verified = verified and result.converged
    if not result.converged:
        note = f"NOT verified: Ipopt ended {result.status}" + (
            "" if result.outcome != "infeasible" else
            f" from {len(starts or [1])} start(s); no start found a feasible point, which "
            "does not prove the target unreachable")
    schedule = _schedule(result, problem.throttled())
    if refined is not None:
        for row, err in zip(schedule, refined.local_error_km):
            row["local_error_km"] = float(err)
    data = {
        "schema_version": schema.SCHEMA_VERSION,
        "problem": _problem_data(problem, result, requested),
        "status": result.status,
        "converged": result.converged,
        "acceptable": result.outcome == "acceptable",
        "outcome": result.outcome,
        "verified": verified,
        "verification_note": note,
        "tolerance": {"position_km": problem.tolerance.position_km,
                      "velocity_m_s": problem.tolerance.velocity_m_s},
        "objective": result.objective,
        "objective_meaning": problem.objective.meaning,
        "tof_days": units.time_to_days(float(np.sum(result.durations))),
        "iterations": result.iterations,
        "stages": [{"status": st, "iterations": it} for st, it in result.stages],
        "solve_seconds": result.solve_seconds,
        "constraint_violation": result.constraint_violation,
        "min_q3": float(np.min(result.q3)),
        "schedule": schedule,
        "final_state": _polar_dict(result.nodes[:4, -1]),
        "verification": _verification_data(check),
        "refinement": {"rounds": [] if refined is None else refined.history,
                       "starts": starts or []},
        "trajectory": {
            "closed_form": _trajectory(check.closed_form),
            "cvodes": _trajectory(check.cvodes) if check.error is None else None,
        },
        **_calendar_data(problem, result, check),
    }
    if polish:
        _add_polish(data, problem, result, samples, say)
    return Solution(json_ready(data))


def _problem_data(problem, result, sub_arcs_requested):
    """The ``problem`` object of solution.json: the settings as solved (``segments`` is
    the count used, also when a per-revolution rule set it; ``sub_arcs`` the count the
    error control ended with)."""
    seg, dep = problem.segments, problem.departure
    out = {
        "name": problem.name, "description": problem.description,
        "ac_mm_s2": problem.sail.ac_mm_s2, "coefficients": list(problem.sail.coefficients),
        "alpha_bounds_deg": [problem.sail.alpha_min_deg, problem.sail.alpha_max_deg],
        "segments": int(result.alpha.size), "segments_per_revolution": seg.per_revolution,
        "sub_arcs": seg.sub_arcs, "sub_arcs_requested": sub_arcs_requested,
        "equal_segments": seg.equal, "objective": type(problem.objective).__name__,
        "target": _target_dict(problem.target),
        "departure": _fields(dep),
        "departure_state": _polar_dict(result.x_start),
        "r_min_au": problem.path.r_min_au, "q3_margin": problem.path.q3_margin,
    }
    if problem.throttled():
        # Only a throttled problem names its bounds: an unthrottled solution.json is
        # exactly what it was before throttles existed.
        out["throttle_bounds"] = list(problem.throttle_bounds())
    return out


def _add_polish(data, problem, result, samples, say):
    """Polish ``result`` on exact arcs and add what it found to ``data``."""
    # A closed form that found no optimum has nothing worth refining.
    if result.outcome not in ("converged", "acceptable"):
        data["polish"] = {"status": None, "converged": False, "verified": False,
                          "note": f"NOT polished: the closed-form solve ended {result.status}"}
        return
    say(f"{problem.name}: polishing on the exact Eqs. 1-2 in time ({result.alpha.size} segments)")
    exact, _ = exact_refinement.polish(problem, result)
    say(f"{problem.name}: polish {exact.status} after {exact.iterations} iterations; "
        "verifying on CVODES")
    exact_check = verify(problem, exact, samples)
    data["objective_closed_form"] = result.objective
    data["objective_exact"] = exact.objective
    data["tof_days_exact"] = units.time_to_days(float(np.sum(exact.durations)))
    data["polish"] = _polish_data(problem, exact, exact_check)
    data["trajectory"]["polished"] = (_trajectory(exact_check.cvodes)
                                      if exact_check.error is None else None)
