"""The two figures of a solve: their panels, curves, labels and legends, and a layout
in which nothing is clipped by the figure's edge or runs into another panel."""

import copy
import os

import numpy as np
import pytest
from conftest import RESULTS, png_pixels
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import esail_opt as eo
from esail_opt.app import plot_worker, plots, png
from esail_opt.app.solution import Solution

DIGITS = str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789")
SERIES = ["r (au)", "v_r (km/s)", "v_theta (km/s)", "alpha (deg)", "osculating a (au)",
          "osculating e"]


@pytest.fixture(scope="module")
def polished():
    problem = eo.Problem("tiny", eo.ParkingOrbit(1.0), eo.Sail(1.0), eo.Segments(6, 2),
                         eo.MinTime(), eo.CircularOrbit(0.723))
    return eo.solve(problem, polish=True)


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
                           "segment starts"]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (au)", "y (au)")
    assert ax.get_title().startswith("tiny: tof ") and "\npolished: tof " in ax.get_title()
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


@pytest.mark.parametrize("which", ["polished", "throttled"])
def test_timeline_has_its_panels_curves_and_labels(which, request):
    sol = request.getfixturevalue(which)
    d = sol.to_json()
    fig = plots.timeline_figure(sol)
    twins = [ax for ax in fig.axes if ax.get_ylabel() == "throttle kappa"]
    assert len(twins) == (1 if which == "throttled" else 0)
    panels = [ax for ax in fig.axes if ax not in twins]
    assert len(panels) == 8
    # Read row by row: the six series, then the local error and refinement panels.
    panels.sort(key=lambda ax: (-round(ax.get_position().y0, 3), ax.get_position().x0))
    assert [ax.get_ylabel() for ax in panels] == SERIES + [
        "closed-form local error (km)", "position miss (km)"]
    for ax in panels[:6]:
        if ax.get_ylabel() == "alpha (deg)":
            (step,) = ax.get_lines()
            # The polished schedule's pitch, held to the polished time of flight.
            alphas = [row["alpha_deg"] for row in d["polish"]["schedule"]]
            np.testing.assert_array_equal(step.get_ydata(), alphas + alphas[-1:])
            assert step.get_xdata()[-1] == d["tof_days_exact"]
        else:
            assert [line.get_label() for line in ax.get_lines()] == [
                "closed form", "CVODES", "polished (CVODES)"]
    assert _labels(panels[0]) == ["closed form", "CVODES", "polished (CVODES)"]
    assert [ax.get_xlabel() for ax in panels] == [""] * 4 + ["t (days)"] * 3 + [
        "error-control round"]
    assert panels[6].get_yscale() == panels[7].get_yscale() == "log"
    assert _labels(panels[7]) == ["flown miss", "tolerance"]
    assert "polished Solve_Succeeded" in fig._suptitle.get_text()
    if twins:
        kappa = [row["throttle"] for row in d["polish"]["schedule"]]
        np.testing.assert_array_equal(twins[0].get_lines()[0].get_ydata(), kappa + kappa[-1:])


@pytest.mark.parametrize("which", ["polished", "throttled", "narrow"])
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



# ---------------------------------------------------------------- drawn beside the solve


def _written(paths):
    """Each file's pixels: the worker deflates the timeline in two bands, so its bytes
    differ from a whole deflate's while its image is the same."""
    return {p.name: png_pixels(p.read_bytes()) for p in paths}


def _same_images(ours, theirs):
    return ours.keys() == theirs.keys() and all(np.array_equal(ours[k], theirs[k]) for k in ours)


@pytest.mark.parametrize("which", ["polished", "throttled"])
@pytest.mark.parametrize("framed", [False, True])
def test_a_timeline_finished_from_its_draft_is_the_one_drawn_whole(which, framed, request):
    """The closed form drawn and rendered first (as while the polish runs), the polish
    drawn over its pixels after: pixel for pixel the timeline drawn in one go."""
    sol = request.getfixturevalue(which)
    frame = plots.timeline_frame(sol.schedule.throttled) if framed else None
    draft = plots.timeline_draft(sol.without_polish(), frame=frame)
    assert draft.fits(sol)
    whole = png.figure_pixels(plots.timeline_figure(sol), plots.DPI)
    assert np.array_equal(draft.pixels(sol), whole)


@pytest.mark.parametrize("name", ["earth_mars_min_time_polished", "earth_venus_low_thrust_polished",
                                  "earth_mars_coast"])
def test_shipped_timelines_finished_from_their_drafts_are_the_ones_drawn_whole(name):
    sol = Solution.load(RESULTS / name / "solution.json")
    draft = plots.timeline_draft(sol.without_polish())
    assert np.array_equal(draft.pixels(sol),
                          png.figure_pixels(plots.timeline_figure(sol), plots.DPI))


