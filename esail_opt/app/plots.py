"""Plots of a :class:`~esail_opt.app.solution.Solution`, drawn from its record alone (a solution
loaded from its file plots as the fresh one did): ``trajectory.png`` and ``timeline.png``.

Time axes are calendar dates (TDB) for a dated solution, else days since departure.  Every figure
function here and in :mod:`esail_opt.app.reproduce` draws into the caller's axes or a Figure of its
own (:func:`axes_or_new`).  Titles and legends, which hold names a user chose, are never parsed as
math.  The rest of the package imports matplotlib only when a figure is drawn.
"""

import functools
import re
from datetime import datetime
from pathlib import Path
from types import SimpleNamespace

import matplotlib.dates as mdates
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import LogFormatterSciNotation

from esail_opt.app.outputs import figure_bytes

from esail_opt.runtime.files import atomic_path
from esail_opt.physics import thrust


def axes_or_new(axes, nrows=1, ncols=1, figsize=None, margins=None, **subplots):
    """``(fig, axes)``: the caller's ``axes`` (an Axes or an array) and their top-level figure, or,
    with None, a new bare Figure of ``figsize`` inches (no pyplot: no backend, no window) and its
    ``subplots(nrows, ncols, **subplots)``.  ``margins`` place the grid at :data:`DPI`
    (``subplots_adjust``); without them the layout is constrained, which draws twice when saved."""
    if axes is not None:
        # SubFigure.figure is the root, Figure.figure itself (get_figure(root=True): mpl 3.10).
        return np.ravel(axes)[0].figure.figure, axes
    if margins is None:
        fig = Figure(figsize=figsize, layout="constrained")
    else:
        fig = Figure(figsize=figsize, dpi=DPI)
        fig.subplots_adjust(**margins)
    return fig, fig.subplots(nrows, ncols, **subplots)


#: Where the trajectory's axes sit on its 6.4 in square (fractions of the figure).
TRAJECTORY_MARGINS = dict(left=0.106, right=0.993, bottom=0.094, top=0.925)
#: The trajectory's title size (points), for its two lines of :func:`headline`.
TRAJECTORY_TITLE_SIZE = 10

#: The timeline's columns on its 10 in width (fractions).
TIMELINE_COLUMNS = dict(left=0.067, right=0.987, wspace=0.185)
#: The timeline's right edge when the pitch panel carries the throttle's own axis.
TIMELINE_RIGHT_WITH_THROTTLE = 0.944
#: The timeline's rows, inches: the title, each panel, the gap between rows (they share
#: the last one's time labels), the foot below the last, and the error-control rounds'
#: strip (under a gap as wide as the foot).
TIMELINE_ROWS_IN = dict(title=0.75, panel=1.9, gap=0.12, foot=0.5, rounds=1.6)


#: The resolution the figures are made and written at (labels are measured once).
DPI = 150
#: Room kept left of a column's widest y labels, inches (constrained layout's pad).
LABEL_PAD_IN = 3 / 72


def _fit_columns(fig, left, right=()):
    """Set the left margin to the widest y labels of the Axes ``left`` (those at the
    figure's left edge), and the gap between the columns of a two-column grid to those
    of the Axes ``right``: one measurement is final, the panels' heights unchanged."""
    renderer = FigureCanvasAgg(fig).get_renderer()
    width = fig.bbox.width
    pad = LABEL_PAD_IN * fig.dpi / width

    def room(column):
        return pad + max(ax.get_window_extent(renderer).x0
                         - ax.yaxis.get_tightbbox(renderer).x0 for ax in column) / width

    margin = room(left)
    grids = {id(g): g for g in (ax.get_subplotspec().get_gridspec() for ax in left)}
    placed = [ax for ax in fig.axes if ax.get_subplotspec() is not None
              and id(ax.get_subplotspec().get_gridspec()) in grids]
    edge = [ax for ax in placed
            if ax.get_subplotspec().colspan.stop == ax.get_subplotspec().get_gridspec().ncols]
    _fit_right(fig, renderer, grids.values(), pad, edge)
    gap = room(right) if len(right) else 0.0
    for grid in grids.values():
        grid.update(left=margin)
        if grid.ncols == 2:
            panel = (grid.get_subplot_params(fig).right - margin - gap) / 2
            grid.update(wspace=gap / panel)
    # GridSpec.update moves the Axes of pyplot's figures only.
    for ax in placed:
        ax.set_position(ax.get_subplotspec().get_position(fig))


