"""The two figures of a solve: their panels, curves, limits, labels and legends, a layout
in which nothing is clipped or overlaps, names drawn as written, and what the command
writes and says when a figure cannot be drawn (`solve`, `solve --no-plots`, `plot`)."""

import copy
import csv
import io
import json
import re
import shutil
from datetime import datetime, timedelta

import matplotlib.dates as mdates
import numpy as np
import pytest
from conftest import RESULTS, TINY_PROBLEM
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import esail_opt as eo
from esail_opt.app import plots, schema
from esail_opt.app.solution import Solution

DIGITS = str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789")
SERIES = ["r (au)", "v_r (km/s)", "v_theta (km/s)", "osculating a (au)", "osculating e"]
#: An Ipopt status as Ipopt spells it (Solve_Succeeded, Maximum_Iterations_Exceeded).
IPOPT_STATUS = re.compile(r"[A-Z][a-z]+_[A-Z][a-z]+")


@pytest.fixture(scope="module")
def polished():
    problem = eo.Problem("tiny", eo.ParkingOrbit(1.0), eo.Sail(1.0), eo.Segments(6, 2),
                         eo.MinTime(), eo.CircularOrbit(0.723))
    return eo.solve(problem, polish=True)


@pytest.fixture(scope="module")
def flown3d():
    """A fixed-date Earth-Mars rendezvous flown in three dimensions (``planar=False``),
    on few segments: a schema-7 solution with a clock per segment and CVODES
    samples in the ecliptic's frame."""
    problem = eo.Problem("em3d", eo.BodyDeparture(body="earth", date="2031-01-01"),
                         eo.Sail(1.0), eo.Segments(6, 1), eo.MinTime(),
                         eo.BodyRendezvous(body="mars"), planar=False)
    assert problem.three_d()
    sol = eo.solve(problem)
    assert sol.verified, sol.verification_note
    return sol


@pytest.fixture(scope="module")
def throttled(polished):
    """The same data with a throttle in both schedules, as a throttled problem writes it."""
    data = copy.deepcopy(polished.to_json())
    for rows in (data["schedule"], data["polish"]["schedule"]):
        for k, row in enumerate(rows):
            row["throttle"] = 1.0 if k % 2 == 0 else 0.0
    return Solution.from_json(data)


@pytest.fixture(scope="module")
def narrow(polished):
    """The same data with local errors within one decade, where matplotlib labels the
    log axis's minor ticks too (4×10⁰): wider labels than the decades'."""
    data = copy.deepcopy(polished.to_json())
    rows = data["schedule"]
    for k, row in enumerate(rows):
        row["local_error_km"] = 0.6 + 3.4 * k / max(len(rows) - 1, 1)
    return Solution.from_json(data)


def _drawn(fig):
    FigureCanvasAgg(fig).draw()
    return fig.canvas.get_renderer()


def _labels(ax):
    return [line.get_label() for line in ax.get_legend().get_lines()] \
        if ax.get_legend() is not None else []


def _inside(box, fig):
    # A pixel of slack: matplotlib rounds extents to whole pixels.
    return (box.x0 >= -1 and box.y0 >= -1 and box.x1 <= fig.bbox.x1 + 1
            and box.y1 <= fig.bbox.y1 + 1)


def test_trajectory_has_its_curves_labels_and_legend(polished):
    d = polished.to_json()
    fig = plots.trajectory_figure(polished)
    (ax,) = fig.axes
    assert _labels(ax) == ["departure orbit", "target orbit", "closed form (NLP)",
                           "CVODES (Eqs. 1-2)", "polished, CVODES (Eqs. 1-2)",
                           "segment starts", "Sun"]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (au)", "y (au)")
    assert ax.get_title() == ("tiny: closed form verified, polished verified\n"
                              f"time of flight {d['tof_days_exact']:.2f} days, a_c 1 mm/s²")
    lines = {line.get_label(): line for line in ax.get_lines()}
    cf = d["trajectory"]["closed_form"]
    theta = np.radians(cf["theta_deg"])
    x, y = lines["closed form (NLP)"].get_data()
    np.testing.assert_allclose(x, np.multiply(cf["r_au"], np.cos(theta)), rtol=0, atol=1e-15)
    np.testing.assert_allclose(y, np.multiply(cf["r_au"], np.sin(theta)), rtol=0, atol=1e-15)
    assert len(lines["segment starts"].get_xdata()) == len(d["schedule"])
    # The target circle of radius 0.723 au, the departure one of 1 au.
    tx, ty = lines["target orbit"].get_data()
    np.testing.assert_allclose(np.hypot(tx, ty), 0.723, rtol=1e-12)
    dx, dy = lines["departure orbit"].get_data()
    np.testing.assert_allclose(np.hypot(dx, dy), 1.0, rtol=1e-12)


