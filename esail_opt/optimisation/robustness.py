"""A solved schedule flown many times under a varying solar wind, open loop and guided.

The schedule (:class:`Schedule`) is flown ``runs`` times on the batched closed form under
the same per-piece wind draws: open loop, and guided (:mod:`.guidance`) once for each of
the ``margins``, the fraction of a_c beyond the schedule's that guidance may spend.  A
flight's miss is its closed-form departure from the nominal flight plus the nominal's
own CVODES miss, the closed form's model error being common to all; the run is verified
only if ``check`` flights of each kind, flown on CVODES, agree (:data:`AGREEMENT`).  Each
statistic has its :data:`CONFIDENCE` interval, through which outcomes are compared (a
guided miss is sensitive to the schedule's last digits).  Misses and tolerances are in
km and m/s; everything else is canonical.
"""

import time
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
from scipy.stats import binom, norm

from esail_opt.bodies import lookup
from esail_opt.bodies.dates import J2000_JD
from esail_opt.optimisation.guidance import Plan, Retargeting
from esail_opt.physics import constants as units
from esail_opt.physics.elements import polar3d_from_cartesian
from esail_opt.propagation.ensemble import CARTESIAN, Ensemble
from esail_opt.propagation.rectified3d import cartesian_states
from esail_opt.propagation.simulate import simulate3d

#: A sampled flight agrees with CVODES when its miss is within this fraction of the
#: CVODES miss, or within a tenth of the problem's tolerance.
AGREEMENT = 0.02
#: Percentiles reported, per cent.
PERCENTILES = (50, 90, 95, 99)
#: Confidence of the intervals around the sampled statistics.
CONFIDENCE = 0.95
#: What a run's ``verified`` says, written beside it in robust.json.
VERIFIED_MEANS = (f"every flight re-flown on CVODES lands where its closed-form flight did "
                  f"(within {100 * AGREEMENT:g} % of its miss, or a tenth of the tolerance): "
                  "the statistics can be trusted; whether the flights meet the tolerance is "
                  "each kind's within_tolerance")


def percentile_interval(values, q, confidence=CONFIDENCE):
    """The interval [x_(r), x_(s)] of the sorted sample ``values`` that holds the
    population's ``q``-th percentile with probability at least ``confidence``, whatever
    the distribution: the number of draws below that percentile is binomial (n, q/100),
    and r and s cut off at most (1 - confidence) / 2 of it on each side.  None where
    the sample is too small for such an order statistic on a side."""
    x = np.sort(np.asarray(values, dtype=float))
    n, p, tail = x.size, q / 100, (1 - confidence) / 2
    r = int(binom.ppf(tail, n, p))  # P(fewer than r draws below) <= tail
    s = int(binom.ppf(1 - tail, n, p)) + 1  # P(s or more draws below) <= tail
    if r < 1 or s > n or binom.cdf(r - 1, n, p) > tail:
        return None
    return float(x[r - 1]), float(x[s - 1])


def fraction_interval(successes, n, confidence=CONFIDENCE):
    """Wilson's score interval of a fraction ``successes`` of ``n`` draws."""
    z = float(norm.ppf(0.5 + confidence / 2))
    share, z2 = successes / n, z * z / n
    centre = (share + z2 / 2) / (1 + z2)
    half = z / (1 + z2) * np.sqrt(share * (1 - share) / n + z2 / (4 * n))
    # At none or all of the draws an end is exactly 0 or 1, which rounding would miss.
    return (0.0 if successes == 0 else float(centre - half),
            1.0 if successes == n else float(centre + half))


@dataclass(frozen=True)
class Schedule:
    """A solved, dated rendezvous in three dimensions as pieces, canonical units: pitch
    and clock (rad), durations (TU) and the a_c each asks (throttle included), per
    piece; the sail's full a_c ``sail_ac``; the departure's Cartesian state (six
    components) at ``departure_epoch_days`` (days from J2000); the ``target`` body (as
    :func:`~esail_opt.bodies.lookup.resolve` gives it), met in position and velocity
    at the end within ``tolerance`` (km, m/s); pitch within ``alpha_bounds`` (rad).
    ``name`` names it in the outcome."""

    name: str
    alphas: np.ndarray
    deltas: np.ndarray
    durations: np.ndarray
    acs: np.ndarray
    sail_ac: float
    departure: np.ndarray
    departure_epoch_days: float
    target: object
    tolerance: tuple
    alpha_bounds: tuple


