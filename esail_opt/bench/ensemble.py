"""``esail-opt-bench ensemble``: the flights of a Monte Carlo run (``esail-opt robust``)
flown by the closed form, by CVODES and by heyoka, timed per flight at a stated error.

The case is the shipped 3-D rendezvous :data:`SOLUTION` cut into pieces as robust cuts it;
M flights are drawn as robust draws them (one ``SolarWind().factors`` set per flight, seed
:data:`SEED`) and flown open loop by the closed form (every flight), CVODES at 1e-12 (on
:data:`CVODES_FLIGHTS` flights evenly spread) and heyoka (every flight; skipped without
it).  Times are CPU seconds of this process per flight, each method on one thread.

Errors are arrival distances (km) from CVODES at 1e-12 on the flights it flew.  The closed
form's model error (a few thousand km here, nearly the same in every flight) is what robust
takes out with the nominal's CVODES flight, so it is also judged ``corrected`` as robust
uses it, against the flight's ``deviation`` from the nominal (bounded by
``robustness.AGREEMENT``).  :func:`check_flight` flies one flight on two equations and two
integrators, so that their agreement checks the thrust written in heyoka's expressions.
"""

import time
from pathlib import Path

import numpy as np

from esail_opt.bench import taylor
from esail_opt.bench.propagate import cpu_seconds
from esail_opt.bench.timing import print_table, runs_of
from esail_opt.errors import InputError

#: The solved rendezvous flown (a folder ``esail-opt solve`` wrote).
SOLUTION = "results/earth_mars_min_ac"
#: Flights of the ensemble, and the seed of their thrust factors.
FLIGHTS = 10_000
SEED = 1
#: Flights CVODES flies (evenly spread): its time per flight and the reference of every error.
CVODES_FLIGHTS = 20
#: heyoka's tolerances, loosest first, and its batch sizes as multiples of its SIMD
#: width; the fastest on the pilot flights counts at each tolerance.
HEYOKA_TOLERANCES = (1e-3, 1e-6, 1e-9, 1e-12)
HEYOKA_LANES = (1, 2, 4, 8)
PILOT_FLIGHTS = 512
#: heyoka's tolerance on the flight that checks it against CVODES at the verifier's.
CHECK_TOLERANCE = 1e-15


def load(folder=SOLUTION):
    """The solution in ``folder`` and its pieces as robust flies them (``robustness.Mission``,
    no a_c margin); :class:`InputError` when there is none."""
    from esail_opt.app.robust import schedule
    from esail_opt.app.solution import Solution
    from esail_opt.optimisation.robustness import Mission

    source = Path(folder) / "solution.json"
    if not source.is_file():
        raise InputError(f"solution = {str(folder)!r} holds no solution.json; run the bench "
                         "from the repository's root or give a folder `esail-opt solve` wrote")
    sol = Solution.load(source)
    return sol, Mission.of(schedule(sol))


def flights(mission, count, seed=SEED, wind=None):
    """``count`` flights of ``mission``'s pieces under the solar wind ``wind`` (default
    ``SolarWind()``): each flight's a_c per piece (canonical, thrust factor included),
    shape (count, K)."""
    from esail_opt.propagation.solar_wind import SolarWind

    wind = SolarWind() if wind is None else wind
    return mission.plan.acs * wind.factors(np.diff(mission.ends_days), count, seed)


def start_cartesian(plan):
    """The plan's start as a Cartesian state [x, y, z, vx, vy, vz], canonical."""
    from esail_opt.propagation.rectified3d import STATE, cartesian_states

    return cartesian_states(np.asarray(plan.start, float)[:STATE, None])[:6, 0]


def closed_form(plan, acs, repeats):
    """The flights ``acs`` (M, K) on ``Ensemble.fly``: ``seconds_per_flight`` (median CPU
    seconds of all M, over M, one thread), ``first_call_seconds`` (a fresh first call less a
    warm one: a compile or a disk-cache load), ``chunk`` (flights per compiled call) and
    ``arrivals`` (6, M), Cartesian, canonical."""
    from esail_opt.propagation import batch
    from esail_opt.propagation.ensemble import Ensemble
    from esail_opt.propagation.rectified3d import STATE, cartesian_states

    m, k = acs.shape
    ensemble = Ensemble(k, True, threads=1)  # one thread, as heyoka and CVODES are timed

    def one():
        return ensemble.fly(plan.start[None], plan.alphas[None], plan.durations, acs[:1],
                            deltas=plan.deltas[None])

    # Cleared so that the first call pays what a fresh process's does.
    batch.batch3d_function.cache_clear()
    clock = time.perf_counter()
    start = one()[0, :, 0]  # the start as a state row of the ensemble's own width
    first = time.perf_counter() - clock
    warm = min(_wall(one) for _ in range(3))
    args = (np.tile(start, (m, 1)), np.tile(plan.alphas, (m, 1)), plan.durations, acs)
    deltas = np.tile(plan.deltas, (m, 1))
    seconds = cpu_seconds(lambda: ensemble.fly(*args, deltas=deltas), runs_of(repeats))
    xs = ensemble.fly(*args, deltas=deltas)
    return {"seconds_per_flight": seconds / m, "first_call_seconds": max(first - warm, 0.0),
            "chunk": ensemble.chunk, "timed_runs": runs_of(repeats),
            "arrivals": cartesian_states(xs[:, :STATE, -1].T)[:6]}


