"""Plots of a :class:`~esail_opt.app.solution.Solution`, drawn from its record alone
(a solution loaded from its file plots as the fresh one did).

``trajectory.png``: the closed-form and CVODES trajectories in the ecliptic plane, with
the departure and target orbits and the segment boundaries.  ``timeline.png``: r, v_r,
v_theta, alpha_n (with the throttle kappa on a second axis when the problem has one) and
the osculating a and e against time, then the closed form's local error per segment
(where it is strained) and the flown miss of each error-control round against the
tolerance.
A polished solution adds the CVODES flight of its polished schedule to both, and the
pitch panel shows that schedule.

A solution flown in three dimensions (its schedule has a clock angle, solution.json
schema 5) draws ``trajectory.png`` from above and from the side (z against the days
since departure), the bodies on their unprojected tracks, and adds the clock angle and
the osculating inclination to ``timeline.png``.  Both 3-D views show the CVODES flight
in the ecliptic's Cartesian coordinates: the closed form's samples are polar in their own turning
plane, and the record holds no Cartesian form of them.

Every figure function here and in :mod:`esail_opt.app.reproduce` draws into the
caller's axes or, given none, into a Figure of its own made by :func:`axes_or_new`.
The figures are drawn in the calling process, one after the other, and saved by
matplotlib's own ``savefig`` (:func:`write_plots`).  Titles and legends, which hold the
names a user chose, are drawn as plain text, never parsed as math.  This module imports
matplotlib: the rest of the package imports it only when a figure is drawn.
"""

import functools
import re
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatterSciNotation

from esail_opt.app.files import atomic_path, figure_bytes


def axes_or_new(axes, nrows=1, ncols=1, figsize=None, margins=None, **subplots):
    """The figure of the caller's ``axes`` and those axes, or a new figure and its axes.

    The new figure is a bare :class:`matplotlib.figure.Figure`, made without
    pyplot: drawing it selects no backend and opens no window, and nothing holds
    it once its last reference goes.  Without ``margins`` it has constrained
    layout; with them its grid is placed by those margins and the figure is made at
    :data:`DPI`.  Constrained layout measures every label in both directions and
    then draws the figure a second time when it is saved, a second drawing of the
    two figures that every solve writes: those are placed by margins chosen for
    their fixed size and panels, with the left ones fitted by :func:`_fit_columns`.

    Parameters
    ----------
    axes : matplotlib.axes.Axes, array of Axes, or None
        Where to draw; None for a new figure.
    nrows, ncols, figsize, **subplots
        The new figure's grid, size (inches) and ``Figure.subplots`` options.
    margins : dict, optional
        ``left``, ``right``, ``bottom``, ``top``, ``wspace`` and ``hspace`` of the
        new figure's grid, as :meth:`matplotlib.figure.Figure.subplots_adjust` takes
        them (fractions of the figure); None for constrained layout.

    Returns
    -------
    fig : matplotlib.figure.Figure
        The top-level figure (the one to save).
    axes : matplotlib.axes.Axes or numpy.ndarray
        ``axes`` as given, or the new ones as ``Figure.subplots`` returns them.
    """
    if axes is not None:
        # An Axes' figure may be a SubFigure, whose .figure is the top-level Figure (a
        # Figure's is itself); Artist.get_figure(root=True) would need matplotlib 3.10.
        return np.ravel(axes)[0].figure.figure, axes
    if margins is None:
        fig = Figure(figsize=figsize, layout="constrained")
    else:
        fig = Figure(figsize=figsize, dpi=DPI)
        fig.subplots_adjust(**margins)
    return fig, fig.subplots(nrows, ncols, **subplots)


#: Where the trajectory's axes sit on its 6.4 in square (fractions of the figure):
#: room for the y tick labels and label on the left, the x ones below and a two-line
#: title above; the legend is inside.  Constrained layout chose about these.
TRAJECTORY_MARGINS = dict(left=0.106, right=0.993, bottom=0.094, top=0.925)

#: The timeline's columns on its 10 in width: room for the left column's y labels, and
#: between the columns for the right column's.
TIMELINE_COLUMNS = dict(left=0.067, right=0.987, wspace=0.185)
#: The timeline's right edge when the pitch panel carries the throttle's own axis.
TIMELINE_RIGHT_WITH_THROTTLE = 0.944
#: The six time series, three rows under the figure's title: the gap between two rows
#: holds a row's x tick labels.
TIMELINE_SERIES_ROWS = dict(top=0.955, bottom=0.3085, hspace=0.153)
#: The error panels' row, in a grid of its own so that the wider gap above it holds
#: the "t (days)" labels of the last series and the local error panel's title.
TIMELINE_ERROR_ROW = dict(top=0.2405, bottom=0.045)


