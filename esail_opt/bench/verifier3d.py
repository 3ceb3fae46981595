"""``esail-opt-bench verifier3d``: the 3-D verifier's accuracy, its flights of polished
schedules against a Taylor integration in quadruple precision.

The verifier (``optimisation.verify.verify3d``) judges a 3-D schedule by a CVODES flight in
the turning plane at 3e-16 and states as its error the gap to a second such flight at 1e-15
plus the gap to a Cartesian flight at 3e-16.  This bench flies each case's polished schedule
those three ways and on the Cartesian equations at 1e-15 (the error the Cartesian pair alone
would state), and reports how far each ends from the truth and whether the stated error
covers the judged flight's.  The truth is heyoka (the ``bench`` extra) in quadruple
precision (:func:`.taylor.cartesian_system`); without heyoka there are no true errors.
"""

import dataclasses
import sys
from pathlib import Path

import numpy as np

import esail_opt as eo
from esail_opt.app.outputs import write_json
from esail_opt.bench import taylor
from esail_opt.optimisation import multistart, pipeline
from esail_opt.optimisation.problem_file import shipped_problem
from esail_opt.physics import constants as units
from esail_opt.physics.thrust import radial_transverse_normal
from esail_opt.propagation.simulate import CHECK_TOLERANCE, VERIFY_TOLERANCE, simulate3d

#: The flights measured: (key, form, CVODES tolerance).  The first is the judged one.
FLIGHTS = (("turning_3e-16", "turning", VERIFY_TOLERANCE),
           ("turning_1e-15", "turning", CHECK_TOLERANCE),
           ("cartesian_3e-16", "cartesian", VERIFY_TOLERANCE),
           ("cartesian_1e-15", "cartesian", CHECK_TOLERANCE))
#: heyoka's tolerance in quadruple precision.
TRUTH_TOLERANCE = 1e-30


def cases():
    """(label, problem) of every case: the shipped 3-D rendezvous problems, and
    ``earth_mars_2035`` moved to a 941-day transfer, one the Cartesian pair could not
    judge to 1 m."""
    long = shipped_problem("earth_mars_2035")
    long = dataclasses.replace(
        long, name="earth_mars_941d", departure=eo.BodyDeparture(body="earth", date="2033-03-01"),
        sail=eo.Sail(ac_mm_s2=1.5), segments=eo.Segments(count=30, sub_arcs=3, equal=False))
    return [(name, shipped_problem(name)) for name in ("earth_mars_min_ac", "earth_venus_min_ac",
                                                       "earth_mars_2035")] + [(long.name, long)]


def schedule(problem, result):
    """The departure state, a_c per segment (throttle included), pitch, clock and
    durations of ``result``, canonical."""
    return (problem.start_state(result), result.accelerations(problem),
            np.asarray(result.alpha, float),
            np.asarray(result.delta, float), np.asarray(result.durations, float))


def has_quadruple():
    """Whether heyoka imports with its real128 type: some of its builds lack it."""
    if not taylor.available():
        return False
    import heyoka as hy

    return hasattr(hy, "real128")


def truth(y0, acs, alphas, deltas, durations, coefficients):
    """The schedule's final Cartesian state by heyoka in quadruple precision, or None
    without heyoka or without its quadruple precision (:func:`has_quadruple`)."""
    if not has_quadruple():
        return None
    import heyoka as hy

    real = hy.real128
    ta = hy.taylor_adaptive(taylor.cartesian_system(), [real(float(v)) for v in y0],
                            fp_type=real, tol=real(TRUTH_TOLERANCE), pars=[real(0.0)] * 3)
    for ac, alpha, delta, duration in zip(acs, alphas, deltas, durations):
        R, T, N = (float(v) for v in radial_transverse_normal(alpha, delta, coefficients))
        ta.pars[:] = [real(ac * R), real(ac * T), real(ac * N)]
        ta.propagate_for(real(float(duration)))
    return np.array([float(v) for v in ta.state])


def measure(problem, result):
    """Every flight of :data:`FLIGHTS`' final-position error against the truth (m, None
    without it), the verifier's stated error (m) and whether it covers the judged
    flight's true error, and the error the Cartesian pair alone would state (m)."""
    y0, acs, alphas, deltas, durations = schedule(problem, result)
    coeff = problem.sail.coefficients
    ends = {key: np.asarray(simulate3d(y0, alphas, deltas, durations, acs, form=form, tol=tol,
                                       coefficients=coeff))[:3, -1]
            for key, form, tol in FLIGHTS}
    exact = truth(y0, acs, alphas, deltas, durations, coeff)

    def metres(a, b):
        return float(units.length_to_km(np.linalg.norm(a - b)) * 1e3)

    judged = ends["turning_3e-16"]
    stated = metres(judged, ends["turning_1e-15"]) + metres(judged, ends["cartesian_3e-16"])
    errors = {key: None if exact is None else metres(end, exact[:3]) for key, end in ends.items()}
    return {"error_m": errors, "verifier_error_m": stated,
            "covered": None if exact is None else stated >= errors["turning_3e-16"],
            "cartesian_pair_error_m": metres(ends["cartesian_3e-16"], ends["cartesian_1e-15"])}


def run(out, repeats=1):
    """Solve and polish every case, and every other optimum of the last case's search
    (``multistart.search``: turn counts whose flights dip to a third of an au, where both
    forms are hardest to fly), measure each polished flight (:func:`measure`), print a
    table and write ``verifier3d.json``; returns its path.  Nothing is timed: ``repeats``
    is not used."""
    rows = []
    for label, problem in cases():
        print(f"bench verifier3d: {label}: solving with --polish ...", file=sys.stderr, flush=True)
        rows.append(_row(label, problem, pipeline.solve(problem, polish=True)))
    print(f"bench verifier3d: {label}: searching its turn counts ...", file=sys.stderr,
          flush=True)
    for k, found in enumerate(multistart.search(problem)[0], 1):
        rows.append(_row(f"{label} search #{k}", problem,
                         pipeline.run_from_optimum(problem, found.result, polish=True)))
    _print(rows)
    path = Path(out) / "verifier3d.json"
    write_json(path, {"truth": f"heyoka real128, tolerance {TRUTH_TOLERANCE:g}"
                      if has_quadruple() else None, "rows": rows})
    return path


def _row(label, problem, run_):
    """The row of a run: its polished flight measured, or its closed-form one."""
    polished = run_.polish is not None and run_.polish.result is not None
    result = run_.polish.result if polished else run_.result
    return {"case": label, "tof_days": units.time_to_days(float(np.sum(result.durations))),
            "polished": polished, "polish_verified": bool(polished and run_.polish.verified),
            **measure(problem, result)}


def _print(rows):
    keys = [key for key, _, _ in FLIGHTS]
    print("bench verifier3d: final-position error against the truth, m")
    print(f"  {'case':26s} {'days':>6s} " + " ".join(f"{k:>16s}" for k in keys)
          + f" {'stated':>8s} {'old':>8s}")
    for row in rows:
        errors = " ".join("               -" if row["error_m"][k] is None
                          else f"{row['error_m'][k]:16.4f}" for k in keys)
        print(f"  {row['case']:26s} {row['tof_days']:6.1f} {errors} "
              f"{row['verifier_error_m']:8.4f} {row['cartesian_pair_error_m']:8.4f}")