@dataclass(frozen=True)
class Mission:
    """A schedule ready to fly: the plan, when its pieces end (days from departure),
    the target's states there, and the nominal's closed-form and CVODES flights (the
    CVODES one as the correction added to every closed-form flight)."""

    plan: Plan
    ends_days: np.ndarray
    target_track: np.ndarray
    nominal: np.ndarray
    correction: np.ndarray
    departure_jd: float
    tolerance: tuple

    def with_margin(self, margin):
        """The plan whose sail has ``margin`` (a fraction) more a_c than it asks."""
        return replace(self.plan, sail_ac=self.plan.sail_ac * (1 + margin))

    @classmethod
    def of(cls, schedule):
        s = schedule
        x0, quat = polar3d_from_cartesian(ca.DM(s.departure))
        start = np.r_[np.array(x0).ravel(), 0.0, np.array(quat).ravel()]
        days = np.r_[0.0, np.cumsum(units.time_to_days(s.durations))]
        track = lookup.ecliptic_state(s.target, np.full(days.size, J2000_JD), "target",
                                     s.departure_epoch_days + days)
        scale = (s.tolerance[0] / units.length_to_km(1.0),
                 s.tolerance[1] / units.speed_to_m_s(1.0))
        plan = Plan(start, s.alphas, s.deltas, s.durations, s.acs, track[:, -1], scale,
                    s.alpha_bounds, s.sail_ac)
        ensemble = Ensemble(s.alphas.size, True)
        nominal = ensemble.fly(start[None], s.alphas[None], s.durations, s.acs[None],
                               deltas=s.deltas[None])[0]
        flown = _cvodes(start, s.alphas, s.deltas, s.durations, s.acs)
        correction = flown - nominal[CARTESIAN]
        return cls(plan, days, track, nominal, correction, J2000_JD + s.departure_epoch_days,
                   tuple(s.tolerance))


def _cvodes(start, alphas, deltas, durations, acs):
    """The Cartesian states (6, K + 1) of one flight of the pieces on CVODES."""
    y0 = cartesian_states(start[:, None])[:6, 0]
    return simulate3d(y0, alphas, deltas, durations, 1.0, throttles=acs)[:6]


@dataclass(frozen=True)
class Flights:
    """One kind of flight's outcome, per flight: arrival misses (km, m/s), closest
    approach (km) and when (days from departure), and the wind's mean factor; a guided
    kind's a_c ``margin`` (None open loop)."""

    kind: str
    margin: float | None
    miss_km: np.ndarray
    miss_m_s: np.ndarray
    closest_km: np.ndarray
    closest_days: np.ndarray
    mean_factor: np.ndarray
    positions: np.ndarray  # (M, 3, K + 1), au, corrected as the misses are
    arrival: np.ndarray  # (M, 6), canonical, corrected as the misses are

    def percentiles(self):
        """Each of :data:`PERCENTILES` of the misses, and its interval (``*_interval``,
        :func:`percentile_interval`)."""
        return {f"p{q}": {"miss_km": float(np.percentile(self.miss_km, q)),
                          "miss_m_s": float(np.percentile(self.miss_m_s, q)),
                          "miss_km_interval": percentile_interval(self.miss_km, q),
                          "miss_m_s_interval": percentile_interval(self.miss_m_s, q)}
                for q in PERCENTILES}

    def within(self, tolerance):
        """The fraction of flights within both bounds."""
        return float(np.mean(self._inside(tolerance)))

    def within_interval(self, tolerance):
        """The interval of :meth:`within` (:func:`fraction_interval`)."""
        inside = self._inside(tolerance)
        return fraction_interval(int(inside.sum()), inside.size)

    def _inside(self, tolerance):
        return (self.miss_km <= tolerance[0]) & (self.miss_m_s <= tolerance[1])

    def take(self, index):
        return Flights(self.kind, self.margin, *(getattr(self, f)[index] for f in (
            "miss_km", "miss_m_s", "closest_km", "closest_days", "mean_factor", "positions",
            "arrival")))