def _rows(fig, twins=()):
    """The figure's panels read row by row, left to right, twins left out."""
    return sorted((ax for ax in fig.axes if ax not in twins),
                  key=lambda ax: (-round(ax.get_position().y0, 3), ax.get_position().x0))


@pytest.mark.parametrize("which", ["polished", "throttled"])
def test_timeline_has_its_panels_curves_and_labels(which, request):
    sol = request.getfixturevalue(which)
    d = sol.to_json()
    assert len(d["refinement"]["rounds"]) == 1  # no rounds' panel: one dot is no data
    fig = plots.timeline_figure(sol)
    twins = [ax for ax in fig.axes if ax.get_ylabel() == "throttle kappa"]
    assert len(twins) == (1 if which == "throttled" else 0)
    panels = _rows(fig, twins)
    assert [ax.get_ylabel() for ax in panels] == SERIES + [
        plots.PITCH_LABEL, plots.LOCAL_ERROR_LABEL, plots.THRUST_LABEL]
    for ax in panels[:5]:
        assert [line.get_label() for line in ax.get_lines()] == [
            "closed form", "CVODES", "polished (CVODES)"]
    # The polished schedule's pitch, held to the polished time of flight.
    (step,) = panels[5].get_lines()
    alphas = [row["alpha_deg"] for row in d["polish"]["schedule"]]
    np.testing.assert_array_equal(step.get_ydata(), alphas + alphas[-1:])
    assert step.get_xdata()[-1] == d["tof_days_exact"]
    assert panels[5].get_position().x0 > 0.5  # the pitch (and its throttle) on the right
    assert _labels(panels[0]) == ["closed form", "CVODES", "polished (CVODES)"]
    assert [ax.get_xlabel() for ax in panels] == [""] * 6 + [plots.DAYS_LABEL] * 2
    assert panels[6].get_yscale() == "log"
    assert "polished" in fig._suptitle.get_text()
    if twins:
        kappa = [row["throttle"] for row in d["polish"]["schedule"]]
        np.testing.assert_array_equal(twins[0].get_lines()[0].get_ydata(), kappa + kappa[-1:])


def test_timeline_limits_hold_the_closed_form_and_its_flight(polished):
    """Each series panel spans its closed-form, CVODES and polished samples with
    matplotlib's 5 % margins, the time axis the whole flight, the pitch panel [-90, 90]
    deg."""
    d = polished.to_json()
    flights = [d["trajectory"][key] for key in ("closed_form", "cvodes", "polished")]
    fig = plots.timeline_figure(polished)
    panels = {ax.get_ylabel(): ax for ax in fig.axes}
    low, high = panels[plots.PITCH_LABEL].get_ylim()
    assert low <= -90 and high >= 90
    for key, label in plots.SERIES.items():
        ax = panels[label]
        low, high = ax.get_ylim()
        values = np.concatenate([flight[key] for flight in flights])
        span = values.max() - values.min()
        assert low == pytest.approx(values.min() - 0.05 * span, rel=1e-9, abs=1e-12)
        assert high == pytest.approx(values.max() + 0.05 * span, rel=1e-9, abs=1e-12)
    t = np.concatenate([flight["t_days"] for flight in flights])
    low, high = panels["r (au)"].get_xlim()
    assert low == pytest.approx(t.min() - 0.05 * np.ptp(t), abs=1e-9)
    assert high == pytest.approx(t.max() + 0.05 * np.ptp(t), rel=1e-12)


@pytest.fixture(scope="module")
def two_rounds(polished):
    """The same data with two error-control rounds, the second within the tolerance,
    and without local errors (as a file of another segment method would be)."""
    data = copy.deepcopy(polished.to_json())
    rounds = data["refinement"]["rounds"]
    rounds.append(dict(rounds[0], round=1, target_miss_r_km=rounds[0]["target_miss_r_km"] / 1e4))
    for row in data["schedule"]:
        del row["local_error_km"]
    return Solution.from_json(data)


@pytest.mark.parametrize("which", ["polished", "throttled", "narrow", "flown3d",
                                   "planar_mars", "two_rounds"])
