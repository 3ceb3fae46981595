"""``esail-opt-bench propagate``: the paper's 10-year orbit raising (Sec. 3) propagated
by the closed form, by CVODES and by Ref. [10]'s model, timed in one run; the same
ten years as a work-precision race, each method's call time against its final error;
and a batch of such raisings, the closed form (compiled across cases) against CVODES
and heyoka (:mod:`.taylor`; skipped, and said so, without it), each at the closed
form's error and at 1e-12."""

import math
from pathlib import Path

from esail_opt.bench.timing import median_seconds, print_table

#: The case: a_c (mm/s^2), fixed pitch (deg), years from the circular 1 au orbit, arcs.
AC_MM_S2, ALPHA_DEG, YEARS, ARCS = 0.1, 45.0, 10.0, 20
#: The race's settings: arcs of the closed form (equal durations over the ten years),
#: CVODES's tolerances on the case's 20 arcs, and the final errors read off the curves.
RACE_ARCS = (20, 40, 80, 160, 320)
RACE_TOLERANCES = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-10, 1e-12)
RACE_ERRORS_KM = {"1e6": 1e6, "1e5": 1e5, "1e4": 1e4}
#: The batch: pitch (deg) and a_c (mm/s^2) grids as (start, stop, count), and the cases
#: CVODES is timed on (evenly spread; its time per case is scaled to all cases).
BATCH_GRID = {"alpha_deg": (-40.0, 80.0, 41), "ac_mm_s2": (0.05, 0.2, 25)}
BATCH_CVODES_CASES = 100
#: heyoka's tolerances on the batch, loosest first; and its batch sizes as multiples of
#: its SIMD width (the fastest counts: more lanes share each call from Python, fewer
#: fill the vector registers).
HEYOKA_TOLERANCES = (1e-3, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 1e-7, 1e-8, 1e-10, 1e-12)
HEYOKA_LANES = (1, 2, 4)


def _functions():
    """Name -> (CasADi Function, arguments), keyed as the timings are: ``closed_form``,
    ``closed_form_theta_lengths``, ``cvodes``, ``cvodes_single_call`` and ``ref10``
    (:func:`run`)."""
    import numpy as np

    from esail_opt.physics import constants as units
    from esail_opt.physics.thrust import radial_transverse
    from esail_opt.propagation.arcs import FIRST_ORDER
    from esail_opt.propagation.rectified import rectified_function
    from esail_opt.propagation.radial_balance import radial_balance_function
    from esail_opt.propagation.simulate import schedule_function, segment_integrator

    ac, alpha = units.accel_from_mm_s2(AC_MM_S2), math.radians(ALPHA_DEG)
    horizon = units.time_from_years(YEARS)
    args = _schedule(ARCS)
    x0, row = args[0], np.ones((1, ARCS))
    closed = rectified_function(ARCS, length_in="time", model=FIRST_ORDER)
    # The arcs' angles come from the timed run, so the angle form flies the same 20 arcs.
    angles = np.diff(np.r_[0.0, np.array(closed(*args)[0])[1]])[None, :]
    R, T = (float(v) for v in radial_transverse(alpha))
    times = horizon / ARCS * np.arange(1, ARCS + 1)[None, :]
    return {
        "closed_form": (closed, args),
        "closed_form_theta_lengths": (rectified_function(ARCS, model=FIRST_ORDER),
                                      (x0, ac * row, alpha * row, angles)),
        "cvodes": (schedule_function(ARCS, 1, "time"), args),
        # The attitude never changes, so CVODES can fly all 10 years without restarts.
        "cvodes_single_call": (segment_integrator(ARCS, "time"), (x0, ac, alpha, horizon)),
        "ref10": (radial_balance_function(ARCS), (times, 1.0, ac, R, T, 0.0)),
    }


def _position_km(a, b):
    """Distance between the planar positions (r, theta) of two states, km."""
    from esail_opt.physics import constants as units

    # Not the law of cosines: it rounds to the root of a negative number at metres apart.
    gap = math.hypot(a[0] * math.cos(a[1]) - b[0] * math.cos(b[1]),
                     a[0] * math.sin(a[1]) - b[0] * math.sin(b[1]))
    return units.length_to_km(gap)