def _fit_right(fig, renderer, grids, pad, right):
    """Move the right edge of ``grids`` left by as much as an x tick label of the Axes
    ``right`` (those at the right edge) reaches past the figure's right edge less
    ``pad`` (a fraction of its width): the last label is centred on a panel's end."""
    width = fig.bbox.width
    boxes = [ax.xaxis.get_tightbbox(renderer) for ax in right]
    reach = max((box.x1 for box in boxes if box is not None), default=0.0) / width
    over = reach - (1 - pad)
    if over > 0:
        for grid in grids:
            grid.update(right=grid.get_subplot_params(fig).right - over)


#: Digits and minus as Unicode superscripts, for :class:`PlainLogFormatter`.
_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075"
                             "\u2076\u2077\u2078\u2079")
_MATHDEFAULT = re.compile(r"\$\\mathdefault\{(.*)\}\$")
_EXPONENT = re.compile(r"\^\{(-?\d+)\}")


class PlainLogFormatter(LogFormatterSciNotation):
    """matplotlib's log-axis tick labels (``10^k``, ``c x 10^k``) in Unicode superscripts (all in
    DejaVu Sans), not mathtext, whose parser takes a good part of a timeline's drawing time."""

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)
        match = _MATHDEFAULT.fullmatch(label)
        if match is None:
            return label
        plain = match.group(1).replace(r"\times", "\u00d7")
        plain = _EXPONENT.sub(lambda m: m.group(1).translate(_SUPERSCRIPT), plain)
        return plain[:1].replace("-", "\u2212") + plain[1:]


def _plain_log_labels(axis):
    """Label a log ``axis`` with :class:`PlainLogFormatter` where matplotlib's log scale would: its
    decades, and its minor ticks when it spans too few decades to show more than one."""
    axis.set_major_formatter(PlainLogFormatter(10))
    axis.set_minor_formatter(PlainLogFormatter(10, labelOnlyBase=False))


def _plain_legend(legend):
    """Draw ``legend``'s entries as plain text: they hold names the user chose (a small
    body's), which matplotlib would otherwise parse as math between two ``$``."""
    for text in legend.get_texts():
        text.set_parse_math(False)


def figure_failure(name, err):
    """The one line that says the figure ``name`` could not be drawn, and why (the
    first line of the error: matplotlib's parse errors run over several)."""
    reason = (str(err).strip().splitlines() or [""])[0].strip()
    return f"{name} could not be drawn: {type(err).__name__}" + (f": {reason}" if reason else "")


def _orbit_xy(a, e, omega_rad=0.0, points=361):
    nu = np.linspace(0, 2 * np.pi, points)
    r = a * (1 - e**2) / (1 + e * np.cos(nu))
    return r * np.cos(nu + omega_rad), r * np.sin(nu + omega_rad)


def _samples_xy(samples):
    return _xy(samples.r_au, samples.theta_deg)


def _xy(r_au, theta_deg):
    r = np.asarray(r_au, float)
    th = np.radians(np.asarray(theta_deg, float))
    return r * np.cos(th), r * np.sin(th)


# ------------------------------------------------------------------ words, time, the flight


def headline(sol):
    """A figure's title in two lines: the problem's name and whether its flight (and the polished
    one) is verified, then the flown flight's time of flight, a_c and dates."""
    verdict = _verdict(sol.flight_verified, sol.outcome)
    if sol.polished:
        verdict = (f"closed form {verdict}, polished "
                   + _verdict(sol.polish.verified, sol.polish.outcome))
    flown = _flown(sol)
    facts = [f"time of flight {flown.tof_days:.{2 if flown.polished else 1}f} days",
             f"a_c {'needed ' if sol.ac_mm_s2_required is not None else ''}"
             f"{flown.ac_mm_s2:.4g} mm/s²"]
    if flown.departure_date is not None:
        facts.append(f"{flown.departure_date[:10]} to {flown.arrival_date[:10]}")
    name = sol.problem.name + (" in 3-D" if three_d(sol) else "")
    return f"{name}: {verdict}\n" + ", ".join(facts)


def _verdict(verified, outcome):
    """"verified", or "not verified" with Ipopt's outcome in a word when it did not converge."""
    if verified:
        return "verified"
    if outcome is None or outcome.value == "converged":
        return "not verified"
    return f"not verified (Ipopt: {outcome.value})"