#: The resolution the two figures are made and written at: the labels that
#: :func:`_fit_columns` measures are then not measured again when the figure is saved.
DPI = 150
#: Room kept left of a column's widest y labels, inches (constrained layout's pad).
LABEL_PAD_IN = 3 / 72


def _fit_columns(fig, axes):
    """Set the left margin, and the gap between the columns of ``axes`` (an array of
    rows of Axes whose grids share their columns), to the widest y labels of each column.

    A panel's y tick labels depend on its height only, which this leaves alone, so one
    measurement is final.  It is a small part of what constrained layout does to the
    same end (that measures both directions, then draws the whole figure once more),
    and margins fixed in advance would clip labels wider than the usual ones (a log
    axis under a decade reads 4×10⁰).
    """
    renderer = FigureCanvasAgg(fig).get_renderer()
    width = fig.bbox.width
    pad = LABEL_PAD_IN * fig.dpi / width

    def room(column):
        return pad + max(ax.get_window_extent(renderer).x0
                         - ax.yaxis.get_tightbbox(renderer).x0 for ax in column) / width

    axes = np.atleast_2d(axes)
    left = room(axes[:, 0])
    grids = {id(g): g for g in (ax.get_subplotspec().get_gridspec() for ax in axes[:, 0])}
    _fit_right(fig, renderer, grids.values(), pad, axes[:, -1])
    for grid in grids.values():
        if axes.shape[1] == 1:
            grid.update(left=left)
        else:
            gap = room(axes[:, 1])
            panel = (grid.get_subplot_params(fig).right - left - gap) / 2
            grid.update(left=left, wspace=gap / panel)
    # GridSpec.update moves the Axes of pyplot's figures only; these (twins too) are
    # moved here.
    for ax in fig.axes:
        spec = ax.get_subplotspec()
        if spec is not None and id(spec.get_gridspec()) in grids:
            ax.set_position(spec.get_position(fig))


def _fit_right(fig, renderer, grids, pad, right):
    """Move the right edge of ``grids`` left by as much as an x tick label of the Axes
    ``right`` (the right-hand column, the only ones whose labels can reach the edge)
    reaches past the figure's right edge less ``pad`` (a fraction of its width), and not
    at all when none does: the last label is centred on a panel's right end, and a time
    axis that ends at 1000 days puts half of its "1000" beyond a margin fixed for
    shorter ones."""
    width = fig.bbox.width
    boxes = [ax.xaxis.get_tightbbox(renderer) for ax in right]
    reach = max((box.x1 for box in boxes if box is not None), default=0.0) / width
    over = reach - (1 - pad)
    if over > 0:
        for grid in grids:
            grid.update(right=grid.get_subplot_params(fig).right - over)


#: The timeline's height with its three rows of series, inches.
TIMELINE_HEIGHT_IN = 10.5


def _timeline_rows(rows):
    """The series' and the error row's grids for ``rows`` rows of series, and the
    figure's height: each row of series as tall as in the three-row timeline, and the
    margins and the error row as many inches as there."""
    h = TIMELINE_HEIGHT_IN
    top, bottom, space = (TIMELINE_SERIES_ROWS[k] for k in ("top", "bottom", "hspace"))
    panel = (top - bottom) * h / (3 + 2 * space)
    height = h + (rows - 3) * panel * (1 + space)
    series = dict(top=1 - (1 - top) * h / height, bottom=bottom * h / height, hspace=space)
    errors = {k: v * h / height for k, v in TIMELINE_ERROR_ROW.items()}
    return series, errors, height


def _timeline_axes(throttled, rows=3):
    """A new timeline figure and its (``rows`` + 1) x 2 array of Axes, placed once by
    fixed margins (see :func:`axes_or_new` on why not constrained layout); ``throttled``
    widens the right margin for the throttle's axis."""
    columns = dict(TIMELINE_COLUMNS)
    if throttled:
        columns["right"] = TIMELINE_RIGHT_WITH_THROTTLE
    series_rows, error_row, height = _timeline_rows(rows)
    fig = Figure(figsize=(10, height), dpi=DPI)
    series = fig.add_gridspec(rows, 2, **columns, **series_rows).subplots()
    errors = fig.add_gridspec(1, 2, **columns, **error_row).subplots(squeeze=False)
    return fig, np.vstack([series, errors])