def _accuracy(states):
    """Errors against CVODES: final position (km), its radial (km) and angular (deg)
    parts, the largest radial gap over the 20 states, and how far each alternative form
    strays from the form it stands in for."""
    import numpy as np

    from esail_opt.physics import constants as units

    truth = states["cvodes"][:, -1]
    out = {}
    for key in ("closed_form", "ref10"):
        final = states[key][:, -1]
        out[f"{key}_final_err_km"] = _position_km(final, truth)
        out[f"{key}_final_err_r_km"] = units.length_to_km(abs(final[0] - truth[0]))
        out[f"{key}_final_err_theta_deg"] = math.degrees(abs(final[1] - truth[1]))

    def max_gap_km(row, a, b):
        return units.length_to_km(float(np.max(np.abs(states[a][row] - states[b][row]))))

    out["closed_form_max_err_r_km"] = max_gap_km(0, "closed_form", "cvodes")
    out["closed_form_theta_lengths_max_diff_km"] = max_gap_km(
        0, "closed_form_theta_lengths", "closed_form")
    out["cvodes_single_call_max_diff_km"] = max_gap_km(0, "cvodes_single_call", "cvodes")
    return out


def _schedule(arcs):
    """The case's arguments for ``arcs`` equal arcs over the ten years, in time."""
    import numpy as np

    from esail_opt.physics import constants as units

    row = np.ones((1, arcs))
    return (np.array([1.0, 0.0, 0.0, 1.0, 0.0]), units.accel_from_mm_s2(AC_MM_S2) * row,
            math.radians(ALPHA_DEG) * row, units.time_from_years(YEARS) / arcs * row)


def race(repeats):
    """Call time against final error for the ten years, each method at several settings:
    ``closed_form`` (the NLP's second-order arcs, ending on the exact angular momentum),
    ``closed_form_richardson`` (first-order arcs, Richardson-extrapolated, likewise) and
    ``closed_form_plain`` (the paper's rectification, ``arcs.FIRST_ORDER``), in time at
    :data:`RACE_ARCS` arcs; ``cvodes`` on the case's 20 arcs at :data:`RACE_TOLERANCES`.

    The error is the final position's distance (km) from CVODES at
    ``simulate.VERIFY_TOLERANCE``.  Returns ``points`` ({"method", "setting", "seconds",
    "miss_km"}), ``at_error_km`` (:func:`_race_at_error`), ``call_floor_seconds``
    (:func:`_call_floor_seconds`), ``ratio_cvodes_over_call_floor`` (CVODES at 1e-12) and
    ``reference_final_state`` [r, theta, v_r, v_theta, t].
    """
    import numpy as np

    from esail_opt.propagation.simulate import VERIFY_TOLERANCE, schedule_function

    truth = np.array(schedule_function(ARCS, 1, "time", tol=VERIFY_TOLERANCE)(
        *_schedule(ARCS)))[:, -1]
    points = [_race_point(*entry, truth, repeats) for entry in _race_entries()]
    floor_seconds = _call_floor_seconds(repeats)
    cvodes_tight = next(p["seconds"] for p in points
                        if p["method"] == "cvodes" and p["setting"] == "tol 1e-12")
    return {"points": points, "at_error_km": _race_at_error(points),
            "call_floor_seconds": floor_seconds,
            "ratio_cvodes_over_call_floor": cvodes_tight / floor_seconds,
            "reference_tolerance": VERIFY_TOLERANCE, "reference_final_state": truth[:5].tolist()}


def _race_entries():
    """The race's (method, setting, Function, arguments), as :func:`race` lists them."""
    from esail_opt.propagation.arcs import FIRST_ORDER, PANEL_NODES, ArcModel
    from esail_opt.propagation.rectified import rectified_function
    from esail_opt.propagation.simulate import schedule_function

    models = {"closed_form": ArcModel(sub_arcs=1, nodes=PANEL_NODES),
              "closed_form_richardson": ArcModel(order=1, extrapolate=True, sub_arcs=1,
                                                 nodes=PANEL_NODES),
              "closed_form_plain": FIRST_ORDER}
    entries = [(method, f"{n} arcs", rectified_function(n, length_in="time", model=model),
                _schedule(n)) for method, model in models.items() for n in RACE_ARCS]
    entries += [("cvodes", f"tol {tol:g}", schedule_function(ARCS, 1, "time", tol=tol),
                 _schedule(ARCS)) for tol in RACE_TOLERANCES]
    return entries


