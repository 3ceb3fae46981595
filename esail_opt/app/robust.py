"""The ``robust`` command's work: a solved schedule flown under a varying solar wind.

A solved, dated rendezvous in three dimensions is cut into its arcs (the pieces the
NLP flew), and flown ``runs`` times on the batched closed form, each flight with the
wind's thrust factor drawn per piece (:class:`~esail_opt.propagation.solar_wind.
SolarWind`): open loop (the schedule as solved), and guided (re-targeted every
``guide_days`` from where the flight is, :mod:`esail_opt.optimisation.guidance`), once
for each of the ``margins``: how much more a_c than the schedule asks the sail has for
guidance to spend.  The same wind blows on every kind, so the guided kinds tell what
each margin buys.  The margin can also be solved into the schedule: a MinTime problem
whose ``Sail(throttle=True, throttle_max=1 / (1 + m))`` asks at most that fraction of
the sail flies with a reserve m at margin 0, and a MinAcceleration answer's a_c times
(1 + m) is the sail to build.

A flight's miss is the closed form's departure from the nominal closed-form flight,
added to the nominal's own miss flown on CVODES: the closed form's model error (a few
thousand km over a two-year transfer) is common to all flights and is taken out by
the nominal's CVODES flight, while the closed form carries the differences.  That this
holds is checked, not assumed: ``check`` flights of each kind are flown on CVODES with
their own wind and angles, and the run is verified only if every one lands where the
closed form said, within :data:`AGREEMENT` of its miss or a tenth of the tolerance.
"""

import time
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from esail_opt.app import outputs
from esail_opt.bodies import lookup
from esail_opt.bodies.dates import J2000_JD, iso_from_jd
from esail_opt.errors import InputError, check_range
from esail_opt.optimisation.guidance import Plan, Retargeting
from esail_opt.physics import constants as units
from esail_opt.physics.elements import polar3d_from_cartesian
from esail_opt.propagation.ensemble import CARTESIAN, Ensemble
from esail_opt.propagation.rectified3d import cartesian_states
from esail_opt.propagation.simulate import simulate3d
from esail_opt.propagation.solar_wind import SolarWind

#: A sampled flight agrees with CVODES when its miss is within this fraction of the
#: CVODES miss, or within a tenth of the problem's tolerance.
AGREEMENT = 0.02
#: Percentiles reported, per cent.
PERCENTILES = (50, 90, 95, 99)
#: The files of a run.
NAMES = ("robust.csv", "robust.json", "robust.png")


@dataclass(frozen=True)
class Request:
    """What to fly: ``runs`` flights a kind, the wind, its seed, the guidance (every
    ``guide_days``; 0 for none), the sail's a_c ``margins`` over what the schedule asks
    (fractions: one guided kind each), and ``check`` flights of each kind flown again on
    CVODES."""

    runs: int = 1000
    wind: SolarWind = SolarWind()
    seed: int = 1
    guide_days: float = 30.0
    margins: tuple = (0.1,)
    check: int = 4

    def __post_init__(self):
        check_range("--runs", self.runs, 1, 10 ** 7)
        check_range("--seed", self.seed, 0, 2 ** 63)
        check_range("--guide-days", self.guide_days, 0.0, 1e5, unit="d")
        if not 1 <= len(self.margins) <= 12:
            raise InputError(f"--margin = {','.join(map(str, self.margins))}: give 1 to 12 "
                             "margins")
        for margin in self.margins:
            check_range("--margin", margin, 0.0, 10.0)
        check_range("--check", self.check, 0, 1000)


def _cartesian(state):
    c = state.cartesian
    return np.r_[[c[k] for k in ("x_au", "y_au", "z_au")],
                 [units.speed_from_km_s(c[k]) for k in ("vx_km_s", "vy_km_s", "vz_km_s")]]