def _flown(sol):
    """The flight that flies, which the attitude and thrust panels show: the polished
    schedule and samples, else the closed form's schedule and CVODES flight (its own
    samples when CVODES failed); with its time of flight, a_c (mm/s²) and dates."""
    ac = sol.ac_mm_s2_required if sol.ac_mm_s2_required is not None else sol.problem.ac_mm_s2
    if sol.trajectory_polished is None:
        cv = sol.trajectory_cvodes
        return SimpleNamespace(
            polished=False, schedule=sol.schedule, tof_days=sol.tof_days, ac_mm_s2=ac,
            samples=cv if cv is not None else sol.trajectory_closed_form,
            departure_date=sol.departure_date, arrival_date=sol.arrival_date)
    p = sol.polish
    return SimpleNamespace(
        polished=True, schedule=p.schedule, tof_days=sol.tof_days_exact,
        samples=sol.trajectory_polished,
        ac_mm_s2=p.ac_mm_s2_required if p.ac_mm_s2_required is not None else ac,
        departure_date=p.departure_date or sol.departure_date,
        arrival_date=p.arrival_date or sol.arrival_date)


#: The time axes' labels: a dated solution's, and an undated one's.
DATE_LABEL = "date (TDB)"
DAYS_LABEL = "t since departure (days)"


def _day_zero(date):
    """Where day 0 of a flight that departs on ``date`` (ISO 8601, TDB; None when
    undated) lies on the time axes: its matplotlib date number (days), or 0."""
    return 0.0 if date is None else mdates.date2num(datetime.fromisoformat(date))


def _time_axis(ax, sol):
    """Calendar dates, ISO style, on the x axis of ``ax`` (and of the Axes that share
    it) for a dated solution; returns the time axis's label."""
    if not sol.dated:
        return DAYS_LABEL
    locator = mdates.AutoDateLocator(minticks=3, maxticks=7)
    formatter = mdates.AutoDateFormatter(locator, defaultfmt="%Y-%m-%d")
    formatter.scaled = {1 / 24: "%Y-%m-%d %H:%M", 1.0: "%Y-%m-%d", 30.0: "%Y-%m",
                        365.0: "%Y-%m"}
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(formatter)
    return DATE_LABEL


def thrust_acceleration(sol):
    """The sail's thrust acceleration |a| = kappa a_c (r_E / r) |(R, T, N)|, r_E = 1 au, along the
    flight that flies (:func:`_flown`), (R, T, N) of each segment's pitch and clock
    (:func:`esail_opt.physics.thrust.radial_transverse_normal`).  Returns ``(t_days, a_mm_s2)``,
    days since departure and mm/s², at each sample; a sample on a segment's start comes twice, once
    per segment, so that steps draw upright."""
    flown = _flown(sol)
    sched = flown.schedule
    t = np.asarray(flown.samples.t_days, float)
    starts = np.array([row.t_days for row in sched])
    # Within 0.1 s of a start a sample lies on it (the samples end and start segments).
    before = np.searchsorted(starts, t - 1e-6) - 1
    after = np.searchsorted(starts, t + 1e-6, side="right") - 1
    seg = np.clip(np.column_stack([before, after]), 0, len(sched) - 1)
    keep = np.column_stack([np.ones(len(t), bool), seg[:, 0] != seg[:, 1]]).ravel()
    seg = seg.ravel()[keep]

    def column(name, default):
        return np.array([default if getattr(row, name) is None else getattr(row, name)
                         for row in sched], float)[seg]

    rtn = thrust.radial_transverse_normal(np.radians(column("alpha_deg", 0.0)),
                                          np.radians(column("clock_deg", 0.0)),
                                          tuple(sol.problem.coefficients))
    factor = np.sqrt(sum(np.array(f, float).ravel()**2 for f in rtn))  # |(R, T, N)|
    r_au = np.repeat(np.asarray(flown.samples.r_au, float), 2)[keep]
    r_e_au = 1.0
    return np.repeat(t, 2)[keep], column("throttle", 1.0) * flown.ac_mm_s2 * r_e_au / r_au * factor


# --------------------------------------------------------------------------- trajectory