def _race_point(method, setting, fun, args, truth, repeats):
    """One point of the race: ``fun(*args)`` timed, and its final error against ``truth`` (km)."""
    import numpy as np

    value = fun(*args)
    final = np.array(value[0] if isinstance(value, (tuple, list)) else value)[:, -1]
    return {"method": method, "setting": setting,
            "seconds": median_seconds(lambda: fun(*args), repeats),
            "miss_km": _position_km(final, truth)}


def _race_at_error(points):
    """Per final error of :data:`RACE_ERRORS_KM`, each method's seconds read on its curve
    (``precision.seconds_at_miss``) and CVODES's over the closed form's."""
    from esail_opt.bench.precision import seconds_at_miss

    at_error = {}
    for key, error in RACE_ERRORS_KM.items():
        row = {f"{name}_seconds": seconds_at_miss(
            [(p["seconds"], p["miss_km"]) for p in points if p["method"] == name], error)
            for name in ("closed_form", "closed_form_richardson", "closed_form_plain",
                         "cvodes")}
        base, other = row["closed_form_seconds"], row["cvodes_seconds"]
        row["ratio_cvodes_over_closed_form"] = (None if base is None or other is None
                                                else other / base)
        at_error[key] = row
    return at_error


def _call_floor_seconds(repeats):
    """One call of a Function that only doubles its input, with the case's arguments:
    the floor no Function called from Python undercuts."""
    import casadi as ca

    args = _schedule(ARCS)
    x, acs = ca.SX.sym("x", 5), ca.SX.sym("ac", 1, ARCS)
    floor = ca.Function("floor", [x, acs, ca.SX.sym("alpha", 1, ARCS),
                                  ca.SX.sym("length", 1, ARCS)], [2 * x])
    return median_seconds(lambda: floor(*args), max(repeats, 100))


def _batch_cases(grid):
    """The batch's pitch (rad) and a_c (canonical) per case, pitch varying slowest."""
    import numpy as np

    from esail_opt.physics import constants as units

    alpha, ac = np.meshgrid(np.radians(np.linspace(*grid["alpha_deg"])),
                            units.accel_from_mm_s2(np.linspace(*grid["ac_mm_s2"])),
                            indexing="ij")
    return alpha.ravel(), ac.ravel()


def cpu_seconds(fn, repeats):
    """Median CPU seconds of this process over ``repeats`` calls of ``fn()`` after one warm-up
    call: a one-thread method's own work, without the waits for a core a wall clock counts."""
    import time

    return median_seconds(fn, repeats, clock=time.process_time)


def _heyoka_point(tol, sizes, schedule, truth, repeats):
    """heyoka's point at tolerance ``tol``: timed at each batch size of ``sizes``, the
    fastest counting, and its final errors against ``truth`` (:func:`heyoka_batch`)."""
    import time

    import numpy as np

    from esail_opt.bench import taylor

    cases, by_size = schedule[1].shape[0], {}
    for size in sizes:
        start = time.perf_counter()
        ta = taylor.integrator(tol, size)
        built = time.perf_counter() - start
        ready = taylor.prepare(size, *schedule)
        by_size[size] = {"compile_seconds": built, "seconds_per_case": cpu_seconds(
            lambda ta=ta, ready=ready: taylor.fly_prepared(ta, ready), repeats) / cases}
    best = min(by_size, key=lambda size: by_size[size]["seconds_per_case"])
    ends = taylor.fly(taylor.integrator(tol, best), *schedule)[:, :, -1]
    errors = [_position_km(ends[m], truth[:, m]) for m in range(cases)]
    return {"tolerance": tol, "batch_size": best,
            "seconds_per_case": by_size[best]["seconds_per_case"],
            "median_final_error_km": float(np.median(errors)),
            "max_final_error_km": float(np.max(errors)), "by_batch_size": by_size}


#: Rounds of :func:`paired_ratios`.
PAIRED_ROUNDS = 31