def test_nothing_is_clipped_or_overlapping(which, request):
    sol = request.getfixturevalue(which)
    for fig in (plots.trajectory_figure(sol), plots.timeline_figure(sol)):
        renderer = _drawn(fig)
        boxes = {ax: ax.get_tightbbox(renderer) for ax in fig.axes}
        for ax, box in boxes.items():
            assert _inside(box, fig), (ax.get_ylabel(), box, fig.bbox)
        if fig._suptitle is not None:
            title = fig._suptitle.get_window_extent(renderer)
            assert _inside(title, fig)
            assert not any(title.overlaps(ax.get_window_extent()) for ax in fig.axes)
        # Each panel with its tick labels and axis labels keeps clear of every other
        # panel's frame (a twin shares its panel's frame and is left out).
        frames = [ax for ax in fig.axes if ax.get_ylabel() != "throttle kappa"]
        for ax in fig.axes:
            for other in frames:
                if other is ax or other.get_position().bounds == ax.get_position().bounds:
                    continue
                assert not boxes[ax].overlaps(other.get_window_extent()), (
                    ax.get_ylabel(), other.get_ylabel())


@pytest.mark.parametrize("which", ["polished", "flown3d", "planar_mars"])
def test_the_legend_hides_none_of_the_flight(which, request):
    """The trajectory's legend sits in a corner clear of the flight: no drawn point of
    the flown curve (sampled along its length on the page) falls inside the legend's box
    as matplotlib lays it out."""
    sol = request.getfixturevalue(which)
    fig = plots.trajectory_figure(sol)
    renderer = _drawn(fig)
    ax = fig.axes[0]
    box = ax.get_legend().get_window_extent(renderer)
    flown = [line for line in ax.get_lines() if line.get_label() in (FLOWN, CLOSED_FORM)]
    assert flown
    for line in flown:
        xy = ax.transData.transform(line.get_xydata())
        fine = np.linspace(0, len(xy) - 1, 20 * len(xy))
        xs, ys = (np.interp(fine, np.arange(len(xy)), xy[:, k]) for k in (0, 1))
        assert not np.any((xs > box.x0) & (xs < box.x1) & (ys > box.y0) & (ys < box.y1))


# ---------------------------------------------------------------- in three dimensions

AU_KM = 149597870.7  # written out again here, not taken from the package
FLOWN = "CVODES flight"
CLOSED_FORM = "closed form (NLP)"


def _lines(ax):
    return {line.get_label(): line for line in ax.get_lines()}


@pytest.fixture(scope="module")
def planar_mars():
    """The 3-D fixture's problem with ``planar=True``: a real-body problem in the
    ecliptic projection."""
    problem = eo.Problem("em2d", eo.BodyDeparture(body="earth", date="2031-01-01"),
                         eo.Sail(1.0), eo.Segments(6, 1), eo.MinTime(),
                         eo.BodyRendezvous(body="mars"), planar=True)
    assert not problem.three_d()
    return eo.solve(problem)


@pytest.mark.parametrize("which", ["polished", "planar_mars"])
def test_planar_figures_keep_their_axes(which, request):
    """A planar solution has no clock: one trajectory view, and the timeline's eight
    panels (none of them the clock or the inclination), and the rounds' when there
    were more than one."""
    sol = request.getfixturevalue(which)
    assert not plots.three_d(sol)
    assert len(plots.trajectory_figure(sol).axes) == 1
    labels = [ax.get_ylabel() for ax in plots.timeline_figure(sol).axes]
    rounds = len(sol.rounds) > 1
    assert len(labels) == 8 + rounds and set(SERIES) <= set(labels)
    assert (plots.ROUNDS_LABEL in labels) == rounds
    assert plots.CLOCK_LABEL not in labels and plots.INCLINATION_LABEL not in labels