#: Digits and minus as Unicode superscripts, for :class:`PlainLogFormatter`.
_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075"
                             "\u2076\u2077\u2078\u2079")
_MATHDEFAULT = re.compile(r"\$\\mathdefault\{(.*)\}\$")
_EXPONENT = re.compile(r"\^\{(-?\d+)\}")


class PlainLogFormatter(LogFormatterSciNotation):
    """The tick labels of matplotlib's log axes (the same ticks labelled, the same
    ``10^k`` and ``c x 10^k``), written with Unicode superscripts instead of mathtext.

    Mathtext's parser is built and run once per process for each new label, which
    cost a solve's timeline a noticeable part of its drawing time; DejaVu Sans, the
    default font, has every superscript used here, so the labels read the same.
    """

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)
        match = _MATHDEFAULT.fullmatch(label)
        if match is None:
            return label
        plain = match.group(1).replace(r"\times", "\u00d7")
        plain = _EXPONENT.sub(lambda m: m.group(1).translate(_SUPERSCRIPT), plain)
        return plain[:1].replace("-", "\u2212") + plain[1:]


def _plain_log_labels(axis):
    """Label a log ``axis`` with :class:`PlainLogFormatter` where matplotlib's log scale
    would label it: its decades, and its minor ticks on an axis that spans too few
    decades to show more than one."""
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


def _xy(r_au, theta_deg):
    r = np.asarray(r_au, float)
    th = np.radians(np.asarray(theta_deg, float))
    return r * np.cos(th), r * np.sin(th)


def _samples_xy(samples):
    return _xy(samples.r_au, samples.theta_deg)


def _draw_bodies(ax, sol):
    """The departure and target bodies on their real orbits over the flight (ephemeris
    or elements, projected on the ecliptic), each at the departure and at the arrival."""
    from esail_opt.bodies import lookup

    start, jd, pairs = _flight_bodies(sol)
    for label, body, colour in pairs:
        # The projection on the ecliptic is the ecliptic x and y, read for all the dates
        # in one call (the polar states put theta on the track's branch, one by one).
        x, y = lookup.ecliptic_state(lookup.resolve(body), jd)[:2]
        ax.plot(x, y, color=colour, lw=0.8, ls="--", label=f"{label} over the flight")
        ax.plot(x[[0, -1]], y[[0, -1]], "o", color=colour, ms=4)


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
        _draw_bodies(ax, sol)
    elif tgt is not None:
        if tgt.kind == "Orbit":
            # The apse line is free: draw the circle of radius a as a guide.
            xy = _orbit_xy(tgt.a_au, 0.0)
            label = f"target a = {tgt.a_au} au (e = {tgt.e}, free apse line)"
        else:
            xy = _orbit_xy(tgt.radius_au, 0.0)
            label = "target orbit"
        ax.plot(*xy, color="tab:green", lw=0.8, ls="--", label=label)


def trajectory_figure(solution, ax=None):
    """The trajectory in the plane (au), closed form and CVODES, with orbits and nodes;
    a solution flown in three dimensions is drawn by :func:`_trajectory3d_figure`.

    Drawn into ``ax`` if given (in 3-D a pair of Axes: from above, from the side), else
    into a new figure; returns the figure.
    """
    sol = solution
    if three_d(sol):
        return _trajectory3d_figure(sol, ax)
    prob = sol.problem
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
    ax.plot([0], [0], "*", color="orange", ms=12)
    ax.set_aspect("equal")
    ax.set_xlabel("x (au)")
    ax.set_ylabel("y (au)")
    title = f"{prob.name}: tof {sol.tof_days:.1f} d, {sol.status}"
    if sol.tof_days_exact is not None:
        title += f"\npolished: tof {sol.tof_days_exact:.2f} d, {sol.polish.status}"
    # A title at a given height is not moved clear of ticks above the axes (there are
    # none): matplotlib skips measuring the y axis for it, once per title and draw.
    ax.set_title(title, y=1.0, parse_math=False)
    _plain_legend(ax.legend(fontsize=7, loc="upper right"))
    ax.grid(alpha=0.3)
    if created:
        _fit_columns(fig, [[ax]])
    return fig