def paired_ratios(closed, others, rounds):
    """Each of ``others`` (name -> call) over the closed form's call ``closed``, timed in
    turn ``rounds`` times (CPU seconds, the order rotating each round), the ratio taken
    round by round: on a shared machine a method timed minutes after another meets other
    neighbours, while one round's calls, fractions of a second apart, meet the same ones.  Returns
    per name the median ratio (above 1: the closed form is faster), the smallest and
    largest, and the rounds."""
    import statistics
    import time

    names = list(others)
    calls = [("closed form", closed)] + [(name, others[name]) for name in names]
    for _, call in calls:
        call()
    ratios = {name: [] for name in names}
    for k in range(rounds):
        seconds = {}
        turn = calls[k % len(calls):] + calls[:k % len(calls)]
        for name, call in turn:
            start = time.process_time()
            call()
            seconds[name] = time.process_time() - start
        for name in names:
            ratios[name].append(seconds[name] / seconds["closed form"])
    return {name: {"median": statistics.median(r), "smallest": min(r), "largest": max(r),
                   "rounds": rounds} for name, r in ratios.items()}


def heyoka_batch(repeats, schedule, truth, target_km, closed=None):
    """The batch flown by heyoka (:mod:`.taylor`) at each of :data:`HEYOKA_TOLERANCES`, or
    ``{"skipped": reason}`` when heyoka does not import.  ``schedule`` is ``taylor.fly``'s
    (x0[4], acs, alphas, durations), the last three (M, N); ``truth`` (5, M) each case's
    reference final state; ``target_km`` the closed form's median final error; ``closed``
    the closed form's flight of the same batch, a call without arguments.

    Returns ``points`` (:func:`_heyoka_point`), ``equal_error`` (the loosest point whose
    median final error is at most ``target_km``, or None), ``tight`` (1e-12),
    ``python_loop_seconds_per_case`` (the Python loop around heyoka's calls) and, with
    ``closed``, ``paired`` (:func:`paired_ratios` of those two points).  Times are median
    CPU seconds of ``taylor.fly_prepared`` on lanes prepared beforehand.
    """
    from esail_opt.bench import taylor

    if not taylor.available():
        return {"skipped": "heyoka is not installed (pip install 'esail_opt[bench]')"}
    import heyoka

    cases = schedule[1].shape[0]
    simd = heyoka.recommended_simd_size()
    points = [_heyoka_point(tol, [lanes * simd for lanes in HEYOKA_LANES], schedule, truth,
                            repeats) for tol in HEYOKA_TOLERANCES]
    equal = next((p for p in points if p["median_final_error_km"] <= target_km), None)
    floor_size = equal["batch_size"] if equal else simd
    ready = taylor.prepare(floor_size, *schedule)
    floor = cpu_seconds(lambda: taylor.fly_prepared(taylor.integrator(1e-12, floor_size),
                                                    ready, steps=False), repeats) / cases
    tight = next(p for p in points if p["tolerance"] == 1e-12)
    paired = None
    if closed is not None:
        flights = {}
        for key, point in (("equal_error", equal), ("tight", tight)):
            if point is not None:
                ta = taylor.integrator(point["tolerance"], point["batch_size"])
                ready = taylor.prepare(point["batch_size"], *schedule)
                flights[key] = lambda ta=ta, ready=ready: taylor.fly_prepared(ta, ready)
        paired = paired_ratios(closed, flights, max(PAIRED_ROUNDS, repeats))
    return {"points": points, "equal_error": equal, "python_loop_seconds_per_case": floor,
            "python_loop_batch_size": floor_size, "tight": tight, "paired": paired,
            "simd_size": simd, "heyoka_version": heyoka.__version__,
            "how": "Eqs. 1-2 as dynamics.rhs, replayed on heyoka expressions; a_c R and "
                   "a_c T runtime parameters set per arc; taylor_adaptive_batch, "
                   "propagate_until each arc's end, one thread"}