def _draw_bodies(sol, top, side=None):
    """The departure and target bodies on their real tracks over the flight (ecliptic
    of J2000): x, y into ``top`` and z against the date into ``side``, each marked at
    the departure (circle) and the arrival (square)."""
    from esail_opt.bodies import dates, lookup

    prob = sol.problem
    start, end = (dates.jd_from_iso(d) for d in (sol.departure_date, sol.arrival_date))
    jd = np.linspace(start, end, 200)
    pairs = [(sol.departure_body.name, prob.departure.body, "0.5")]
    if sol.target_body is not None:
        pairs.append((sol.target_body.name, prob.target.body, "tab:green"))
    for label, body, colour in pairs:
        x, y, z = lookup.ecliptic_state(lookup.resolve(body), jd)[:3]
        views = [(top, x, y)]
        if side is not None:
            views.append((side, _day_zero(sol.departure_date) + (jd - start), z))
        for ax, u, v in views:
            ax.plot(u, v, color=colour, lw=0.8, ls="--", label=f"{label} over the flight")
            for end, marker in ((0, "o"), (-1, "s")):
                ax.plot(u[[end]], v[[end]], marker, color=colour, mec="k", mew=0.6, ms=5,
                        zorder=3)


def _legend(ax, sol):
    """The legend of ``ax``, with the bodies' markers at the departure (circle) and the
    arrival (square) explained once, with their dates, for every body."""
    handles, labels = ax.get_legend_handles_labels()
    if sol.dated:
        for marker, when, date in (("o", "departure", sol.departure_date),
                                   ("s", "arrival", sol.arrival_date)):
            handles.append(Line2D([], [], ls="none", marker=marker, mfc="w", mec="k",
                                  mew=0.6, ms=5))
            labels.append(f"at {when}, {date[:10]}")
    legend = ax.legend(handles, labels, fontsize=7)
    _plain_legend(legend)
    _keep_clear(ax, legend)


#: The legend's corners as axes fractions, in the order taken when they are equally clear.
LEGEND_CORNERS = {"upper right": (1, 1), "upper left": (0, 1), "lower left": (0, 0),
                  "lower right": (1, 0)}
#: Room kept around the legend, a fraction of its size: the layout may still move the frame.
LEGEND_PAD = 0.12


def _keep_clear(ax, legend):
    """Put ``legend`` in the corner of ``ax`` that needs the least widening of the view (none where
    a corner is clear of every drawn point, :func:`_drawn_points`), and widen the view on that side.
    matplotlib's loc="best" only weighs what the legend hides, and measures it at every draw."""
    renderer = FigureCanvasAgg(ax.figure).get_renderer()
    size = legend.get_window_extent(renderer)
    corner = None
    for _ in range(3):  # widening one side narrows an equal-aspect frame: look again
        ax.apply_aspect()
        frame = ax.get_window_extent(renderer)
        w, h = ((1 + LEGEND_PAD) * size.width / frame.width,
                (1 + LEGEND_PAD) * size.height / frame.height)
        if h >= 0.5:
            break
        x, y = _drawn_points(ax)

        def widening(where):
            """The factor the y span needs for the legend at ``where`` to hide nothing."""
            cx, cy = LEGEND_CORNERS[where]
            under = y[(np.abs(x - cx) < w) & (np.abs(y - cy) < h)]
            if under.size == 0:
                return 1.0
            return max((under.max() if cy == 1 else 1 - under.min()) / (1 - h), 1.0)

        corner = corner or min(LEGEND_CORNERS, key=widening)
        factor = widening(corner)
        if factor == 1.0:
            break
        low, high = ax.get_ylim()
        if LEGEND_CORNERS[corner][1] == 1:
            ax.set_ylim(low, low + (high - low) * factor)
        else:
            ax.set_ylim(high - (high - low) * factor, high)
    legend.set_loc(corner or "upper right")


def _drawn_points(ax):
    """The points of every line of ``ax`` in axes fractions, a curve's resampled every
    half per cent of the frame along its length so that a sparse one counts."""
    to_axes = ax.transData + ax.transAxes.inverted()
    spots = [np.zeros((0, 2))]
    for line in ax.get_lines():
        xy = to_axes.transform(np.asarray(line.get_xydata(), float))
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if line.get_linestyle() not in ("None", "") and len(xy) > 1:
            along = np.r_[0.0, np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]
            even = np.linspace(0.0, along[-1], max(int(along[-1] / 0.005), 2))
            xy = np.column_stack([np.interp(even, along, xy[:, k]) for k in (0, 1)])
        spots.append(xy)
    return np.vstack(spots).T