def _wall(fn):
    clock = time.perf_counter()
    fn()
    return time.perf_counter() - clock


def cvodes(plan, acs, tol=None):
    """The flights ``acs`` (S, K) on CVODES one by one, as robust's checks fly them
    (``simulate.simulate3d`` of the plan's start, angles and durations, ``ac`` 1 and the
    flight's a_c as throttles) at ``tol`` (default ``simulate.TOLERANCE``):
    ``seconds_per_flight`` (CPU seconds of all S, over S) and ``arrivals`` (6, S),
    Cartesian, canonical."""
    from esail_opt.propagation.simulate import TOLERANCE, simulate3d

    y0 = start_cartesian(plan)
    tol = TOLERANCE if tol is None else tol
    ends = []
    clock = time.process_time()
    for row in acs:
        ends.append(simulate3d(y0, plan.alphas, plan.deltas, plan.durations, 1.0,
                               throttles=row, tol=tol)[:6, -1])
    seconds = time.process_time() - clock
    return {"seconds_per_flight": seconds / len(acs), "arrivals": np.array(ends).T}


def heyoka_flights(plan, acs, repeats, reference, sample):
    """The flights ``acs`` (M, K) by heyoka at each of :data:`HEYOKA_TOLERANCES`, or
    ``{"skipped": reason}`` without heyoka; ``reference`` (6, S) is CVODES's arrivals of the
    flights ``sample`` (indices into the M).  Returns ``points``: per tolerance,
    ``seconds_per_flight`` (median CPU seconds of all M at the fastest batch size, over M),
    ``batch_size``, ``build_seconds`` (wall seconds to construct the integrator: a compile or
    a disk-cache load), the pilot's figures per batch size and ``error_km`` against
    ``reference`` (median, max); and ``simd_size``, ``heyoka_version``.
    """
    if not taylor.available():
        return {"skipped": "heyoka is not installed (pip install 'esail_opt[bench]')"}
    import heyoka

    y0 = start_cartesian(plan)
    m = acs.shape[0]
    tiled = [np.tile(v, (m, 1)) for v in (plan.alphas, plan.deltas)]
    simd = heyoka.recommended_simd_size()
    pilot = min(m, PILOT_FLIGHTS)
    points = []
    for tol in HEYOKA_TOLERANCES:
        by_size = {}
        for size in (lanes * simd for lanes in HEYOKA_LANES):
            clock = time.perf_counter()
            ta = taylor.cartesian_integrator(tol, size)
            built = time.perf_counter() - clock
            ready = taylor.prepare3d(size, y0, acs[:pilot], tiled[0][:pilot],
                                     tiled[1][:pilot], plan.durations)
            by_size[size] = {"build_seconds": built, "pilot_seconds_per_flight": cpu_seconds(
                lambda ta=ta, ready=ready: taylor.fly_prepared(ta, ready), 3) / pilot}
        best = min(by_size, key=lambda size: by_size[size]["pilot_seconds_per_flight"])
        ta = taylor.cartesian_integrator(tol, best)
        ready = taylor.prepare3d(best, y0, acs, *tiled, plan.durations)
        seconds = cpu_seconds(lambda: taylor.fly_prepared(ta, ready), runs_of(repeats))
        arrivals = taylor.fly_prepared(ta, ready)[-1, :, :m]
        errors = _distance_km(arrivals[:, sample], reference)
        points.append({"tolerance": tol, "seconds_per_flight": seconds / m, "batch_size": best,
                       "build_seconds": by_size[best]["build_seconds"],
                       "error_km": _spread(errors), "by_batch_size": by_size})
    return {"points": points, "simd_size": simd, "heyoka_version": heyoka.__version__,
            "timed_runs": runs_of(repeats), "pilot_flights": pilot,
            "how": "dynamics.rhs_cartesian replayed on heyoka's expressions; a_c R, a_c T, "
                   "a_c N runtime parameters set per arc and lane "
                   "(thrust.radial_transverse_normal); taylor_adaptive_batch, "
                   "propagate_until each arc's end, one thread"}