def _closed_form_batch(repeats, stacked, native):
    """The batch's closed form compiled across cases and, for comparison, by CasADi one
    case at a time (:func:`batch`): seconds, compile seconds, states and q3."""
    import time

    import casadi as ca
    import numpy as np

    from esail_opt.propagation.arcs import PANEL_NODES, ArcModel
    from esail_opt.propagation.batch import batch_function

    cases = stacked[0].shape[1]
    model = ArcModel(sub_arcs=1, nodes=PANEL_NODES)
    start = time.perf_counter()
    closed = batch_function(ARCS, cases, length_in="time", model=model, jit=native)
    compile_seconds = time.perf_counter() - start
    given = [ca.DM(a) for a in stacked]
    seconds = cpu_seconds(lambda: closed(*given), repeats)
    xs, q3 = (np.array(v) for v in closed(*given))
    # CasADi's compile, one case at a time: what the compile across cases gains, and how
    # far its numbers move (libmvec's elementary functions).
    start = time.perf_counter()
    scalar = batch_function(ARCS, cases, length_in="time", model=model, jit=native,
                            across_cases=False)
    scalar_compile = time.perf_counter() - start
    scalar_seconds = cpu_seconds(lambda: scalar(*given), repeats)
    scalar_xs = np.array(scalar(*given)[0])
    moved = np.max(np.abs(xs - scalar_xs) / np.max(np.abs(scalar_xs), axis=1, keepdims=True))
    return {"seconds": seconds, "compile_seconds": compile_seconds, "xs": xs, "q3": q3,
            "call": lambda: closed(*given), "one_case_at_a_time": {
                "seconds": scalar_seconds, "compile_seconds": scalar_compile,
                "largest_difference_over_row_size": float(moved),
                "how": "the same mapped Function compiled by CasADi's own JIT, as before "
                       "the compile across cases"}}


def _cvodes_points(repeats, stacked, timed, truth):
    """CVODES on the ``timed`` cases of the batch at each of the race's tolerances, per
    case and as one mapped call (the faster counts), with the median final error."""
    import casadi as ca
    import numpy as np

    from esail_opt.propagation.simulate import schedule_function

    points = []
    per_case = [[ca.DM(stacked[0][:, m])] + [ca.DM(a[:, m * ARCS:(m + 1) * ARCS])
                                            for a in stacked[1:]] for m in timed]
    for tol in RACE_TOLERANCES:
        fun = schedule_function(ARCS, 1, "time", tol=tol)
        loop = cpu_seconds(lambda f=fun: [f(*args) for args in per_case], repeats)
        mapped_args = (stacked[0][:, timed],
                       *(np.concatenate([a[:, m * ARCS:(m + 1) * ARCS] for m in timed], axis=1)
                         for a in stacked[1:]))
        mapped = fun.map(timed.size)
        mapped_given = [ca.DM(a) for a in mapped_args]
        together = cpu_seconds(lambda f=mapped, a=mapped_given: f(*a), repeats)
        ends = np.array(mapped(*mapped_given))[:, ARCS - 1::ARCS]
        miss = [_position_km(ends[:, k], truth[:, m]) for k, m in enumerate(timed)]
        points.append({"tolerance": tol, "seconds_per_case": min(loop, together) / timed.size,
                       "per_case_calls_seconds": loop, "mapped_call_seconds": together,
                       "median_final_error_km": float(np.median(miss))})
    return points


def batch(repeats, grid=None, cvodes_cases=BATCH_CVODES_CASES, native=True):
    """Many cases of the ten years at ARCS arcs, pitch and a_c on ``grid`` (default
    :data:`BATCH_GRID`): the race's closed form in one call compiled across cases
    (``propagation.batch.batch_function``; ``native`` False keeps it on CasADi's virtual
    machine) and, for comparison, compiled by CasADi one case at a time; CVODES on
    ``cvodes_cases`` evenly spread cases (:func:`_cvodes_points`); heyoka
    (:func:`heyoka_batch`).  Times are median CPU seconds (:func:`cpu_seconds`) from
    arguments already in each method's form.  Returns the ``batch`` block
    (:func:`_batch_block`) with its ``per_case`` table.
    """
    import numpy as np

    grid = BATCH_GRID if grid is None else grid
    alphas, acs = _batch_cases(grid)
    cases = alphas.size
    x0, _, _, lengths = _schedule(ARCS)
    stacked = (np.tile(x0[:, None], (1, cases)), np.repeat(acs, ARCS)[None, :],
               np.repeat(alphas, ARCS)[None, :], np.tile(lengths, (1, cases)))
    closed = _closed_form_batch(repeats, stacked, native)
    truth, errors = _batch_errors(closed["xs"], stacked)
    timed = np.unique(np.linspace(0, cases - 1, min(cvodes_cases, cases)).round().astype(int))
    points = _cvodes_points(repeats, stacked, timed, truth)
    heyoka = heyoka_batch(repeats, (x0[:4], np.repeat(acs[:, None], ARCS, 1),
                                    np.repeat(alphas[:, None], ARCS, 1),
                                    np.tile(lengths, (cases, 1))),
                          truth, float(np.median(errors)), closed=closed["call"])
    block = _batch_block(closed, errors, timed, points, heyoka, native, grid)
    block["per_case"] = per_case_table(block)
    return block


