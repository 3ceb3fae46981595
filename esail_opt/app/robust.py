"""The ``robust`` command's edge: checks the request and the solution (a dated, verified 3-D
rendezvous with a body), reads its schedule into the canonical pieces that
:mod:`esail_opt.optimisation.robustness` flies under a varying solar wind, and writes
robust.csv, robust.json and robust.png."""

from dataclasses import dataclass

import numpy as np

from esail_opt.app import outputs
from esail_opt.bodies import lookup
from esail_opt.bodies.dates import iso_from_jd
from esail_opt.errors import InputError, check_range
from esail_opt.optimisation import robustness
from esail_opt.optimisation.robustness import Schedule
from esail_opt.physics import constants as units
from esail_opt.propagation.solar_wind import SolarWind

#: The files of a run.
NAMES = ("robust.csv", "robust.json", "robust.png")


@dataclass(frozen=True)
class Request:
    """What to fly: ``runs`` flights a kind, the wind and its seed, guidance every
    ``guide_days`` (0: none), the sail's a_c ``margins`` over what the schedule asks
    (fractions, one guided kind each), and ``check`` flights a kind flown again on CVODES."""

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
    """A departure state's Cartesian components (au, km/s) in canonical units."""
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
    return sol.polish if sol.polished else sol


def schedule(sol):
    """``sol``'s schedule as the pieces the NLP flew, canonical units; InputError when it is
    not one a run flies.  A polished solution flies its polish, at the a_c it asks."""
    source = _checked(sol)
    pieces = sol.problem.sub_arcs
    arcs = source.schedule
    repeat = lambda v: np.repeat(np.asarray(v, float), pieces)  # noqa: E731
    alphas = repeat(np.radians([r.alpha_deg for r in arcs]))
    deltas = repeat(np.radians([r.clock_deg for r in arcs]))
    durations = repeat(units.time_from_days(np.array([r.duration_days for r in arcs])))
    durations /= pieces
    throttles = repeat([1.0 if r.throttle is None else r.throttle for r in arcs])
    sail_ac = units.accel_from_mm_s2(source.ac_mm_s2_required or sol.problem.ac_mm_s2)
    tol = sol.tolerance
    # A polish may move the departure (a free date): it is flown from its own.
    start = getattr(source, "departure_state", None) or sol.problem.departure_state
    epoch = getattr(source, "departure_epoch_days", None)
    return Schedule(sol.problem.name, alphas, deltas, durations, sail_ac * throttles, sail_ac,
                    _cartesian(start), sol.departure_epoch_days if epoch is None else epoch,
                    lookup.resolve(sol.problem.target.body),
                    (tol.position_km, tol.velocity_m_s),
                    tuple(np.radians(sol.problem.alpha_bounds_deg)))


def run(sol, request, progress=lambda text: None):
    """Fly ``sol``'s schedule as ``request`` says; a ``robustness.Robustness``."""
    return robustness.run(schedule(sol), request, progress)


FIELDS = ("flight", "kind", "margin", "miss_km", "miss_m_s", "closest_km", "closest_date", "mean_factor")


def rows(result):
    """robust.csv's rows: each flight of each kind, its closest approach dated."""
    out = []
    for k in result.kinds:
        for i in range(len(k.miss_km)):
            out.append({"flight": i, "kind": k.kind,
                        "margin": "" if k.margin is None else k.margin,
                        "miss_km": float(k.miss_km[i]),
                        "miss_m_s": float(k.miss_m_s[i]),
                        "closest_km": float(k.closest_km[i]),
                        "closest_date": iso_from_jd(result.departure_jd + k.closest_days[i]),
                        "mean_factor": float(k.mean_factor[i])})
    return out


def write(result, out_dir, plots=True):
    """The run's table, record and figure written into ``out_dir`` as one set."""
    fig = figure(result) if plots else None
    return outputs.write_table_set(out_dir, NAMES, outputs.csv_text(rows(result), FIELDS),
                                 result.record(), fig)


def figure(result, flights_drawn=200):
    """Histograms of the arrival misses (position, velocity) of each kind against the
    tolerance, and a cloud of trajectories seen from the ecliptic's north."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    fig = Figure(figsize=(13, 4.4), layout="constrained")
    hist_r, hist_v, cloud = fig.subplots(1, 3)
    blues = colormaps["Blues"](np.linspace(0.55, 0.95, max(len(result.guided), 1)))
    kinds = [(result.open_loop, "tab:gray"), *zip(result.guided, blues)]

    for ax, field, bound, unit in ((hist_r, "miss_km", result.tolerance[0], "km"),
                                   (hist_v, "miss_m_s", result.tolerance[1], "m/s")):
        values = np.concatenate([getattr(k, field) for k, _ in kinds])
        low, high = max(values.min(), 1e-6 * values.max(), 1e-12), values.max()
        bins = np.geomspace(low, high * 1.0001, 40) if high > low else 10
        for k, colour in kinds:
            ax.hist(np.maximum(getattr(k, field), low), bins=bins, color=colour, alpha=0.6,
                    label=result.label(k))
        tolerance = ax.axvline(bound, color="tab:red", lw=1.2,
                               label=f"tolerance {bound:g} {unit}")
        ax.set_xscale("log")
        ax.set_xlabel(f"arrival miss ({unit})")
        ax.set_ylabel("flights")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend(handles=[tolerance], fontsize=8)
    # The kinds' labels are long and the same in both histograms: said once, under them.
    fig.legend(handles=hist_r.get_legend_handles_labels()[0][:len(kinds)],
               loc="outside lower center", ncols=len(kinds), fontsize=8)
    for k, colour in kinds:
        take = k.positions[: flights_drawn]
        for pos in take:
            cloud.plot(pos[0], pos[1], color=colour, lw=0.4, alpha=0.3)
    track = result.target_path
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
