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