def test_trajectory_in_3d_shows_the_flight_from_above_and_from_the_side(flown3d):
    """The top view is the CVODES flight's x, y and the side view its z (au) against its
    date; the bodies' tracks start and end where the verified flight does (the
    departure is the Earth's state, the rendezvous meets Mars within the tolerance),
    marked there and so named in the legend."""
    d = flown3d.to_json()
    cv = d["trajectory"]["cvodes"]
    assert d["schema_version"] == schema.SCHEMA_VERSION and d["time_scale"] == "TDB"
    fig = plots.trajectory_figure(flown3d)
    top, side = fig.axes
    assert (top.get_xlabel(), top.get_ylabel()) == ("x (au)", "y (au)")
    assert (side.get_xlabel(), side.get_ylabel()) == (plots.DATE_LABEL, "z (au)")
    assert fig._suptitle.get_text().startswith("em3d in 3-D: verified\n")
    assert top.get_title().startswith("from above")
    assert side.get_title().startswith("from the side")
    x, y = _lines(top)[FLOWN].get_data()
    np.testing.assert_array_equal(x, cv["x_au"])
    np.testing.assert_array_equal(y, cv["y_au"])
    t, z = _lines(side)[FLOWN].get_data()
    np.testing.assert_allclose(t - _day_number("2031-01-01"), cv["t_days"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(z, cv["z_au"])
    assert np.ptp(z) * AU_KM > 1e6  # Mars's plane is 1.85 deg off: the flight leaves the ecliptic
    assert len(_lines(side)["segment starts"].get_xdata()) == len(d["schedule"])
    miss_au = d["tolerance"]["position_km"] / AU_KM
    for ax in (top, side):
        earth, mars = (_lines(ax)[f"{b} over the flight"].get_data() for b in ("earth", "mars"))
        flight = _lines(ax)[FLOWN].get_data()
        for body, end, bound in ((earth, 0, 1e-9), (mars, -1, miss_au)):
            assert abs(body[0][end] - flight[0][end]) <= bound
            assert abs(body[1][end] - flight[1][end]) <= bound
    assert abs(_lines(side)["mars over the flight"].get_xdata()[-1]
               - _day_number(d["arrival_date"])) < 1e-6
    _assert_marked_bodies(top, d)


def test_timeline_in_3d_adds_the_clock_and_the_inclination(flown3d):
    """Two panels more than the planar timeline: the clock's steps are schedule.csv's
    clock_deg held to the arrival, the inclination the CVODES samples'."""
    d = flown3d.to_json()
    fig = plots.timeline_figure(flown3d)
    panels = {ax.get_ylabel(): ax for ax in fig.axes}
    assert len(fig.axes) == 10 + (len(d["refinement"]["rounds"]) > 1)
    assert set(SERIES) <= set(panels)
    clock_rows = [float(row["clock_deg"]) for row in
                  csv.DictReader(io.StringIO(flown3d.schedule_csv()))]
    (step,) = panels[plots.CLOCK_LABEL].get_lines()
    day0 = _day_number("2031-01-01")
    np.testing.assert_array_equal(step.get_ydata(), clock_rows + clock_rows[-1:])
    np.testing.assert_allclose(step.get_xdata() - day0, [row["t_days"] for row in d["schedule"]]
                               + [d["tof_days"]], rtol=0, atol=1e-9)
    (incl,) = panels[plots.INCLINATION_LABEL].get_lines()
    cv = d["trajectory"]["cvodes"]
    np.testing.assert_allclose(incl.get_xdata() - day0, cv["t_days"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(incl.get_ydata(), cv["inclination_deg"])
    series = [ax for ax in _rows(fig) if ax.get_ylabel() != plots.ROUNDS_LABEL]
    assert [ax.get_ylabel() for ax in series[-4:]] == [
        plots.CLOCK_LABEL, plots.PITCH_LABEL, plots.LOCAL_ERROR_LABEL, plots.THRUST_LABEL]
    assert [ax.get_xlabel() for ax in series[-2:]] == [plots.DATE_LABEL] * 2


def test_plot_redraws_a_3d_solution_from_its_file(flown3d, tmp_path, capsys):
    """`esail-opt plot` on a folder whose solution.json is schema 7 draws both figures,
    in 3-D as the fresh solution's."""
    from esail_opt.app import cli

    folder = tmp_path / "run"
    flown3d.write(folder, plots=False)
    written = json.loads((folder / "solution.json").read_text())
    assert written["schema_version"] == schema.SCHEMA_VERSION
    assert cli.main(["plot", str(folder)]) == 0
    for name, _ in plots.FIGURES:
        assert (folder / name).stat().st_size > 10_000
    loaded = Solution.load(folder / "solution.json")
    top, side = plots.trajectory_figure(loaded).axes
    np.testing.assert_array_equal(_lines(side)[FLOWN].get_ydata(),
                                  flown3d.trajectory_cvodes.three_d["z_au"])
    assert len(plots.timeline_figure(loaded).axes) == len(plots.timeline_figure(flown3d).axes)


def _day_number(iso):
    """matplotlib's date number of an ISO date, counted here by hand: days since
    matplotlib's epoch."""
    epoch = datetime.fromisoformat(mdates.get_epoch())
    return (datetime.fromisoformat(iso) - epoch).total_seconds() / 86400


def _assert_marked_bodies(ax, d):
    """Each body's track has a circle where it starts (the departure) and a square where
    it ends (the arrival), and the legend says which is which, with the dates."""
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert f"at departure, {d['departure_date'][:10]}" in legend
    assert f"at arrival, {d['arrival_date'][:10]}" in legend
    assert "Sun" in legend
    marks = {(line.get_marker(), line.get_xdata()[0], line.get_ydata()[0])
             for line in ax.get_lines() if len(line.get_xdata()) == 1}
    tracks = [line for line in ax.get_lines() if line.get_label().endswith(" over the flight")]
    assert len(tracks) == 2
    for track in tracks:
        x, y = track.get_data()
        assert ("o", x[0], y[0]) in marks and ("s", x[-1], y[-1]) in marks


def test_a_dated_planar_trajectory_marks_the_bodies_in_its_legend(planar_mars):
    d = planar_mars.to_json()
    (ax,) = plots.trajectory_figure(planar_mars).axes
    _assert_marked_bodies(ax, d)


def test_a_dated_timeline_runs_on_calendar_dates_from_the_departure(planar_mars):
    """Every time axis of a dated solution reads calendar dates, ISO style, each at its
    tick, and its curves start at the departure date (2031-01-01 here).  The dates are
    written under the last row only: every panel shares its time axis."""
    d = planar_mars.to_json()
    fig = plots.timeline_figure(planar_mars)
    _drawn(fig)
    day0, arrival = _day_number("2031-01-01"), _day_number(d["arrival_date"])
    epoch = datetime.fromisoformat(mdates.get_epoch())
    panels = [ax for ax in _rows(fig) if ax.get_ylabel() != plots.ROUNDS_LABEL]
    assert len(panels) == 8
    for ax in panels:
        assert min(line.get_xdata()[0] for line in ax.get_lines()) == pytest.approx(day0,
                                                                                     abs=1e-9)
        low, high = ax.get_xlim()
        assert low < day0 < arrival < high and day0 - low < 0.06 * (arrival - day0)
        assert ax.get_shared_x_axes().joined(ax, panels[-1])
        if ax not in panels[-2:]:
            assert ax.get_xticklabels() == []
            continue
        ticks = [(x, t.get_text()) for x, t in zip(ax.get_xticks(), ax.get_xticklabels())
                 if low <= x <= high]
        assert len(ticks) >= 3
        for x, text in ticks:
            assert re.fullmatch(r"\d{4}-\d{2}(-\d{2})?", text)
            assert (epoch + timedelta(days=float(x))).isoformat().startswith(text)
    assert [ax.get_xlabel() for ax in panels[-2:]] == [plots.DATE_LABEL] * 2


def _thrust_line(fig):
    (ax,) = [ax for ax in fig.axes if ax.get_ylabel() == plots.THRUST_LABEL]
    (line,) = ax.get_lines()
    return line


def test_thrust_at_zero_pitch_and_full_throttle_is_a_c_at_1_au_over_r(polished):
    """At alpha = 0 and throttle 1, (R, T, N) = (1, 0, 0): the thrust panel draws
    a_c (1 au / r) at every sample of the flight that flies (the polished one)."""
    data = copy.deepcopy(polished.to_json())
    data["problem"]["ac_mm_s2"] = 0.37
    for row in data["polish"]["schedule"]:
        row["alpha_deg"] = 0.0
    t, a = _thrust_line(plots.timeline_figure(Solution.from_json(data))).get_data()
    flown = data["trajectory"]["polished"]
    assert set(t) == set(flown["t_days"])
    np.testing.assert_allclose(a, 0.37 / np.interp(t, flown["t_days"], flown["r_au"]),
                               rtol=1e-15, atol=0)


@pytest.mark.parametrize("name", ["earth_venus_min_ac_planar", "earth_mars_min_ac"])
def test_thrust_is_the_sails_acceleration_at_the_flown_radius(name):
    """On a committed MinAcceleration solve (throttled; the second polished, in 3-D),
    the thrust panel draws kappa (a_c / 2)(1 au / r) sqrt(1 + 3 cos^2 alpha), Huo's
    exact model whatever the clock (PHYSICS-NOTES), with the a_c the flight needed, at
    every sample inside a segment."""
    path = RESULTS / name / "solution.json"
    if not path.exists():
        pytest.skip(f"no committed {name}")
    d = json.loads(path.read_text())
    assert d["problem"]["coefficients"] == [0.75, 0.25]
    polished = d["trajectory"].get("polished") is not None
    source = d["polish"] if polished else d
    sched, a_c = source["schedule"], source["ac_mm_s2_required"]
    flown = d["trajectory"]["polished" if polished else "cvodes"]
    t, a = _thrust_line(plots.timeline_figure(Solution.load(path))).get_data()
    t = t - _day_number(source["departure_date"])
    starts = np.array([row["t_days"] for row in sched])
    inside = 0
    for ts, r in zip(flown["t_days"], flown["r_au"]):
        if np.isclose(ts, starts, rtol=0, atol=1e-6).any():
            continue
        row = sched[np.searchsorted(starts, ts) - 1]
        expected = (row["throttle"] * a_c / 2 / r
                    * np.sqrt(1 + 3 * np.cos(np.radians(row["alpha_deg"]))**2))
        (i,) = np.flatnonzero(np.abs(t - ts) < 1e-7)
        assert a[i] == pytest.approx(expected, rel=1e-12, abs=1e-15)
        inside += 1
    assert inside > len(flown["t_days"]) / 2


def test_a_panel_without_data_is_not_drawn(polished, two_rounds):
    """One error-control round is one dot: no axes for it.  Two get a strip across both
    columns under the series; a schedule without local errors has no local error panel,
    and the thrust, then the last of seven, spans both columns: no cell is empty."""
    fig = plots.timeline_figure(polished)
    assert plots.ROUNDS_LABEL not in [ax.get_ylabel() for ax in fig.axes]
    assert all(ax.get_lines() for ax in fig.axes)
    fig = plots.timeline_figure(two_rounds)
    panels = _rows(fig)
    labels = [ax.get_ylabel() for ax in panels]
    assert plots.LOCAL_ERROR_LABEL not in labels
    assert labels == SERIES + [plots.PITCH_LABEL, plots.THRUST_LABEL, plots.ROUNDS_LABEL]
    left, right = panels[0].get_position(), panels[1].get_position()
    for ax in panels[-2:]:
        assert ax.get_position().x0 == pytest.approx(left.x0)
        assert ax.get_position().x1 == pytest.approx(right.x1)
    miss, tolerance = panels[-1].get_lines()
    rounds = two_rounds.to_json()["refinement"]["rounds"]
    assert list(miss.get_ydata()) == [r["target_miss_r_km"] for r in rounds]
    assert all(ax.get_lines() for ax in fig.axes)


@pytest.fixture(scope="module")
def failed(polished):
    """The same data as a closed-form solve that hit Ipopt's iteration limit."""
    data = copy.deepcopy(polished.to_json())
    data.update(status="Maximum_Iterations_Exceeded", outcome="failed", converged=False,
                verified=False)
    return Solution.from_json(data)


@pytest.mark.parametrize("which", ["polished", "flown3d", "planar_mars", "failed"])
def test_titles_say_in_words_the_verdict_the_time_of_flight_a_c_and_dates(which, request):
    sol = request.getfixturevalue(which)
    d = sol.to_json()
    polished = d["trajectory"].get("polished") is not None
    tof = f"{d['tof_days_exact']:.2f}" if polished else f"{d['tof_days']:.1f}"
    for fig in (plots.trajectory_figure(sol), plots.timeline_figure(sol)):
        head = (fig._suptitle or fig.axes[0].title).get_text()
        text = " ".join([head] + [ax.get_title() for ax in fig.axes])
        assert not IPOPT_STATUS.search(text) and d["status"] not in text
        name, verdict = head.split("\n")[0].split(": ", 1)
        assert name == d["problem"]["name"] + (" in 3-D" if which == "flown3d" else "")
        assert verdict == {"polished": "closed form verified, polished verified",
                           "failed": "closed form not verified (Ipopt: failed), "
                                     "polished verified"}.get(which, "verified")
        assert f"time of flight {tof} days, a_c 1 mm/s²" in head
        if sol.dated:
            assert head.endswith(f", {d['departure_date'][:10]} to {d['arrival_date'][:10]}")


def test_a_target_bodys_distance_from_the_ecliptic_means_one_thing(flown3d):
    """A 3-D solution gives the target body's distance from the ecliptic as the departure
    body's, DE421's |z| of each (read independently here), and the flight's miss along
    the normal apart; a version-5 file, which gave that miss as ``out_of_plane_km``,
    reads with it as ``normal_miss_km`` and the body's distance unknown."""
    from test_optimisation3d import AU_KM, de421_ecliptic

    from esail_opt.bodies.dates import jd_from_iso

    d = flown3d.to_json()
    body = d["target_body"]
    mars = de421_ecliptic("mars", jd_from_iso(d["arrival_date"]))
    earth = de421_ecliptic("earthmoon", jd_from_iso(d["departure_date"]))
    assert body["out_of_plane_km"] == pytest.approx(abs(mars[2]) * AU_KM, rel=1e-6)
    assert d["departure_body"]["out_of_plane_km"] == pytest.approx(abs(earth[2]) * AU_KM,
                                                                   rel=1e-6)
    assert body["normal_miss_km"] <= d["verification"]["target_miss_r_km"]
    assert body["normal_miss_km"] < 1e-3 * body["out_of_plane_km"]
    old = json.loads(json.dumps(d))
    old["schema_version"] = 5
    for part in (old["target_body"], old["verification"]):
        part["out_of_plane_km"] = part.pop("normal_miss_km")
    loaded = Solution.from_json(old)
    assert loaded.target_body.normal_miss_km == body["normal_miss_km"]
    assert loaded.target_body.out_of_plane_km is None
    assert (f"{d['problem']['target']['body']}: the 3-D flight meets it to "
            f"{body['normal_miss_km']:.4g} km along the ecliptic's normal") in loaded.summary()
    assert (f"is {body['out_of_plane_km']:.4g} km out of the ecliptic at arrival; the 3-D "
            f"flight meets it to {body['normal_miss_km']:.4g} km") in flown3d.summary()


@pytest.mark.parametrize("limits", [(2e-4, 20.0), (300.0, 8000.0), (5000.0, 8000.0)])
def test_log_labels_are_matplotlibs_in_superscripts(limits):
    """The same ticks labelled as by matplotlib's own log-axis labels (mathtext), and
    each label reads the same number."""
    fig = Figure()
    ours, theirs = fig.subplots(1, 2)
    for ax in (ours, theirs):
        ax.semilogy([0, 1], limits)
    plots._plain_log_labels(ours.yaxis)
    _drawn(fig)
    for minor in (False, True):
        mine = [t.get_text() for t in ours.get_yticklabels(minor=minor)]
        reference = [t.get_text() for t in theirs.get_yticklabels(minor=minor)]
        assert [bool(t) for t in mine] == [bool(t) for t in reference]
        values = ours.yaxis.get_minorticklocs() if minor else ours.yaxis.get_majorticklocs()
        for text, value in zip(mine, values):
            if text:
                assert _read(text) == pytest.approx(value, rel=1e-12)
    assert "$" not in "".join(t.get_text() for t in ours.get_yticklabels())


def _read(label):
    """The number that a label such as 10⁻³ or 2×10³ says, read back by hand."""
    coefficient, _, power = label.rpartition("10")
    return float(coefficient.rstrip("×") or 1) * 10.0 ** int(power.translate(DIGITS))


def test_formatter_writes_superscripts():
    f = plots.PlainLogFormatter(10)
    assert [f(v) for v in (1e-3, 1.0, 10.0, 2e3)] == ["10⁻³", "10⁰", "10¹", "2×10³"]



# ---------------------------------------------------------------- written, and what fails


def _named(sol, name):
    """``sol`` as a problem called ``name`` would have written it."""
    data = copy.deepcopy(sol.to_json())
    data["problem"]["name"] = name
    return Solution.from_json(data)


def _stand_in_solve(monkeypatch, sol, tmp_path):
    """A problem file whose solve returns ``sol`` (no Ipopt): for the command's
    handling of what is written."""
    from esail_opt.app import solution

    monkeypatch.setattr(solution, "solve_with_nearest", lambda problem, **kw: (sol, None))
    problem = tmp_path / "p.py"
    problem.write_text(TINY_PROBLEM.format(name="tiny"))
    return problem


def _one_error_line(err):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    return lines[0]


NAME = "x$a^b^c$"


def test_names_are_drawn_as_written_never_parsed_as_math(polished, tmp_path):
    """A name with dollars (mathtext would fail on a^b^c) is the figures' title as it
    was written, and both figures are written."""
    sol = _named(polished, NAME)
    trajectory, timeline = sol.plot()
    for fig in (trajectory, timeline):
        _drawn(fig)  # mathtext, if it were used, would raise here
    assert trajectory.axes[0].get_title().split(":")[0] == NAME
    assert timeline._suptitle.get_text().split(":")[0] == NAME
    written = sol.write(tmp_path / "out")
    assert sorted(p.name for p in written) == sorted(
        ["solution.json", "schedule.csv", "schedule_closed_form.csv", "trajectory.png",
         "timeline.png"])
    assert all(p.stat().st_size > 10_000 for p in written if p.suffix == ".png")


def test_a_figure_that_fails_is_one_line_and_exit_4_and_the_rest_is_written(
        polished, tmp_path, monkeypatch, capsys):
    from esail_opt.app import cli

    def broken(solution):
        raise ValueError("no figure today\nsecond line")

    assert polished.verified
    monkeypatch.setattr(plots, "FIGURES", (("trajectory.png", plots.trajectory_figure),
                                           ("timeline.png", broken)))
    problem = _stand_in_solve(monkeypatch, polished, tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "timeline.png").write_text("an old timeline")  # not left beside the new set
    assert cli.main(["solve", str(problem), "--out", str(out)]) == cli.EXIT_FIGURE == 4
    captured = capsys.readouterr()
    line = _one_error_line(captured.err)
    assert "timeline.png could not be drawn: ValueError: no figure today" in line
    assert sorted(p.name for p in out.iterdir()) == [
        "schedule.csv", "schedule_closed_form.csv", "solution.json", "trajectory.png"]
    assert Solution.load(out / "solution.json") == polished
    assert f"wrote {out / 'trajectory.png'}" in captured.out
    # Redrawing it fails the same way, with the same status, and keeps the rest.
    assert cli.main(["plot", str(out)]) == 4
    assert "timeline.png could not be drawn" in _one_error_line(capsys.readouterr().err)
    assert (out / "trajectory.png").stat().st_size > 10_000


def test_no_plots_writes_everything_but_the_figures_and_plot_draws_them(
        polished, tmp_path, monkeypatch, capsys):
    from esail_opt.app import cli

    problem = _stand_in_solve(monkeypatch, polished, tmp_path)
    out = tmp_path / "out"
    assert cli.main(["solve", str(problem), "--out", str(out), "--no-plots"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "schedule.csv", "schedule_closed_form.csv", "solution.json"]
    capsys.readouterr()
    assert cli.main(["plot", str(out)]) == 0
    assert capsys.readouterr().out.split() == [
        word for name, _ in plots.FIGURES for word in ("wrote", str(out / name))]
    for name, _ in plots.FIGURES:
        assert (out / name).stat().st_size > 10_000


@pytest.mark.parametrize("case", ["missing", "file", "empty", "bad json", "bad porkchop"])
def test_plot_refuses_a_folder_without_a_record_in_one_line(case, tmp_path, capsys):
    from esail_opt.app import cli

    folder = tmp_path / "run"
    if case == "file":
        folder.write_text("not a folder")
    elif case != "missing":
        folder.mkdir()
    if case == "bad json":
        (folder / "solution.json").write_text("{ torn")
    elif case == "bad porkchop":
        (folder / "porkchop.json").write_text("[1, 2]")
    assert cli.main(["plot", str(folder)]) == 2
    assert "esail-opt plot: error: " in _one_error_line(capsys.readouterr().err)


def _redrawn(tmp_path, capsys, shipped, kind):
    """``esail-opt plot`` on a folder holding only the shipped ``results/SHIPPED/KIND.json``:
    its KIND.png written, and the record as read."""
    from esail_opt.app import cli

    source = RESULTS / shipped / f"{kind}.json"
    if not source.exists():
        pytest.skip(f"no shipped {kind}.json")
    folder = tmp_path / "run"
    folder.mkdir()
    shutil.copy(source, folder / source.name)
    assert cli.main(["plot", str(folder)]) == 0
    assert f"wrote {folder / f'{kind}.png'}" in capsys.readouterr().out
    assert (folder / f"{kind}.png").stat().st_size > 10_000
    return json.loads(source.read_text())


def test_plot_draws_a_porkchop_from_its_record(tmp_path, capsys):
    """porkchop.png drawn again from a shipped porkchop.json: the best cell starred
    where the record puts it, and the title as the record names it."""
    from esail_opt.app import porkchop

    record = _redrawn(tmp_path, capsys, "earth_mars_window_porkchop", "porkchop")
    (ax, *_) = porkchop.figure(record).axes
    (best,) = [line for line in ax.get_lines() if line.get_label() == "best"]
    assert best.get_ydata()[0] == record["best"]["objective"]
    assert ax.get_title().startswith(f"{record['problem']}: ")


def test_plot_draws_a_sweep_from_its_record(tmp_path, capsys):
    """sweep.png drawn again from a shipped sweep.json: each verified member at its value,
    the record's rows read back through JSON as the sweep wrote them."""
    from esail_opt.app import sweep

    record = _redrawn(tmp_path, capsys, "sweep_earth_mars_ac", "sweep")
    objective = sweep.figure(record).axes[0]
    (verified,) = [line for line in objective.get_lines() if line.get_label() == "verified"]
    rows = [r for r in record["rows"] if r["verified"]]
    assert list(verified.get_xdata()) == [r["value"] for r in rows]
    factor = record["objective_shown_as"][0]  # canonical objective to the unit shown
    assert np.allclose(verified.get_ydata(), [factor * r["objective"] for r in rows])