# ------------------------------------------------------------------- in three dimensions


def three_d(sol):
    """Whether ``sol`` was flown in three dimensions: its schedule has a clock angle
    (solution.json's ``clock_deg``, schema 5)."""
    return len(sol.schedule) > 0 and sol.schedule[0].clock_deg is not None


def _flight3d(sol):
    """The CVODES flight's Cartesian samples (``Samples.three_d``) as float arrays, with
    its ``t_days``; None when the flight failed.  The closed form's samples are polar in
    their own turning plane and have no place in the ecliptic's frame, so the 3-D views
    show the CVODES flight (a verified one is within the tolerance
    of the closed form's nodes)."""
    cv = sol.trajectory_cvodes
    if cv is None or cv.three_d is None:
        return None
    out = {k: np.asarray(v, float) for k, v in cv.three_d.items()}
    out["t_days"] = np.asarray(cv.t_days, float)
    return out


#: Where the 3-D trajectory's two views sit on their 6.4 x 9 in figure (fractions):
#: from above, square, and under it from the side, z against time.
TRAJECTORY3D_SIZE = (6.4, 9.0)
TRAJECTORY3D_MARGINS = dict(left=0.12, right=0.965, bottom=0.06, top=0.945, hspace=0.2)
TRAJECTORY3D_HEIGHTS = (3.0, 1.15)


def _trajectory3d_figure(sol, axes=None):
    """A 3-D solution's path from above (x, y: the ecliptic of J2000) and from the side
    (z against the time since departure, days), with the bodies' real 3-D tracks over the
    flight and the segment starts (the CVODES samples at the schedule's start times)."""
    created = axes is None
    if created:
        fig = Figure(figsize=TRAJECTORY3D_SIZE, dpi=DPI)
        fig.subplots_adjust(**TRAJECTORY3D_MARGINS)
        top, side = fig.subplots(2, 1, height_ratios=TRAJECTORY3D_HEIGHTS)
    else:
        fig, (top, side) = axes_or_new(axes)
    _draw_bodies3d(top, side, sol)
    flight = _flight3d(sol)
    if flight is None:
        side.text(0.5, 0.5, "no 3-D flight (CVODES failed)", ha="center",
                  transform=side.transAxes)
    else:
        t = flight["t_days"]
        top.plot(flight["x_au"], flight["y_au"], color="tab:red", lw=1.2,
                 label="CVODES flight")
        side.plot(t, flight["z_au"], color="tab:red", lw=1.2, label="CVODES flight")
        starts = [row.t_days for row in sol.schedule]
        x, y, z = (np.interp(starts, t, flight[k]) for k in ("x_au", "y_au", "z_au"))
        top.plot(x, y, "o", ms=3, color="k", label="segment starts")
        side.plot(starts, z, "o", ms=3, color="k", label="segment starts")
    top.plot([0], [0], "*", color="orange", ms=12)
    side.axhline(0.0, color="0.3", lw=0.6)
    top.set_aspect("equal")
    top.set(xlabel="x (au)", ylabel="y (au)")
    side.set(xlabel="t since departure (days)", ylabel="z (au)")
    title = f"{sol.problem.name}: tof {sol.tof_days:.1f} d, {sol.status}, in 3-D"
    top.set_title(title + "\nfrom above: the ecliptic of J2000", y=1.0, parse_math=False)
    side.set_title("from the side: height above the ecliptic", fontsize=9, y=1.0)
    _plain_legend(top.legend(fontsize=7, loc="upper right"))
    for ax in (top, side):
        ax.grid(alpha=0.3)
    if created:
        _fit_columns(fig, [[top], [side]])
    return fig


def _draw_bodies3d(top, side, sol):
    """The departure and target bodies on their real 3-D states over the flight (DE421
    unprojected, or a small body's six elements): x, y from above, z against time from
    the side, each marked at the departure and at the arrival."""
    from esail_opt.bodies import lookup

    if not sol.dated:
        return
    start, jd, pairs = _flight_bodies(sol)
    for label, body, colour in pairs:
        x, y, z = lookup.ecliptic_state(lookup.resolve(body), jd)[:3]
        t = jd - start
        for ax, (u, v) in ((top, (x, y)), (side, (t, z))):
            ax.plot(u, v, color=colour, lw=0.8, ls="--", label=f"{label} over the flight")
            ax.plot(u[[0, -1]], v[[0, -1]], "o", color=colour, ms=4)