def _outcome(kind, margin, mission, xs, factors):
    states = xs[:, CARTESIAN] + mission.correction
    gap = states - mission.target_track
    distance = units.length_to_km(np.linalg.norm(gap[:, :3], axis=1))
    nearest = np.argmin(distance, axis=1)
    weights = np.diff(mission.ends_days)
    return Flights(kind, margin, distance[:, -1], units.speed_to_m_s(np.linalg.norm(gap[:, 3:, -1], axis=1)),
                   distance[np.arange(len(nearest)), nearest], mission.ends_days[nearest],
                   factors @ weights / weights.sum(), states[:, :3], states[:, :, -1])


def _check(mission, flights, factors, controls):
    """Each of ``flights`` (a sample, flown with ``factors`` and ``controls``; None for
    the plan's) against its own CVODES flight: the largest position and velocity
    disagreements, km and m/s, and whether all agree."""
    p, tolerance = mission.plan, mission.tolerance
    worst_km = worst_m_s = 0.0
    agree = True
    for i in range(len(factors)):
        alphas, deltas, acs = ((controls.alphas[i], controls.deltas[i], controls.acs[i])
                               if controls is not None else (p.alphas, p.deltas, p.acs))
        end = _cvodes(p.start, alphas, deltas, p.durations, acs * factors[i])[:, -1]
        miss = end - mission.target_track[:, -1]
        wrong = end - flights.arrival[i]
        km = units.length_to_km(np.linalg.norm(wrong[:3]))
        m_s = units.speed_to_m_s(np.linalg.norm(wrong[3:]))
        worst_km, worst_m_s = max(worst_km, km), max(worst_m_s, m_s)
        agree &= km <= max(AGREEMENT * units.length_to_km(np.linalg.norm(miss[:3])),
                           tolerance[0] / 10)
        agree &= m_s <= max(AGREEMENT * units.speed_to_m_s(np.linalg.norm(miss[3:])),
                            tolerance[1] / 10)
    return {"kind": flights.kind, "margin": flights.margin, "flights": len(factors),
            "worst_position_km": worst_km,
            "worst_velocity_m_s": worst_m_s, "agree": bool(agree)}


#: How many evenly spread days of the flight the figure draws the target's path at: at
#: the segments' ends alone, an inner planet's orbit over a long flight was a polygon.
PATH_SAMPLES = 600