def check_problem(problem):
    """InputError unless ``problem`` (a :class:`~esail_opt.optimisation.problem.Problem`)
    is what a run flies: a dated rendezvous with a body, in three dimensions."""
    kind = type(problem.target).__name__ if problem.target is not None else None
    if kind != "BodyRendezvous" or type(problem.departure).__name__ != "BodyDeparture":
        raise InputError(f"{problem.name}: robust flies a dated rendezvous with a body "
                         f"(BodyDeparture to BodyRendezvous); this one's target is {kind}")
    if not problem.three_d():
        raise InputError(f"{problem.name}: robust flies three-dimensional solutions; "
                         "solve the problem without planar=True")


def _checked(sol):
    """The schedule a run flies, or InputError saying what the solution lacks."""
    target = sol.problem.target
    if not sol.dated or getattr(target, "kind", None) != "BodyRendezvous":
        raise InputError(f"{sol.problem.name}: robust flies a dated rendezvous with a body "
                         f"(BodyDeparture to BodyRendezvous); this one's target is "
                         f"{getattr(target, 'kind', None)}")
    if sol.problem.departure_state.cartesian is None:
        raise InputError(f"{sol.problem.name}: robust flies three-dimensional solutions; "
                         "solve the problem without planar=True")
    if not sol.verified:
        raise InputError(f"{sol.problem.name}: the solution is not verified; robust flies "
                         "only a schedule that meets its target")
    return (sol.polish if sol.polished else sol), sol.polished


@dataclass(frozen=True)
class Mission:
    """A solved rendezvous as pieces: the plan, when they end (days from departure),
    the target's states there, and the nominal's closed-form and CVODES flights."""

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
    def of(cls, sol):
        source, polished = _checked(sol)
        pieces = sol.problem.sub_arcs
        rows = source.schedule
        repeat = lambda v: np.repeat(np.asarray(v, float), pieces)  # noqa: E731
        alphas = repeat(np.radians([r.alpha_deg for r in rows]))
        deltas = repeat(np.radians([r.clock_deg for r in rows]))
        durations = repeat(units.time_from_days(np.array([r.duration_days for r in rows])))
        durations /= pieces
        throttles = repeat([1.0 if r.throttle is None else r.throttle for r in rows])
        required = source.ac_mm_s2_required or sol.problem.ac_mm_s2
        acs = units.accel_from_mm_s2(required) * throttles
        x0, quat = polar3d_from_cartesian(ca.DM(_cartesian(sol.problem.departure_state)))
        start = np.r_[np.array(x0).ravel(), 0.0, np.array(quat).ravel()]
        days = np.r_[0.0, np.cumsum(units.time_to_days(durations))]
        body = lookup.resolve(sol.problem.target.body)
        track = lookup.ecliptic_state(body, np.full(days.size, J2000_JD), "target",
                                     sol.departure_epoch_days + days)
        tol = sol.tolerance
        scale = (tol.position_km / units.length_to_km(1.0),
                 tol.velocity_m_s / units.speed_to_m_s(1.0))
        plan = Plan(start, alphas, deltas, durations, acs, track[:, -1], scale,
                    tuple(np.radians(sol.problem.alpha_bounds_deg)),
                    units.accel_from_mm_s2(required))
        ensemble = Ensemble(alphas.size, True)
        nominal = ensemble.fly(start[None], alphas[None], durations, acs[None],
                               deltas=deltas[None])[0]
        flown = _cvodes(start, alphas, deltas, durations, acs)
        correction = flown - nominal[CARTESIAN]
        return cls(plan, days, track, nominal, correction, J2000_JD + sol.departure_epoch_days,
                   (tol.position_km, tol.velocity_m_s))


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
        return {f"p{q}": {"miss_km": float(np.percentile(self.miss_km, q)),
                          "miss_m_s": float(np.percentile(self.miss_m_s, q))}
                for q in PERCENTILES}

    def within(self, tolerance):
        """The fraction of flights within both bounds."""
        return float(np.mean((self.miss_km <= tolerance[0]) & (self.miss_m_s <= tolerance[1])))


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