def _batch_errors(xs, stacked):
    """The batch's reference final states (CVODES at ``simulate.VERIFY_TOLERANCE``, one
    mapped call, 5 x cases) and each case's final error of the states ``xs`` (km)."""
    import numpy as np

    from esail_opt.propagation.simulate import VERIFY_TOLERANCE, schedule_function

    cases = stacked[0].shape[1]
    finals = xs[:, ARCS - 1::ARCS]
    truth = np.array(schedule_function(ARCS, 1, "time", tol=VERIFY_TOLERANCE).map(cases)(
        *stacked))[:, ARCS - 1::ARCS]
    return truth, np.array([_position_km(finals[:, m], truth[:, m]) for m in range(cases)])


def _batch_block(closed, errors, timed, points, heyoka, native, grid):
    """The ``batch`` block of :func:`batch` but its ``per_case`` table: the closed form's
    time and errors; CVODES's seconds per case times the cases at 1e-12
    (``cvodes_seconds_tight``) and read on its curve at the closed form's median error
    over the ``timed`` cases (``cvodes_seconds_equal_error``); heyoka's block."""
    import numpy as np

    from esail_opt.bench.precision import seconds_at_miss

    cases = errors.size
    target = float(np.median(errors[timed]))
    equal = seconds_at_miss([(p["seconds_per_case"], p["median_final_error_km"])
                             for p in points], target)
    tight = next(p for p in points if p["tolerance"] == 1e-12)
    equal_total = None if equal is None else equal * cases
    return {
        "cases": int(cases), "arcs": ARCS, "closed_form_seconds": closed["seconds"],
        "cvodes_seconds_equal_error": equal_total,
        "cvodes_seconds_tight": tight["seconds_per_case"] * cases,
        "ratio_equal_error": None if equal is None else equal_total / closed["seconds"],
        "ratio_tight": tight["seconds_per_case"] * cases / closed["seconds"],
        "median_final_error_km": float(np.median(errors)),
        "max_final_error_km": float(np.max(errors)),
        "median_final_error_km_timed_cases": target,
        "cvodes_median_final_error_km_tight": tight["median_final_error_km"],
        "smallest_q3": float(np.min(closed["q3"])),
        "cvodes_cases_timed": int(timed.size),
        "cvodes_points": points,
        "compile_seconds": closed["compile_seconds"], "compiled": native,
        "closed_form_one_case_at_a_time": closed["one_case_at_a_time"],
        "grid": {key: list(value) for key, value in grid.items()},
        "heyoka": heyoka,
        "note": "times are median CPU seconds of this process, each method on one thread; "
                "closed form: every case in one compiled mapped call; CVODES: seconds per "
                "case on cvodes_cases_timed evenly spread cases, the faster of per-case "
                "calls and one mapped call, times cases; heyoka: every case, its batch mode "
                "arc by arc; final error: distance of the final position from CVODES at "
                "the reference tolerance",
    }