def test_a_draft_fits_its_own_solution_only(polished, throttled):
    """A draft drawn from other data (here the throttled variant's) does not fit: the
    worker then draws the timeline whole."""
    assert plots.timeline_draft(polished.without_polish()).fits(polished)
    assert not plots.timeline_draft(throttled.without_polish()).fits(polished)


@pytest.mark.skipif(not plot_worker._forks(), reason="the worker forks (Linux only)")
@pytest.mark.parametrize("which", ["polished", "throttled"])
@pytest.mark.parametrize("frame", [None, False, True])
@pytest.mark.parametrize("draft", [None, "own", "other"])
def test_the_worker_writes_what_drawing_here_writes(which, frame, draft, request, tmp_path):
    """The same images, pixel for pixel, as plots.write_plots, from the worker's processes,
    with the timeline drawn into a frame made ahead for the right case, for the wrong
    one, or without one; finished from its own draft, given another solution's draft,
    or given none; and the worker is gone once they are written."""
    polished = request.getfixturevalue(which)
    other = request.getfixturevalue("polished" if which == "throttled" else "throttled")
    for name in ("here", "there"):
        (tmp_path / name).mkdir()
    here = plots.write_plots(polished, tmp_path / "here")
    with plot_worker.PlotWorker(throttled=frame) as worker:
        process = worker._process
        if draft is not None:
            worker.draft((polished if draft == "own" else other).without_polish())
        worker.start(polished, tmp_path / "there")
        there = worker.written()
        assert not process.is_alive()
    assert [p.name for p in there] == [p.name for p in here] == [n for n, _ in plots.FIGURES]
    assert _same_images(_written(there), _written(here))


@pytest.mark.skipif(not plot_worker._forks(), reason="the worker forks (Linux only)")
def test_a_worker_that_never_takes_its_draft_is_ended_and_the_figures_drawn_here(
        polished, tmp_path, monkeypatch):
    """A stopped worker reads nothing, so the draft's sending thread stays blocked on the
    full pipe: start() waits WAIT_SECONDS for it, ends the worker, and the figures are
    drawn here, the same as ever."""
    import signal

    monkeypatch.setattr(plot_worker, "WAIT_SECONDS", 1.0)
    for name in ("here", "there"):
        (tmp_path / name).mkdir()
    here = plots.write_plots(polished, tmp_path / "here")
    # A shipped solution's draft: more than the pipe holds (the tiny one's fits in it).
    big = Solution.load(RESULTS / "earth_mars_min_time_polished" / "solution.json")
    with plot_worker.PlotWorker(throttled=False) as worker:
        os.kill(worker._process.pid, signal.SIGSTOP)
        worker.draft(big.without_polish())
        worker.start(polished, tmp_path / "there")
        assert not worker.running  # ended by start(), before written() waited at all
        there = worker.written()
    assert _same_images(_written(there), _written(here))


@pytest.mark.skipif(not plot_worker._forks(), reason="the worker forks (Linux only)")
def test_a_dead_worker_is_replaced_by_drawing_here(polished, tmp_path):
    with plot_worker.PlotWorker() as worker:
        worker._process.kill()
        worker._process.join()
        worker.start(polished, tmp_path)
        paths = worker.written()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(n for n, _ in plots.FIGURES)
    assert all(p.stat().st_size > 0 for p in paths)


@pytest.mark.skipif(not plot_worker._forks(), reason="the worker forks (Linux only)")
def test_a_figure_that_fails_in_the_worker_fails_here_too(polished, tmp_path, monkeypatch):
    """A figure's own fault is met again in the caller's process, where it raises as it
    would without a worker (the worker, forked after the patch, fails the same way)."""
    def broken(solution):
        raise ValueError("no figure today")

    monkeypatch.setattr(plots, "FIGURES", (("trajectory.png", plots.trajectory_figure),
                                           ("timeline.png", broken)))
    with plot_worker.PlotWorker() as worker:
        worker.start(polished, tmp_path)
        with pytest.raises(ValueError, match="no figure today"):
            worker.written()


@pytest.mark.skipif(not plot_worker._forks(), reason="the worker forks (Linux only)")
def test_a_worker_that_cannot_be_forked_leaves_the_figures_to_be_drawn_here(
        polished, tmp_path, monkeypatch):
    import multiprocessing.process

    def no_fork(self):
        raise OSError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(multiprocessing.process.BaseProcess, "start", no_fork)
    with plot_worker.PlotWorker() as worker:
        assert worker._process is None
        worker.start(polished, tmp_path)
        paths = worker.written()
    assert sorted(p.name for p in paths) == sorted(n for n, _ in plots.FIGURES)
    assert all(p.stat().st_size > 0 for p in paths)