@dataclass(frozen=True)
class Robustness:
    """A run's outcome: the request, the mission's name and tolerance, the nominal's
    CVODES miss, the kinds of flight (open loop, and guided at each margin), the CVODES
    checks and the seconds each took."""

    name: str
    request: Request
    tolerance: tuple
    nominal_miss: tuple
    open_loop: Flights
    guided: tuple
    checks: list
    seconds: dict
    departure_jd: float
    ends_days: np.ndarray
    target_track: np.ndarray

    @property
    def verified(self):
        return all(c["agree"] for c in self.checks)

    @property
    def kinds(self):
        return (self.open_loop, *self.guided)

    def _outcome(self, flights):
        return {"percentiles": flights.percentiles(),
                "within_tolerance": flights.within(self.tolerance),
                "closest_km_p50": float(np.median(flights.closest_km))}

    def record(self):
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
            "seconds": self.seconds,
        }

    def rows(self):
        out = []
        for k in self.kinds:
            for i in range(len(k.miss_km)):
                out.append({"flight": i, "kind": k.kind,
                            "margin": "" if k.margin is None else k.margin,
                            "miss_km": float(k.miss_km[i]),
                            "miss_m_s": float(k.miss_m_s[i]),
                            "closest_km": float(k.closest_km[i]),
                            "closest_date": iso_from_jd(self.departure_jd + k.closest_days[i]),
                            "mean_factor": float(k.mean_factor[i])})
        return out

    def summary(self):
        lines = [f"{self.name}: {self.request.runs} flights a kind, thrust factor sigma "
                 f"{self.request.wind.sigma:g}, correlation {self.request.wind.corr_days:g} d, "
                 f"seed {self.request.seed}"]
        for k in self.kinds:
            p = k.percentiles()
            what = ("open loop" if k.margin is None else
                    f"guided every {self.request.guide_days:g} d, a_c margin "
                    f"{100 * k.margin:g} %")
            lines.append(f"  {what}: miss p50 {p['p50']['miss_km']:.4g} km / "
                         f"{p['p50']['miss_m_s']:.4g} m/s, p95 {p['p95']['miss_km']:.4g} km / "
                         f"{p['p95']['miss_m_s']:.4g} m/s; {100 * k.within(self.tolerance):.1f} % "
                         f"within {self.tolerance[0]:g} km and {self.tolerance[1]:g} m/s")
        for c in self.checks:
            kind = c["kind"].replace("_", " ") + ("" if c["margin"] is None else
                                                  f" (margin {100 * c['margin']:g} %)")
            lines.append(f"  CVODES check, {c['flights']} {kind} flights: "
                         f"largest disagreement {c['worst_position_km']:.3g} km, "
                         f"{c['worst_velocity_m_s']:.3g} m/s"
                         + ("" if c["agree"] else " (NOT within the agreement bound)"))
        return "\n".join(lines)


def waypoints(ends_days, every):
    """The pieces at which guidance re-targets: the first piece starting at or after
    each multiple of ``every`` days (none for ``every`` 0)."""
    if every <= 0:
        return []
    starts = ends_days[:-1]
    return sorted(set(np.searchsorted(starts, np.arange(every, starts[-1], every)).tolist()))


def run(sol, request, progress=lambda text: None):
    """Fly ``sol``'s schedule as ``request`` says; a :class:`Robustness`."""
    seconds = {}
    clock = time.perf_counter()
    mission = Mission.of(sol)
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
        progress(f"flying {m} flights guided every {request.guide_days:g} d, a_c margin "
                 f"{100 * margin:g} %")
        clock = time.perf_counter()
        guidance = Retargeting(ensemble, mission.with_margin(margin),
                               waypoints(mission.ends_days, request.guide_days))
        gxs, controls = guidance.fly(factors, mission.nominal)
        seconds[f"guided_margin_{margin:g}"] = time.perf_counter() - clock
        flown.append((_outcome("guided", margin, mission, gxs, factors),
                      controls.take(sample)))
    progress(f"checking {request.check} flights of each kind on CVODES")
    clock = time.perf_counter()
    checks = [_check(mission, _subset(flights, sample), factors[sample], controls)
              for flights, controls in flown]
    seconds["cvodes_check"] = time.perf_counter() - clock
    end = mission.correction[:, -1] + mission.nominal[CARTESIAN, -1]
    gap = end - mission.target_track[:, -1]
    nominal_miss = (units.length_to_km(np.linalg.norm(gap[:3])),
                    units.speed_to_m_s(np.linalg.norm(gap[3:])))
    return Robustness(sol.problem.name, request, mission.tolerance, nominal_miss, open_loop,
                      tuple(f for f, _ in flown[1:]), checks, seconds, mission.departure_jd,
                      mission.ends_days, mission.target_track)