def _pitch_schedule(sol, polished):
    """The schedule that the pitch panel shows: the polished one when there is one."""
    return sol.polish.schedule if polished else sol.schedule


def _throttled(sched):
    """Whether a schedule has a throttle, which the pitch panel draws on its own axis."""
    return len(sched) > 0 and sched.throttled


def _pitch_axes(ax, throttled):
    """The pitch panel's axes, and the throttle's on its right when the problem has
    one (returned; else None): what :func:`_pitch_steps` draws into."""
    ax.set_ylim(-95, 95)
    if not throttled:
        return None
    # The throttle shares the pitch panel: it switches at the same times, and a coast
    # (kappa = 0) explains a pitch that wanders.
    twin = ax.twinx()
    twin.set_ylim(-0.05, 1.05)
    twin.set_ylabel("throttle kappa", color="tab:orange")
    return twin


def _pitch_steps(ax, twin, sol, polished):
    """The pitch schedule (the polished one when there is one) as steps against time,
    and the throttle's into ``twin``; returns their lines.  The time axis is the
    series' (shared), set by the closed form's flights alone: a polished schedule ends a
    hair away."""
    sched = _pitch_schedule(sol, polished)
    t = [row.t_days for row in sched]
    alpha = [row.alpha_deg for row in sched]
    t_end = sol.tof_days_exact if polished else sol.tof_days
    lines = ax.step(t + [t_end], alpha + alpha[-1:], where="post", color="k", scalex=False,
                    label="polished" if polished else None)
    if twin is not None:
        kappa = [row.throttle for row in sched]
        lines += twin.step(t + [t_end], kappa + kappa[-1:], where="post", color="tab:orange",
                           lw=1.0, scalex=False)
    return lines


#: The five series panels (solution.json's sample fields) and the pitch panel (None),
#: in the order of the timeline's axes.
TIMELINE_PANELS = (("r_au", "r (au)"), ("vr_km_s", "v_r (km/s)"),
                   ("vtheta_km_s", "v_theta (km/s)"), (None, "alpha (deg)"),
                   ("a_au", "osculating a (au)"), ("e", "osculating e"))


def timeline_figure(solution, axes=None):
    """r, v_r, v_theta, alpha and osculating a and e against time (days), then the local
    errors and the error-control rounds.  A solution flown in three dimensions adds a
    row: the clock angle per segment and the CVODES flight's osculating inclination to
    the ecliptic (r, v_r and v_theta are then those of the flight's own turning plane).

    Drawn into ``axes`` (a 4 x 2 array of Axes, 5 x 2 in 3-D) if given, else into a new
    figure placed by fixed margins (:func:`_timeline_axes`); returns the figure.

    Each series panel's limits span every flight it shows, with matplotlib's margins.
    """
    sol = solution
    created = axes is None
    throttled = _throttled(sol.schedule)
    rows = 4 if three_d(sol) else 3
    fig, axes = _timeline_axes(throttled, rows) if created else axes_or_new(axes)
    for ax in axes[:rows].ravel():
        ax.sharex(axes[0, 0])
    # With a polish, the pitch panel shows the polished schedule: the one that flies.
    polished = sol.trajectory_polished is not None
    for ax, (key, label) in zip(axes.ravel(), TIMELINE_PANELS):
        if key is None:
            _pitch_steps(ax, _pitch_axes(ax, throttled), sol, polished)
        else:
            _series(ax, sol, key)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    if rows == 4:
        _clock_panel(axes[3, 0], sol)
        _inclination_panel(axes[3, 1], sol)
    for ax in axes[rows - 1]:
        ax.set_xlabel("t (days)")
    _local_error_panel(axes[rows, 0], sol)
    _error_control_panel(axes[rows, 1], sol)
    _plain_legend(axes[0, 0].legend(fontsize=7))
    verdict = "verified" if sol.flight_verified else "NOT verified"
    fig.suptitle(f"{sol.problem.name}: {sol.status}, {verdict}"
                 + (f"; polished {sol.polish.status} (pitch: polished schedule)"
                    if polished else ""), parse_math=False)
    if created:
        _fit_columns(fig, axes)
    return fig


#: The clock panel's and the inclination panel's y labels (3-D timelines).
CLOCK_LABEL = "clock delta (deg)"
INCLINATION_LABEL = "osculating i to ecliptic (deg)"