def per_case_table(block):
    """The batch's methods side by side: seconds per case, median final error and time over
    the closed form's (above 1: the closed form is faster).  Equal error is read as in
    :func:`_batch_block` and :func:`heyoka_batch`; rows skipped or never reaching it are left out.
    """
    cases, closed = block["cases"], block["closed_form_seconds"] / block["cases"]
    rows = [("closed form", closed, block["median_final_error_km"], None),
            ("closed form, one case at a time",
             block["closed_form_one_case_at_a_time"]["seconds"] / cases,
             block["median_final_error_km"], None)]
    taylor = block["heyoka"]
    for key, label in (("equal_error", "heyoka at equal error"), ("tight", "heyoka at 1e-12")):
        point = taylor.get(key)
        if point is not None:
            rows.append((label, point["seconds_per_case"], point["median_final_error_km"],
                         point["tolerance"]))
    if block["cvodes_seconds_equal_error"] is not None:
        rows.append(("CVODES at equal error", block["cvodes_seconds_equal_error"] / cases,
                     block["median_final_error_km_timed_cases"], None))
    rows.append(("CVODES at 1e-12", block["cvodes_seconds_tight"] / cases,
                 block["cvodes_median_final_error_km_tight"], 1e-12))
    return [{"method": name, "seconds_per_case": seconds, "median_final_error_km": error,
             "tolerance": tol, "ratio_over_closed_form": seconds / closed}
            for name, seconds, error, tol in rows]


def race_figure(curves, block=None):
    """The race as a log-log work-precision diagram, on a new Figure; with the
    ``batch`` block, the batch's methods beside it (:func:`batch_points`)."""
    from matplotlib.figure import Figure

    from esail_opt.bench.precision import draw_precision

    axes = Figure(figsize=(6.0 if block is None else 12.0, 4.8)).subplots(
        1, 1 if block is None else 2, squeeze=False)[0]
    draw_precision({"problem": f"{YEARS:g}-year raising, alpha {ALPHA_DEG:g} deg",
                    "ac_mm_s2": AC_MM_S2, "points": curves["points"]}, ax=axes[0],
                   xlabel="time of one propagation call [s]",
                   ylabel=("final position error [km] (vs CVODES at "
                           f"{curves['reference_tolerance']:g})"))
    if block is not None:
        ax = draw_precision({"problem": "batch", "ac_mm_s2": AC_MM_S2,
                             "points": batch_points(block)}, ax=axes[1],
                            xlabel="CPU time per case, one thread [s]",
                            ylabel="median final position error [km]")
        grid = block["grid"]
        ax.set_title(f"{block['cases']} raisings, pitch {grid['alpha_deg'][0]:g} to "
                     f"{grid['alpha_deg'][1]:g} deg, a_c {grid['ac_mm_s2'][0]:g} to "
                     f"{grid['ac_mm_s2'][1]:g} mm/s^2", fontsize="medium")
    axes[0].figure.tight_layout()
    return axes[0].figure


def batch_points(block):
    """The batch's (seconds per case, median final error) points, each method's
    settings a curve: the closed form both ways, CVODES and heyoka per tolerance."""
    closed = block["per_case"][:2]
    points = [{"method": name, "setting": "", "seconds": row["seconds_per_case"],
               "miss_km": row["median_final_error_km"]}
              for name, row in zip(("closed_form", "closed_form_one_case_at_a_time"), closed)]
    points += [{"method": "cvodes", "setting": f"tol {p['tolerance']:g}",
                "seconds": p["seconds_per_case"], "miss_km": p["median_final_error_km"]}
               for p in block["cvodes_points"]]
    points += [{"method": "heyoka", "setting": f"tol {p['tolerance']:g}",
                "seconds": p["seconds_per_case"], "miss_km": p["median_final_error_km"]}
               for p in block["heyoka"].get("points", [])]
    return points


def _print_race(curves):
    rows = []
    for key, row in curves["at_error_km"].items():
        for name, value in row.items():
            unit = "" if name.startswith("ratio") else "s"
            rows.append((f"{key} km: {name}", "never" if value is None else float(value),
                         "" if value is None else unit))
    rows += [("one call of a Function that does nothing", 1e6 * curves["call_floor_seconds"],
              "us"),
             ("ratio CVODES 1e-12 / that call", curves["ratio_cvodes_over_call_floor"], "")]
    print_table("bench propagate: work-precision, 10 years (call time at equal final error)",
                rows)