def _subset(flights, index):
    return Flights(flights.kind, flights.margin, *(getattr(flights, f)[index] for f in (
        "miss_km", "miss_m_s", "closest_km", "closest_days", "mean_factor", "positions",
        "arrival")))


FIELDS = ("flight", "kind", "margin", "miss_km", "miss_m_s", "closest_km", "closest_date", "mean_factor")


def write(result, out_dir, plots=True):
    """The run's table, record and figure written into ``out_dir`` as one set."""
    fig = figure(result) if plots else None
    return outputs.write_table_set(out_dir, NAMES, outputs.csv_text(result.rows(), FIELDS),
                                 result.record(), fig)


def figure(result, flights_drawn=200):
    """Histograms of the arrival misses (position, velocity) of each kind against the
    tolerance, and a cloud of trajectories seen from the ecliptic's north."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 4.4), layout="constrained")
    hist_r, hist_v, cloud = fig.subplots(1, 3)
    blues = colormaps["Blues"](np.linspace(0.55, 0.95, max(len(result.guided), 1)))
    kinds = [(result.open_loop, "tab:gray"), *zip(result.guided, blues)]

    def label(k):
        return ("open loop" if k.margin is None else
                f"guided every {result.request.guide_days:g} d (+{100 * k.margin:g} % a_c)")
    for ax, field, bound, unit in ((hist_r, "miss_km", result.tolerance[0], "km"),
                                   (hist_v, "miss_m_s", result.tolerance[1], "m/s")):
        values = np.concatenate([getattr(k, field) for k, _ in kinds])
        low, high = max(values.min(), 1e-6 * values.max(), 1e-12), values.max()
        bins = np.geomspace(low, high * 1.0001, 40) if high > low else 10
        for k, colour in kinds:
            ax.hist(np.maximum(getattr(k, field), low), bins=bins, color=colour, alpha=0.6,
                    label=label(k))
        ax.axvline(bound, color="tab:red", lw=1.2, label=f"tolerance {bound:g} {unit}")
        ax.set_xscale("log")
        ax.set_xlabel(f"arrival miss ({unit})")
        ax.set_ylabel("flights")
        ax.legend(fontsize=8)
    for k, colour in kinds:
        take = k.positions[: flights_drawn]
        for pos in take:
            cloud.plot(pos[0], pos[1], color=colour, lw=0.4, alpha=0.3)
    track = result.target_track
    cloud.plot(track[0], track[1], color="tab:red", lw=1.2, label="target")
    cloud.plot(track[0, -1], track[1, -1], "o", color="tab:red")
    cloud.plot(0, 0, "o", color="gold", ms=9)
    cloud.set_aspect("equal")
    cloud.set_xlabel("x (au, ecliptic J2000)")
    cloud.set_ylabel("y (au)")
    cloud.legend(fontsize=8)
    arrival_date = iso_from_jd(result.departure_jd + result.ends_days[-1])[:10]
    fig.suptitle(f"{result.name}: {result.request.runs} flights a kind under a thrust factor "
                 f"of sigma {result.request.wind.sigma:g}, correlation "
                 f"{result.request.wind.corr_days:g} d (arrival {arrival_date})")
    return fig