def check_flight(plan, acs):
    """One flight ``acs`` (K,) against CVODES at ``simulate.VERIFY_TOLERANCE``: flown by
    CVODES at 1e-12 (``cvodes_1e-12``, the reference of every other error: its own
    error) and, with heyoka, by heyoka at :data:`CHECK_TOLERANCE` (``heyoka_1e-15``),
    each one's arrival position (km) and velocity (m/s) difference."""
    from esail_opt.physics import constants as units
    from esail_opt.propagation.simulate import VERIFY_TOLERANCE

    row = acs[None]
    truth = cvodes(plan, row, VERIFY_TOLERANCE)["arrivals"][:, 0]
    flown = {"cvodes_1e-12": cvodes(plan, row)["arrivals"][:, 0]}
    if taylor.available():
        ta = taylor.cartesian_integrator(CHECK_TOLERANCE, 1)
        ends = taylor.fly3d(ta, start_cartesian(plan), row, plan.alphas[None],
                            plan.deltas[None], plan.durations[None])
        flown[f"heyoka_{CHECK_TOLERANCE:g}"] = ends[0, :6, -1]
    gaps = {key: end - truth for key, end in flown.items()}
    return {"reference_tolerance": VERIFY_TOLERANCE,
            **{key: {"position_km": float(units.length_to_km(np.linalg.norm(gap[:3]))),
                     "velocity_m_s": float(units.speed_to_m_s(np.linalg.norm(gap[3:])))}
               for key, gap in gaps.items()}}


def _distance_km(a, b):
    """Distances between the positions of the columns of ``a`` and ``b``, km."""
    from esail_opt.physics import constants as units

    return units.length_to_km(np.linalg.norm(np.asarray(a)[:3] - np.asarray(b)[:3], axis=0))


def _spread(values):
    return {"median": float(np.median(values)), "max": float(np.max(values))}


def closed_form_accuracy(mission, arrivals, reference):
    """The closed form's ``arrivals`` (6, S) against CVODES's ``reference`` (6, S) of the
    same flights: raw (``error_km``), as robust reports them (``corrected_error_km``: plus
    the nominal's correction), and the corrected error over the flight's departure from the
    nominal on CVODES (``deviation_km``; ``corrected_over_deviation``), median and max."""
    from esail_opt.propagation.rectified3d import STATE, cartesian_states

    correction = mission.correction[:, -1:]
    nominal = cartesian_states(mission.nominal[:STATE, -1:])[:6] + correction
    corrected = _distance_km(arrivals + correction, reference)
    deviation = _distance_km(reference, nominal)
    return {"error_km": _spread(_distance_km(arrivals, reference)),
            "corrected_error_km": _spread(corrected),
            "deviation_km": _spread(deviation),
            "corrected_over_deviation": _spread(corrected / deviation)}


def measure(flights_count=FLIGHTS, repeats=3, solution=SOLUTION, cvodes_flights=CVODES_FLIGHTS,
            seed=SEED):
    """The bench's record (see the module): the case, each method's time per flight and
    accuracy, and the ratios of their times to the closed form's."""
    from esail_opt.optimisation.robustness import AGREEMENT
    from esail_opt.propagation.simulate import TOLERANCE
    from esail_opt.propagation.solar_wind import SolarWind

    clock = time.perf_counter()
    sol, mission = load(solution)
    setup = time.perf_counter() - clock
    plan = mission.plan
    acs = flights(mission, flights_count, seed)
    sample = np.unique(np.linspace(0, flights_count - 1,
                                   min(cvodes_flights, flights_count)).round().astype(int))
    closed = closed_form(plan, acs, repeats)
    reference = cvodes(plan, acs[sample])
    heyoka = heyoka_flights(plan, acs, repeats, reference["arrivals"], sample)
    wind = SolarWind()
    record = {
        "case": {"solution": str(solution), "problem": sol.problem.name,
                 "pieces": int(plan.alphas.size),
                 "transfer_days": float(mission.ends_days[-1]),
                 "flights": int(flights_count), "seed": seed,
                 "wind": {"sigma": wind.sigma, "corr_days": wind.corr_days},
                 "setup_seconds": setup},
        "closed_form": {key: value for key, value in closed.items() if key != "arrivals"},
        "cvodes": {"tolerance": TOLERANCE, "flights_timed": int(sample.size),
                   "seconds_per_flight": reference["seconds_per_flight"]},
        "heyoka": heyoka,
        "check_flight": check_flight(plan, acs[sample[0]]),
        "agreement_bound": AGREEMENT,
    }
    record["closed_form"].update(closed_form_accuracy(mission, closed["arrivals"][:, sample],
                                                      reference["arrivals"]))
    record["ratios"] = ratios(record)
    record["per_flight"] = per_flight_table(record)
    record["note"] = (
        "times: median CPU seconds of this process per flight, each method on one thread, "
        "from arguments in the method's own form to its states; closed form and heyoka fly "
        "every flight, CVODES the flights_timed ones; errors: distance of the arrival "
        "position from CVODES at the stated tolerance on the flights it flew; "
        "corrected: the closed form as robust reports a flight (its departure from the "
        "nominal closed form plus the nominal's CVODES flight); setup_seconds: load, "
        "pieces, target track, the closed form's first call and nominal, the nominal's "
        "CVODES flight")
    return record