@dataclass(frozen=True)
class Robustness:
    """A run's outcome (:func:`run`), verified when every CVODES check agrees."""

    name: str
    request: object
    tolerance: tuple
    nominal_miss: tuple
    open_loop: Flights
    guided: tuple
    checks: list
    seconds: dict
    departure_jd: float
    ends_days: np.ndarray
    target_path: np.ndarray  # (3, PATH_SAMPLES), au: the target over the flight, drawn

    @property
    def verified(self):
        return all(c["agree"] for c in self.checks)

    @property
    def kinds(self):
        return (self.open_loop, *self.guided)

    def label(self, flights):
        """How ``flights`` were flown, in the words the summary and the figure share."""
        if flights.margin is None:
            return "open loop"
        return (f"guided every {self.request.guide_days:g} d and on the approach, a_c margin "
                f"{100 * flights.margin:g} %")

    def _outcome(self, flights):
        return {"percentiles": flights.percentiles(),
                "within_tolerance": flights.within(self.tolerance),
                "within_tolerance_interval": flights.within_interval(self.tolerance),
                "closest_km_p50": float(np.median(flights.closest_km))}

    def record(self):
        """The outcome as data: every number but the per-flight ones."""
        r, w = self.request, self.request.wind
        return {
            "problem": self.name,
            "wind": {"model": "thrust factor: Gauss-Markov, mean 1, per-arc means",
                     "sigma": w.sigma, "corr_days": w.corr_days},
            "runs": r.runs, "seed": r.seed, "guide_days": r.guide_days,
            "tolerance": {"position_km": self.tolerance[0], "velocity_m_s": self.tolerance[1]},
            "nominal_miss": {"position_km": self.nominal_miss[0],
                             "velocity_m_s": self.nominal_miss[1]},
            "open_loop": self._outcome(self.open_loop),
            "guided": [{"margin": k.margin, **self._outcome(k)} for k in self.guided],
            "cvodes_checks": self.checks, "verified": self.verified,
            "verified_means": VERIFIED_MEANS, "seconds": self.seconds,
        }

    def summary(self):
        lines = [f"{self.name}: {self.request.runs} flights a kind, thrust factor sigma "
                 f"{self.request.wind.sigma:g}, correlation {self.request.wind.corr_days:g} d, "
                 f"seed {self.request.seed}; [{100 * CONFIDENCE:g} % intervals of the "
                 "population's values]"]
        for k in self.kinds:
            p = k.percentiles()
            what = self.label(k)
            low, high = k.within_interval(self.tolerance)
            lines.append(f"  {what}: miss p50 {p['p50']['miss_km']:.4g} km "
                         f"{_bracket(p['p50']['miss_km_interval'])} / "
                         f"{p['p50']['miss_m_s']:.4g} m/s, p95 {p['p95']['miss_km']:.4g} km "
                         f"{_bracket(p['p95']['miss_km_interval'])} / "
                         f"{p['p95']['miss_m_s']:.4g} m/s; {100 * k.within(self.tolerance):.1f} % "
                         f"[{100 * low:.1f}-{100 * high:.1f} %] within "
                         f"{self.tolerance[0]:g} km and {self.tolerance[1]:g} m/s")
        for c in self.checks:
            kind = c["kind"].replace("_", " ") + ("" if c["margin"] is None else
                                                  f" (margin {100 * c['margin']:g} %)")
            lines.append(f"  CVODES check, {c['flights']} {kind} flights: "
                         f"largest disagreement {c['worst_position_km']:.3g} km, "
                         f"{c['worst_velocity_m_s']:.3g} m/s"
                         + ("" if c["agree"] else " (NOT within the agreement bound)"))
        lines.append(self._verdict())
        return "\n".join(lines)

    def _verdict(self):
        """One line that keeps apart the two questions: are the numbers right (the CVODES
        checks), and does the mission meet its tolerance (its best kind's fraction)."""
        best = max(self.kinds, key=lambda k: k.within(self.tolerance))
        what = ("open loop" if best.margin is None
                else f"guided with a_c margin {100 * best.margin:g} %")
        share = 100 * best.within(self.tolerance)
        numbers = ("the statistics are verified (each CVODES re-flight agrees with its "
                   "closed-form flight)" if self.verified else
                   "the statistics are NOT verified (a CVODES re-flight disagrees)")
        bounds = f"{self.tolerance[0]:g} km and {self.tolerance[1]:g} m/s"
        if share == 0:
            return f"  verdict: {numbers}; no flight of any kind ends within {bounds}"
        return (f"  verdict: {numbers}; at best {share:.1f} % of flights ({what}) end "
                f"within {bounds}")


def _bracket(interval):
    return "[too few flights to bound]" if interval is None else \
        f"[{interval[0]:.3g}-{interval[1]:.3g}]"


def waypoints(ends_days, every):
    """The pieces at which guidance re-targets: the first piece starting at or after
    each multiple of ``every`` days (none for ``every`` 0), and each piece that starts at
    an instant of :func:`approach_instants` (:func:`cut_at` makes them)."""
    if every <= 0:
        return []
    starts = ends_days[:-1]
    regular = np.searchsorted(starts, np.arange(every, starts[-1], every))
    instants = approach_instants(ends_days[-1], every)
    approach = [i for i, start in enumerate(starts)
                if np.any(np.isclose(start, instants, rtol=0, atol=1e-9 * ends_days[-1]))]
    return sorted(set(regular.tolist()) | set(approach))


#: The last re-targeting, days before arrival: the wind after it is the one nothing
#: corrects, so it comes well inside the wind's correlation time.
APPROACH_LAST_DAYS = 1 / 16


def approach_instants(arrival_days, every):
    """When guidance re-targets on the approach, days from departure: arrival less half
    of ``every``, a quarter, and so on while at least :data:`APPROACH_LAST_DAYS`.  A miss
    made by the wind over one stretch is corrected over the next, as long again."""
    out, left = [], every / 2
    while left >= APPROACH_LAST_DAYS:
        if left < arrival_days:
            out.append(arrival_days - left)
        left /= 2
    return out