def _print(data, repeats):
    print_table("bench propagate: 10-year orbit raising, 20 arcs (19 rectifications), "
                f"median of {repeats}", [
                    ("closed form (rectified, one CasADi call)", 1e6 * data["closed_form_seconds"], "us"),
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


def _print_batch(block):
    rows = []
    for row in block["per_case"]:
        rows += [(f"{row['method']}: time per case", 1e6 * row["seconds_per_case"], "us"),
                 (f"{row['method']}: median final error", row["median_final_error_km"], "km"),
                 (f"{row['method']}: time over the closed form's",
                  row["ratio_over_closed_form"], "")]
    print_table(f"bench propagate: batch of {block['cases']} cases, {block['arcs']} arcs, "
                f"CVODES timed on {block['cvodes_cases_timed']} (CPU time, one thread)", rows)
    taylor = block["heyoka"]
    if "skipped" in taylor:
        print(f"  heyoka skipped: {taylor['skipped']}")
        return
    print(f"  of heyoka's time per case, the Python loop around its calls: "
          f"{1e6 * taylor['python_loop_seconds_per_case']:.3g} us")
    if taylor["equal_error"] is not None:
        print(f"  heyoka at equal error: tolerance {taylor['equal_error']['tolerance']:g}, "
              f"batch size {taylor['equal_error']['batch_size']}")
    else:
        print("  heyoka reached the closed form's error at none of its tolerances")
    for key, label in (("equal_error", "at equal error"), ("tight", "at 1e-12")):
        pair = (taylor.get("paired") or {}).get(key)
        if pair is not None:
            print(f"  heyoka {label} over the closed form, timed in turn {pair['rounds']} "
                  f"times: median {pair['median']:.3g} ({pair['smallest']:.3g} to "
                  f"{pair['largest']:.3g})")


def run(out, repeats, grid=None):
    """The 10-year orbit raising three ways, timed in one run; writes ``propagate.json``.

    The rectified closed form (20 six-month arcs on its own clock, one CasADi call returning
    the 20 states at the rectification points), CVODES at 1e-12 on Eqs. 1-2 (the same
    schedule and states) and Ref. [10]'s model at the same 20 times; for context, the closed
    form given the arcs' angles (as the optimiser uses it) and CVODES in one call with 20
    output times (no restarts).  Each time is the median of ``repeats`` calls from arguments
    already in the Function's form; accuracy is :func:`_accuracy`'s.  Then :func:`race`
    (``race``, ``propagate.png``) and :func:`batch` (``batch``).  Returns the path written.
    """
    import numpy as np

    from esail_opt.app.outputs import save_figure, write_json

    functions = _functions()
    seconds = {name: median_seconds(lambda f=f, a=a: f(*a), repeats)
               for name, (f, a) in functions.items()}
    states = {}
    for name, (f, a) in functions.items():
        value = f(*a)
        states[name] = np.array(value[0] if isinstance(value, (tuple, list)) else value)
    data = {
        "case": {"ac_mm_s2": AC_MM_S2, "alpha_deg": ALPHA_DEG, "r0_au": 1.0, "years": YEARS,
                 "arcs": ARCS, "rectifications": ARCS - 1, "states_compared": ARCS,
                 "cvodes_tolerance": 1e-12},
        "repeats": repeats,
        **{f"{name}_seconds": value for name, value in seconds.items()},
    }
    for name in ("closed_form", "ref10", "closed_form_theta_lengths"):
        data[f"ratio_cvodes_over_{name}"] = seconds["cvodes"] / seconds[name]
    data["ratio_cvodes_single_call_over_closed_form"] = (seconds["cvodes_single_call"]
                                                         / seconds["closed_form"])
    data.update(_accuracy(states))
    data["note"] = ("medians of one Function call each, same run and machine; errors against "
                    "CVODES at the 20 rectification times; *_final_err_km is the distance "
                    "between final positions; race: call time against final error, see "
                    "bench.propagate.race")
    data["race"] = race(repeats)
    data["batch"] = batch(repeats, grid)
    _print(data, repeats)
    _print_race(data["race"])
    _print_batch(data["batch"])
    path = Path(out) / "propagate.json"
    save_figure(race_figure(data["race"], data["batch"]), Path(out) / "propagate.png")
    write_json(path, data)
    return path