def _clock_panel(ax, sol):
    """The clock angle per segment as steps against time, held to the arrival as the
    pitch is; 0 is in the orbital plane, positive toward the angular momentum."""
    sched = sol.schedule
    t = [row.t_days for row in sched] + [sol.tof_days]
    clock = [row.clock_deg for row in sched]
    ax.step(t, clock + clock[-1:], where="post", color="k", scalex=False)
    ax.set_ylim(-190, 190)
    ax.set_yticks(range(-180, 181, 90))
    ax.set_ylabel(CLOCK_LABEL)


def _inclination_panel(ax, sol):
    """The CVODES flight's osculating inclination to the ecliptic of J2000."""
    cv = sol.trajectory_cvodes
    if cv is None or cv.three_d is None:
        ax.text(0.5, 0.5, "no 3-D flight (CVODES failed)", ha="center",
                transform=ax.transAxes)
    else:
        ax.plot(cv.t_days, cv.three_d["inclination_deg"], color="tab:red", lw=0.9,
                label="CVODES")
    ax.set_ylabel(INCLINATION_LABEL)


def _series(ax, sol, key):
    """One sample field of solution.json against time: the closed form, its CVODES
    flight, and the polished flight."""
    cf, cv, exact = sol.trajectory_closed_form, sol.trajectory_cvodes, sol.trajectory_polished
    ax.plot(cf.t_days, getattr(cf, key), color="tab:blue", lw=1.4, label="closed form")
    if cv is not None:
        ax.plot(cv.t_days, getattr(cv, key), color="tab:red", lw=0.9, ls="-.", label="CVODES")
    if exact is not None:
        ax.plot(exact.t_days, getattr(exact, key), color="tab:purple", lw=1.0, ls=":",
                label="polished (CVODES)")


def _local_error_panel(ax, sol):
    """The closed form's position error over each segment from its own start node."""
    sched = sol.schedule
    errors = [row.local_error_km for row in sched]
    if not len(sched) or any(e is None for e in errors):
        ax.text(0.5, 0.5, "no local errors (no error control)", ha="center",
                transform=ax.transAxes)
        return
    t = [row.t_days for row in sched] + [sol.tof_days]
    ax.step(t, errors + errors[-1:], where="post", color="tab:green")
    ax.set_yscale("log")
    _plain_log_labels(ax.yaxis)
    ax.set_xlabel("t (days)")
    ax.set_ylabel("closed-form local error (km)")
    ax.set_title(f"per segment, {sol.problem.sub_arcs} sub-arcs each", fontsize=9, y=1.0)
    ax.grid(alpha=0.3, which="both")


def _error_control_panel(ax, sol):
    """The flown miss after each error-control round, against the tolerance."""
    key = "target_miss_r_km" if sol.problem.target is not None else "miss_r_km"
    misses = [getattr(r, key) for r in sol.rounds if getattr(r, key) is not None]
    if not misses:
        ax.text(0.5, 0.5, "no flight to judge", ha="center", transform=ax.transAxes)
        return
    ax.semilogy(range(len(misses)), misses, "o-", color="tab:red", label="flown miss")
    _plain_log_labels(ax.yaxis)
    ax.axhline(sol.tolerance.position_km, color="k", ls="--", lw=0.8, label="tolerance")
    ax.set_xlabel("error-control round")
    ax.set_ylabel("position miss (km)")
    ax.set_xticks(range(len(misses)))
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
    """Draw each of ``figures``, pairs (file name, ``make()`` returning a Figure), and
    write it into ``out_dir`` atomically, at :data:`DPI`, one after the other.

    A figure that cannot be made or drawn (any exception but an OSError, which is the
    disk's and raises) is skipped, and the others are still written.

    Returns
    -------
    written : list of Path
        The files written.
    failures : list of str
        One line per figure that could not be drawn (:func:`figure_failure`).
    """
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


def _flight_bodies(sol):
    """The departure date (JD), 200 dates over the flight, and (label, body, colour) of
    the departure and target bodies, which both trajectory views draw."""
    from esail_opt.bodies import dates

    prob = sol.problem
    start, end = (dates.jd_from_iso(d) for d in (sol.departure_date, sol.arrival_date))
    pairs = [(sol.departure_body.name, prob.departure.body, "0.5")]
    if sol.target_body is not None:
        pairs.append((sol.target_body.name, prob.target.body, "tab:green"))
    return start, np.linspace(start, end, 200), pairs