def _draw_orbits(ax, sol):
    """The planar view's guides: the departure and target orbits, or the bodies over
    the flight for a dated problem."""
    prob = sol.problem
    dep = prob.departure
    if dep.kind == "ParkingOrbit":
        ax.plot(*_orbit_xy(dep.a_au, dep.e, np.radians(dep.omega_deg)), color="0.6",
                lw=0.8, ls="--", label="departure orbit")
    elif dep.kind != "BodyDeparture":  # a body's own orbit is drawn with the bodies
        ax.plot(*_orbit_xy(prob.departure_state.a_au, 0.0), color="0.6", lw=0.8, ls="--",
                label="departure a (circle)")
    tgt = prob.target
    if sol.dated:
        _draw_bodies(sol, ax)
    elif tgt is not None:
        if tgt.kind == "Orbit":
            # The apse line is free: draw the circle of radius a as a guide.
            xy = _orbit_xy(tgt.a_au, 0.0)
            label = f"target a = {tgt.a_au} au (e = {tgt.e}, free apse line)"
        else:
            xy = _orbit_xy(tgt.radius_au, 0.0)
            label = "target orbit"
        ax.plot(*xy, color="tab:green", lw=0.8, ls="--", label=label)


def _sun(ax):
    ax.plot([0], [0], "*", color="orange", ms=12, label="Sun")


def trajectory_figure(solution, ax=None):
    """The trajectory in the plane (au): closed form, CVODES and polished, with orbits and segment
    starts, into ``ax`` or a new figure; returns the figure.  A 3-D solution is drawn by
    :func:`_trajectory3d_figure` (``ax`` a pair: from above, from the side)."""
    sol = solution
    if three_d(sol):
        return _trajectory3d_figure(sol, ax)
    created = ax is None
    fig, ax = axes_or_new(ax, figsize=(6.4, 6.4), margins=TRAJECTORY_MARGINS)
    _draw_orbits(ax, sol)
    cf = sol.trajectory_closed_form
    ax.plot(*_samples_xy(cf), color="tab:blue", lw=1.6, label="closed form (NLP)")
    cv = sol.trajectory_cvodes
    if cv is not None:
        ax.plot(*_samples_xy(cv), color="tab:red", lw=0.9, ls="-.", label="CVODES (Eqs. 1-2)")
    exact = sol.trajectory_polished
    if exact is not None:
        ax.plot(*_samples_xy(exact), color="tab:purple", lw=1.2, ls=":",
                label="polished, CVODES (Eqs. 1-2)")
    # Segment boundaries: the closed form's nodes, found in its samples by theta.
    th_cf = np.asarray(cf.theta_deg, float)
    r_cf = np.asarray(cf.r_au, float)
    th_starts = [row.theta_deg for row in sol.schedule]
    r_starts = [np.interp(th, th_cf, r_cf) for th in th_starts]
    ax.plot(*_xy(r_starts, th_starts), "o", ms=3, color="k", label="segment starts")
    _sun(ax)
    ax.set_aspect("equal")
    ax.set_xlabel("x (au)")
    ax.set_ylabel("y (au)")
    # A title at a given height spares matplotlib measuring the y axis at every draw.
    ax.set_title(headline(sol), y=1.0, fontsize=TRAJECTORY_TITLE_SIZE, parse_math=False)
    _legend(ax, sol)
    ax.grid(alpha=0.3)
    if created:
        _fit_columns(fig, [ax])
    return fig


def three_d(sol):
    """Whether ``sol`` was flown in 3-D: its schedule has a clock angle (schema 5)."""
    return len(sol.schedule) > 0 and sol.schedule[0].clock_deg is not None


def _flight3d(sol):
    """Arrays of the CVODES flight's Cartesian samples (``Samples.three_d``) and ``t_days``, None if
    it failed: the 3-D views show only it, the closed form being polar in its turning plane."""
    cv = sol.trajectory_cvodes
    if cv is None or cv.three_d is None:
        return None
    out = {k: np.asarray(v, float) for k, v in cv.three_d.items()}
    out["t_days"] = np.asarray(cv.t_days, float)
    return out