def cut_at(schedule, instants_days):
    """``schedule`` with its pieces cut at ``instants_days`` (days from departure): the
    same flight in more pieces, so that guidance can re-target there."""
    days = units.time_to_days(schedule.durations)
    ends = np.cumsum(days)
    cuts = sorted(t for t in instants_days if 0 < t < ends[-1]
                  and np.min(np.abs(ends - t)) > 1e-9 * ends[-1])
    index = np.searchsorted(ends, cuts)  # the piece each cut falls in
    bounds = np.sort(np.r_[0.0, ends, cuts])
    owner = np.sort(np.r_[np.arange(days.size), index])  # each new piece's old piece
    return replace(schedule, alphas=schedule.alphas[owner], deltas=schedule.deltas[owner],
                   acs=schedule.acs[owner], durations=units.time_from_days(np.diff(bounds)))


def run(schedule, request, progress=lambda text: None):
    """Fly ``schedule`` (a :class:`Schedule`) as ``request`` says; a :class:`Robustness`.

    ``request`` has the fields ``runs``, ``wind`` (a
    :class:`~esail_opt.propagation.solar_wind.SolarWind`), ``seed``, ``guide_days``
    (0 flies open loop only), ``margins`` and ``check``, already checked by the caller.
    The draws depend on the seed alone, so a request repeats its numbers.  ``check``
    flights of each kind, evenly spread over the runs, are flown again on CVODES.
    """
    seconds = {}
    clock = time.perf_counter()
    if request.guide_days > 0:
        arrival = float(units.time_to_days(schedule.durations).sum())
        schedule = cut_at(schedule, approach_instants(arrival, request.guide_days))
    mission = Mission.of(schedule)
    p = mission.plan
    factors = request.wind.factors(np.diff(mission.ends_days), request.runs, request.seed)
    ensemble = Ensemble(p.alphas.size, True)
    seconds["setup"] = time.perf_counter() - clock
    progress(f"flying {request.runs} flights open loop")
    clock = time.perf_counter()
    m = request.runs
    xs = ensemble.fly(np.tile(p.start, (m, 1)), np.tile(p.alphas, (m, 1)), p.durations,
                      p.acs * factors, deltas=np.tile(p.deltas, (m, 1)))
    seconds["open_loop"] = time.perf_counter() - clock
    sample = np.linspace(0, m - 1, min(request.check, m)).astype(int)
    open_loop = _outcome("open_loop", None, mission, xs, factors)
    flown = [(open_loop, None)]
    for margin in request.margins if request.guide_days > 0 else ():
        progress(f"flying {m} flights guided every {request.guide_days:g} d and on the "
                 f"approach, a_c margin {100 * margin:g} %")
        clock = time.perf_counter()
        guidance = Retargeting(ensemble, mission.with_margin(margin),
                               waypoints(mission.ends_days, request.guide_days))
        gxs, controls = guidance.fly(factors, mission.nominal)
        seconds[f"guided_margin_{margin:g}"] = time.perf_counter() - clock
        flown.append((_outcome("guided", margin, mission, gxs, factors),
                      controls.take(sample)))
    progress(f"checking {request.check} flights of each kind on CVODES")
    clock = time.perf_counter()
    checks = [_check(mission, flights.take(sample), factors[sample], controls)
              for flights, controls in flown]
    seconds["cvodes_check"] = time.perf_counter() - clock
    end = mission.correction[:, -1] + mission.nominal[CARTESIAN, -1]
    gap = end - mission.target_track[:, -1]
    nominal_miss = (units.length_to_km(np.linalg.norm(gap[:3])),
                    units.speed_to_m_s(np.linalg.norm(gap[3:])))
    path_days = np.linspace(0.0, mission.ends_days[-1], PATH_SAMPLES)
    path = lookup.ecliptic_state(schedule.target, np.full(PATH_SAMPLES, J2000_JD), "target",
                                 schedule.departure_epoch_days + path_days)[:3]
    return Robustness(schedule.name, request, mission.tolerance, nominal_miss, open_loop,
                      tuple(f for f, _ in flown[1:]), checks, seconds, mission.departure_jd,
                      mission.ends_days, path)
