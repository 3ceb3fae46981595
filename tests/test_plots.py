"""The two figures of a solve: their panels, curves, limits, labels and legends, a layout
in which nothing is clipped or overlaps, names drawn as written, and what the command
writes and says when a figure cannot be drawn (`solve`, `solve --no-plots`, `plot`)."""

import copy
import csv
import io
import json
import shutil

import numpy as np
import pytest
from conftest import RESULTS, TINY_PROBLEM
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import esail_opt as eo
from esail_opt.app import plots
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


def test_timeline_limits_hold_the_closed_form_and_its_flight(polished):
    """Each series panel spans its closed-form, CVODES and polished samples with
    matplotlib's 5 % margins, the time axis the whole flight, the pitch panel [-90, 90]
    deg."""
    d = polished.to_json()
    flights = [d["trajectory"][key] for key in ("closed_form", "cvodes", "polished")]
    fig = plots.timeline_figure(polished)
    panels = {ax.get_ylabel(): ax for ax in fig.axes}
    for key, label in plots.TIMELINE_PANELS:
        ax = panels[label]
        low, high = ax.get_ylim()
        if key is None:
            assert low <= -90 and high >= 90
            continue
        values = np.concatenate([flight[key] for flight in flights])
        span = values.max() - values.min()
        assert low == pytest.approx(values.min() - 0.05 * span, rel=1e-9, abs=1e-12)
        assert high == pytest.approx(values.max() + 0.05 * span, rel=1e-9, abs=1e-12)
    t = np.concatenate([flight["t_days"] for flight in flights])
    low, high = panels["r (au)"].get_xlim()
    assert low == pytest.approx(t.min() - 0.05 * np.ptp(t), abs=1e-9)
    assert high == pytest.approx(t.max() + 0.05 * np.ptp(t), rel=1e-12)


@pytest.mark.parametrize("which", ["polished", "throttled", "narrow", "flown3d"])
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


# ---------------------------------------------------------------- in three dimensions

AU_KM = 149597870.7  # written out again here, not taken from the package
FLOWN = "CVODES flight"


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
    panels (none of them the clock or the inclination)."""
    sol = request.getfixturevalue(which)
    assert not plots.three_d(sol)
    assert len(plots.trajectory_figure(sol).axes) == 1
    labels = [ax.get_ylabel() for ax in plots.timeline_figure(sol).axes]
    assert len(labels) == 8
    assert plots.CLOCK_LABEL not in labels and plots.INCLINATION_LABEL not in labels


def test_trajectory_in_3d_shows_the_flight_from_above_and_from_the_side(flown3d):
    """The top view is the CVODES flight's x, y and the side view its z (au) against its
    t (days); the bodies' tracks start and end where the verified flight does (the
    departure is the Earth's state, the rendezvous meets Mars within the tolerance)."""
    d = flown3d.to_json()
    cv = d["trajectory"]["cvodes"]
    assert d["schema_version"] == 7
    top, side = plots.trajectory_figure(flown3d).axes
    assert (top.get_xlabel(), top.get_ylabel()) == ("x (au)", "y (au)")
    assert (side.get_xlabel(), side.get_ylabel()) == ("t since departure (days)", "z (au)")
    x, y = _lines(top)[FLOWN].get_data()
    np.testing.assert_array_equal(x, cv["x_au"])
    np.testing.assert_array_equal(y, cv["y_au"])
    t, z = _lines(side)[FLOWN].get_data()
    np.testing.assert_array_equal(t, cv["t_days"])
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
    assert abs(_lines(side)["mars over the flight"].get_xdata()[-1] - d["tof_days"]) < 1e-6


def test_timeline_in_3d_adds_the_clock_and_the_inclination(flown3d):
    """Two panels more than the planar timeline: the clock's steps are schedule.csv's
    clock_deg held to the arrival, the inclination the CVODES samples'."""
    d = flown3d.to_json()
    fig = plots.timeline_figure(flown3d)
    panels = {ax.get_ylabel(): ax for ax in fig.axes}
    assert len(fig.axes) == 10 and set(SERIES) <= set(panels)
    clock_rows = [float(row["clock_deg"]) for row in
                  csv.DictReader(io.StringIO(flown3d.schedule_csv()))]
    (step,) = panels[plots.CLOCK_LABEL].get_lines()
    np.testing.assert_array_equal(step.get_ydata(), clock_rows + clock_rows[-1:])
    np.testing.assert_array_equal(step.get_xdata(),
                                  [row["t_days"] for row in d["schedule"]] + [d["tof_days"]])
    (incl,) = panels[plots.INCLINATION_LABEL].get_lines()
    cv = d["trajectory"]["cvodes"]
    np.testing.assert_array_equal(incl.get_xdata(), cv["t_days"])
    np.testing.assert_array_equal(incl.get_ydata(), cv["inclination_deg"])
    assert panels[plots.INCLINATION_LABEL].get_xlabel() == "t (days)"


def test_plot_redraws_a_3d_solution_from_its_file(flown3d, tmp_path, capsys):
    """`esail-opt plot` on a folder whose solution.json is schema 7 draws both figures,
    in 3-D as the fresh solution's."""
    from esail_opt.app import cli

    folder = tmp_path / "run"
    flown3d.write(folder, plots=False)
    assert json.loads((folder / "solution.json").read_text())["schema_version"] == 7
    assert cli.main(["plot", str(folder)]) == 0
    for name, _ in plots.FIGURES:
        assert (folder / name).stat().st_size > 10_000
    loaded = Solution.load(folder / "solution.json")
    top, side = plots.trajectory_figure(loaded).axes
    np.testing.assert_array_equal(_lines(side)[FLOWN].get_ydata(),
                                  flown3d.trajectory_cvodes.three_d["z_au"])
    assert len(plots.timeline_figure(loaded).axes) == 10


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
    assert f"{body['normal_miss_km']:.4g} km from the flight" in loaded.summary()


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

    monkeypatch.setattr(solution, "solve", lambda problem, **kw: sol)
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
        ["solution.json", "schedule.csv", "schedule_polished.csv", "trajectory.png",
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
        "schedule.csv", "schedule_polished.csv", "solution.json", "trajectory.png"]
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
        "schedule.csv", "schedule_polished.csv", "solution.json"]
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


def test_plot_draws_a_porkchop_from_its_record(tmp_path, capsys):
    """porkchop.png drawn again from a shipped porkchop.json: the best cell starred
    where the record puts it, and the title as the record names it."""
    from esail_opt.app import cli, porkchop

    source = RESULTS / "earth_mars_window_porkchop" / "porkchop.json"
    if not source.exists():
        pytest.skip("no shipped porkchop.json")
    folder = tmp_path / "run"
    folder.mkdir()
    shutil.copy(source, folder / "porkchop.json")
    assert cli.main(["plot", str(folder)]) == 0
    assert (folder / "porkchop.png").stat().st_size > 10_000
    record = json.loads(source.read_text())
    (ax, *_) = porkchop.figure(record).axes
    (best,) = [line for line in ax.get_lines() if line.get_label() == "best"]
    assert best.get_ydata()[0] == record["best"]["objective"]
    assert ax.get_title().startswith(f"{record['problem']}: ")