#: The 3-D trajectory's figure (inches), where its two views sit (fractions) and their
#: heights' ratio: from above, and under it from the side.
TRAJECTORY3D_SIZE = (6.4, 9.4)
TRAJECTORY3D_MARGINS = dict(left=0.12, right=0.965, bottom=0.06, top=0.912, hspace=0.22)
TRAJECTORY3D_HEIGHTS = (3.0, 1.15)


def _trajectory3d_figure(sol, axes=None):
    """A 3-D solution's path from above (x, y: the ecliptic of J2000) and from the side (z against
    the date), with the bodies' real tracks over the flight and the segment starts."""
    created = axes is None
    if created:
        fig = Figure(figsize=TRAJECTORY3D_SIZE, dpi=DPI)
        fig.subplots_adjust(**TRAJECTORY3D_MARGINS)
        top, side = fig.subplots(2, 1, height_ratios=TRAJECTORY3D_HEIGHTS)
    else:
        fig, (top, side) = axes_or_new(axes)
    if sol.dated:
        _draw_bodies(sol, top, side)
    flight = _flight3d(sol)
    day0 = _day_zero(sol.departure_date)
    if flight is None:
        side.text(0.5, 0.5, "no 3-D flight (CVODES failed)", ha="center",
                  transform=side.transAxes)
    else:
        t = flight["t_days"]
        top.plot(flight["x_au"], flight["y_au"], color="tab:red", lw=1.2,
                 label="CVODES flight")
        side.plot(day0 + t, flight["z_au"], color="tab:red", lw=1.2, label="CVODES flight")
        starts = np.array([row.t_days for row in sol.schedule])
        x, y, z = (np.interp(starts, t, flight[k]) for k in ("x_au", "y_au", "z_au"))
        top.plot(x, y, "o", ms=3, color="k", label="segment starts")
        side.plot(day0 + starts, z, "o", ms=3, color="k", label="segment starts")
    _sun(top)
    side.axhline(0.0, color="0.3", lw=0.6)
    top.set_aspect("equal")
    top.set(xlabel="x (au)", ylabel="y (au)")
    side.set(xlabel=_time_axis(side, sol), ylabel="z (au)")
    fig.suptitle(headline(sol), fontsize=TRAJECTORY_TITLE_SIZE, parse_math=False)
    top.set_title("from above: the ecliptic plane of J2000", fontsize=9, y=1.0)
    side.set_title("from the side: height above the ecliptic", fontsize=9, y=1.0)
    _legend(top, sol)
    for ax in (top, side):
        ax.grid(alpha=0.3)
    if created:
        _fit_columns(fig, [top, side])
    return fig


# ----------------------------------------------------------------------------- timeline

#: The series panels: solution.json's sample fields and their y labels.
SERIES = {"r_au": "r (au)", "vr_km_s": "v_r (km/s)", "vtheta_km_s": "v_theta (km/s)",
          "a_au": "osculating a (au)", "e": "osculating e"}
#: The other panels' y labels.
PITCH_LABEL = "pitch alpha (deg)"
CLOCK_LABEL = "clock delta (deg)"
THRUST_LABEL = "thrust acceleration (mm/s²)"
INCLINATION_LABEL = "osculating i to ecliptic (deg)"
LOCAL_ERROR_LABEL = "closed-form local error (km)"
ROUNDS_LABEL = "position miss (km)"


def timeline_panels(sol):
    """The timeline's panels with data, in drawing order (two a row): pairs of the y label and
    ``draw(ax, sol)``; the pitch goes right, its throttle's axis at the figure's edge."""
    panels = [(label, functools.partial(_series, key=key)) for key, label in SERIES.items()]
    if three_d(sol) and _flight3d(sol) is not None:
        panels.append((INCLINATION_LABEL, _inclination_panel))
    attitude = [(CLOCK_LABEL, _clock_panel)] if three_d(sol) else []
    attitude.insert((len(panels) + 1) % 2, (PITCH_LABEL, _pitch_panel))
    local = [(LOCAL_ERROR_LABEL, _local_error_panel)] if _local_errors(sol) else []
    return panels + attitude + local + [(THRUST_LABEL, _thrust_panel)]