def ratios(record):
    """Each method's time per flight over the closed form's: CVODES at 1e-12, heyoka at 1e-12
    and heyoka at equal error (its loosest tolerance whose worst arrival error is within the
    closed form's worst ``corrected`` one), None when heyoka was skipped or never got there."""
    base = record["closed_form"]["seconds_per_flight"]
    points = record["heyoka"].get("points", [])
    target = record["closed_form"]["corrected_error_km"]["max"]
    tight = next((p for p in points if p["tolerance"] == 1e-12), None)
    equal = next((p for p in points if p["error_km"]["max"] <= target), None)
    return {"cvodes_over_closed_form": record["cvodes"]["seconds_per_flight"] / base,
            "heyoka_tight_over_closed_form": None if tight is None
            else tight["seconds_per_flight"] / base,
            "heyoka_equal_error_over_closed_form": None if equal is None
            else equal["seconds_per_flight"] / base,
            "heyoka_equal_error_tolerance": None if equal is None else equal["tolerance"]}


def per_flight_table(record):
    """The methods side by side: µs per flight, arrival error against CVODES at 1e-12
    (km, the worst over the flights CVODES flew; None for CVODES, the reference) and
    time over the closed form's."""
    closed = record["closed_form"]
    base = closed["seconds_per_flight"]
    rows = [("closed form", base, closed["error_km"]["max"]),
            ("closed form, corrected as robust", base, closed["corrected_error_km"]["max"]),
            ("CVODES 1e-12", record["cvodes"]["seconds_per_flight"], None)]
    rows += [(f"heyoka {p['tolerance']:g}", p["seconds_per_flight"], p["error_km"]["max"])
             for p in record["heyoka"].get("points", [])]
    return [{"method": name, "us_per_flight": 1e6 * seconds, "max_error_km": error,
             "ratio_over_closed_form": seconds / base} for name, seconds, error in rows]


def _print(record):
    case = record["case"]
    rows = []
    for row in record["per_flight"]:
        error = row["max_error_km"]
        rows += [(f"{row['method']}: time per flight", row["us_per_flight"], "us"),
                 (f"{row['method']}: worst arrival error",
                  "(the reference)" if error is None else error, "" if error is None else "km"),
                 (f"{row['method']}: time over the closed form's",
                  row["ratio_over_closed_form"], "")]
    closed = record["closed_form"]
    rows += [("closed form: first call's extra time (once per process)",
              closed["first_call_seconds"], "s"),
             ("closed form corrected: worst error over the deviation",
              closed["corrected_over_deviation"]["max"], "")]
    check = record["check_flight"]
    for key, value in check.items():
        if key != "reference_tolerance":
            rows.append((f"one flight, {key} from CVODES {check['reference_tolerance']:g}",
                         value["position_km"], "km"))
    print_table(f"bench ensemble: {case['problem']}, {case['flights']} flights of "
                f"{case['pieces']} pieces (CPU time, one thread; errors against CVODES "
                f"1e-12 on {record['cvodes']['flights_timed']} flights)", rows)
    if "skipped" in record["heyoka"]:
        print(f"  heyoka skipped: {record['heyoka']['skipped']}")


def run(out, repeats, flights=FLIGHTS, solution=SOLUTION):
    """Measure the bench (:func:`measure`, ``flights`` flights of ``solution``), print
    its table and write ``ensemble.json`` under ``out`` (atomically); returns its path."""
    from esail_opt.app.outputs import write_json

    record = measure(flights, repeats, solution)
    _print(record)
    path = Path(out) / "ensemble.json"
    write_json(path, record)
    return path