def _timeline_axes(count, rounds, throttled):
    """A new timeline figure and its Axes, placed by fixed margins: ``count`` panels two a row (an
    odd last one across both columns), then, with ``rounds``, the error-control rounds' strip across
    both.  ``throttled`` widens the right margin for the throttle's axis."""
    inch = TIMELINE_ROWS_IN
    rows = -(-count // 2)
    strip = inch["foot"] + inch["rounds"] if rounds else 0.0
    height = (inch["title"] + rows * inch["panel"] + (rows - 1) * inch["gap"]
              + inch["foot"] + strip)
    columns = dict(TIMELINE_COLUMNS)
    if throttled:
        columns["right"] = TIMELINE_RIGHT_WITH_THROTTLE
    fig = Figure(figsize=(10, height), dpi=DPI)
    grid = fig.add_gridspec(rows, 2, top=1 - inch["title"] / height,
                            bottom=(inch["foot"] + strip) / height,
                            hspace=inch["gap"] / inch["panel"], **columns)
    axes = [fig.add_subplot(grid[k // 2, k % 2]) for k in range(count - count % 2)]
    if count % 2:
        axes.append(fig.add_subplot(grid[rows - 1, :]))
    if rounds:
        below = fig.add_gridspec(1, 1, top=strip / height, bottom=inch["foot"] / height,
                                 left=columns["left"], right=columns["right"])
        axes.append(fig.add_subplot(below[0, 0]))
    return fig, axes


def timeline_figure(solution, axes=None):
    """The :func:`timeline_panels` against time, and under them the flown miss of each error-control
    round when there was more than one, into ``axes`` (one per panel, and one for the rounds) or a
    new figure (:func:`_timeline_axes`); returns the figure."""
    sol = solution
    panels = timeline_panels(sol)
    misses = _round_misses(sol)
    rounds = len(misses) > 1
    created = axes is None
    if created:
        fig, axes = _timeline_axes(len(panels), rounds, _throttled(_flown(sol).schedule))
    else:
        fig, axes = axes_or_new(axes)
        axes = list(np.ravel(axes))
    series = axes[:len(panels)]
    for ax in series[1:]:
        ax.sharex(series[0])
    time_label = _time_axis(series[0], sol)
    for ax, (label, draw) in zip(series, panels):
        draw(ax, sol)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    last_row = series[-(2 - len(panels) % 2):]
    for ax in series:
        if ax in last_row:
            ax.set_xlabel(time_label)
        else:
            # One shared time axis: dates under every row were most of the text to draw.
            ax.tick_params(labelbottom=False)
    if rounds:
        _rounds_panel(axes[len(panels)], sol, misses)
    _plain_legend(series[0].legend(fontsize=7))
    fig.suptitle(headline(sol), parse_math=False)
    if created:
        left = [ax for ax in axes if ax.get_subplotspec().colspan.start == 0]
        _fit_columns(fig, left, [ax for ax in axes if ax not in left])
    return fig


def _series(ax, sol, key):
    """One sample field of solution.json against time: the closed form, its CVODES
    flight, and the polished flight."""
    cf, cv, exact = sol.trajectory_closed_form, sol.trajectory_cvodes, sol.trajectory_polished
    day0 = _day_zero(sol.departure_date)
    ax.plot(day0 + np.asarray(cf.t_days, float), getattr(cf, key), color="tab:blue", lw=1.4,
            label="closed form")
    if cv is not None:
        ax.plot(day0 + np.asarray(cv.t_days, float), getattr(cv, key), color="tab:red",
                lw=0.9, ls="-.", label="CVODES")
    if exact is not None:
        ax.plot(_day_zero(_flown(sol).departure_date) + np.asarray(exact.t_days, float),
                getattr(exact, key), color="tab:purple", lw=1.0, ls=":",
                label="polished (CVODES)")


def _throttled(sched):
    """Whether a schedule has a throttle, which the pitch panel draws on its own axis."""
    return len(sched) > 0 and sched.throttled


def _steps(ax, sol, name, **style):
    """The flown schedule's column ``name`` as steps against time, held to the arrival;
    the shared time axis is set by the flights alone."""
    flown = _flown(sol)
    x = _day_zero(flown.departure_date) + np.array(
        [row.t_days for row in flown.schedule] + [flown.tof_days])
    y = [getattr(row, name) for row in flown.schedule]
    return ax.step(x, y + y[-1:], where="post", scalex=False, **style)


def _pitch_panel(ax, sol):
    """The pitch of the flown schedule and, on an axis of its own at the right, its
    throttle, if any: a coast (kappa = 0) explains a pitch that wanders."""
    _steps(ax, sol, "alpha_deg", color="k")
    ax.set_ylim(-95, 95)
    ax.set_yticks(range(-90, 91, 45))
    if _throttled(_flown(sol).schedule):
        twin = ax.twinx()
        _steps(twin, sol, "throttle", color="tab:orange", lw=1.0)
        twin.set_ylim(-0.05, 1.05)
        twin.set_ylabel("throttle kappa", color="tab:orange")


def _clock_panel(ax, sol):
    """The flown clock angle: 0 in the orbital plane, positive toward the angular momentum."""
    _steps(ax, sol, "clock_deg", color="k")
    ax.set_ylim(-190, 190)
    ax.set_yticks(range(-180, 181, 90))


def _thrust_panel(ax, sol):
    """The thrust acceleration along the flight that flies (:func:`thrust_acceleration`)."""
    t, a = thrust_acceleration(sol)
    ax.plot(_day_zero(_flown(sol).departure_date) + t, a, color="tab:brown", lw=1.0)
    ax.set_ylim(bottom=0.0)


def _inclination_panel(ax, sol):
    """The CVODES flight's osculating inclination to the ecliptic of J2000."""
    cv = sol.trajectory_cvodes
    ax.plot(_day_zero(sol.departure_date) + np.asarray(cv.t_days, float),
            cv.three_d["inclination_deg"], color="tab:red", lw=0.9, label="CVODES")


def _local_errors(sol):
    """Whether every segment of the closed form has its local error (error control)."""
    return len(sol.schedule) > 0 and all(row.local_error_km is not None for row in sol.schedule)


def _local_error_panel(ax, sol):
    """The closed form's position error over each segment from its own start node."""
    sched = sol.schedule
    x = _day_zero(sol.departure_date) + np.array([row.t_days for row in sched] + [sol.tof_days])
    errors = [row.local_error_km for row in sched]
    ax.step(x, errors + errors[-1:], where="post", color="tab:green",
            label=f"per segment, {sol.problem.sub_arcs} sub-arcs each")
    ax.set_yscale("log")
    _plain_log_labels(ax.yaxis)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)


def _round_misses(sol):
    """The flown miss (km) after each error-control round."""
    key = "target_miss_r_km" if sol.problem.target is not None else "miss_r_km"
    return [getattr(r, key) for r in sol.rounds if getattr(r, key) is not None]


def _rounds_panel(ax, sol, misses):
    """The flown miss after each error-control round, against the tolerance."""
    ax.semilogy(range(len(misses)), misses, "o-", color="tab:red", label="flown miss")
    _plain_log_labels(ax.yaxis)
    ax.axhline(sol.tolerance.position_km, color="k", ls="--", lw=0.8, label="tolerance")
    ax.set_xlabel("error-control round")
    ax.set_ylabel(ROUNDS_LABEL)
    ax.set_xticks(range(len(misses)))
    ax.set_xlim(-0.5, len(misses) - 0.5)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")


#: The figures every solution writes: each file's name and the function that draws it.
FIGURES = (("trajectory.png", trajectory_figure), ("timeline.png", timeline_figure))


def write_plots(solution, out_dir):
    """Draw the :data:`FIGURES` of ``solution`` one after the other and write each into
    ``out_dir`` atomically (:func:`write_figures`); returns what that returns."""
    return write_figures([(name, functools.partial(draw, solution)) for name, draw in FIGURES],
                         out_dir)


def write_figures(figures, out_dir):
    """Draw each of ``figures``, pairs (file name, ``make()`` returning a Figure), and write it into
    ``out_dir`` atomically at :data:`DPI`, one after the other; one that cannot be drawn (any
    exception but an OSError, which raises) is skipped.  Returns ``(written, failures)``: the Paths
    written, and one line per figure not drawn (:func:`figure_failure`)."""
    out = Path(out_dir)
    written, failures = [], []
    for name, make in figures:
        try:
            data = figure_bytes(make(), Path(name).suffix.lstrip("."), DPI)
        except OSError:
            raise
        except Exception as err:  # noqa: BLE001 - a figure's fault costs that figure only
            failures.append(figure_failure(name, err))
            continue
        with atomic_path(out / name) as tmp:
            tmp.write_bytes(data)
        written.append(out / name)
    return written, failures

