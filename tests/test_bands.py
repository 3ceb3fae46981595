"""A figure drawn in two bands at once (``app.bands``) against the figure drawn whole."""

import os

import numpy as np
import pytest
from conftest import RESULTS, png_pixels
from matplotlib.figure import Figure

from esail_opt.app import bands, plots, png
from esail_opt.app.solution import Solution


def _timeline(name):
    return plots.timeline_figure(Solution.load(RESULTS / name / "solution.json"))


def _drawn_whole(make, dpi=100):
    """Whether bands.figure_png of a figure made by ``make`` is the figure drawn whole."""
    return np.array_equal(png_pixels(bands.figure_png(make(), dpi)),
                          png_pixels(png.figure_png(make(), dpi)))


# A polished solve, a throttled one (the pitch panel's second axis), a dated one (the
# bodies), and a spiral without a target.
@pytest.mark.parametrize("name", ["earth_mars_min_time_polished", "earth_mars_coast",
                                  "earth_mars_window", "orbit_raising_10yr"])
def test_a_timeline_in_bands_is_the_timeline_drawn_whole(name):
    """Cut between its second and third rows of panels (four axes above and four below,
    the throttle's twin with its panel), drawn by two processes, joined: the pixels of
    the figure drawn whole."""
    fig = _timeline(name)
    cut = bands.split(fig, plots.DPI)
    panels = [ax for ax in cut.upper if ax in fig.axes]
    assert len(cut.lower) == 4 and len(panels) + len(cut.lower) == len(fig.axes)
    assert fig.texts and all(text in cut.upper for text in fig.texts)  # the title
    height = fig.get_figheight() * plots.DPI  # image rows count from the top
    assert all((1 - ax.get_position().y0) * height < cut.row for ax in panels)
    assert all((1 - ax.get_position().y1) * height > cut.row for ax in cut.lower)
    banded = bands.banded_png(fig, plots.DPI)
    assert banded is not None
    whole = png.figure_png(_timeline(name), plots.DPI)
    assert np.array_equal(png_pixels(banded), png_pixels(whole))


def _two_rows(text_y=None):
    fig = Figure(figsize=(4, 4), dpi=100)
    top, bottom = fig.subplots(2, 1)
    top.plot([0, 1], [0, 1])
    bottom.plot([0, 1], [1, 0])
    fig.suptitle("two rows")
    if text_y is not None:  # a label of the top axes hanging into the lower band
        top.text(0.5, text_y, "reaching down", transform=top.transAxes, ha="center")
    return fig


def test_an_artist_across_the_cut_draws_the_figure_whole():
    """A label of the upper band that reaches into the lower one: no bands, and
    figure_png gives the figure drawn whole."""
    assert bands.banded_png(_two_rows(), 100) is not None
    assert bands.banded_png(_two_rows(text_y=-0.3), 100) is None
    assert _drawn_whole(lambda: _two_rows(text_y=-0.3))


def test_a_figure_of_one_row_is_not_cut():
    fig = Figure(figsize=(4, 2), dpi=100)
    left, right = fig.subplots(1, 2)
    left.plot([0, 1])
    assert bands.split(fig, 100) is None and bands.banded_png(fig, 100) is None


def _dies(*args):
    os._exit(1)


def test_a_band_process_that_dies_draws_the_figure_whole(monkeypatch):
    monkeypatch.setattr(bands, "_lower_band", _dies)
    assert bands.banded_png(_two_rows(), 100) is None
    assert _drawn_whole(_two_rows)


def test_no_fork_to_be_had_draws_the_figure_whole(monkeypatch):
    """A fork that fails (memory, a process limit): no bands, and the figure drawn whole."""
    import multiprocessing

    def no_fork(self):
        raise OSError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(multiprocessing.get_context("fork").Process, "start", no_fork)
    assert bands.banded_png(_two_rows(), 100) is None
    assert _drawn_whole(_two_rows)


def test_the_callers_freeze_of_its_objects_is_left_as_it_was():
    """The band's fork freezes the collector's objects (so neither process copies the
    pages they share); a caller that had frozen nothing gets nothing frozen back, and
    one that had (the figures' worker) keeps its freeze."""
    import gc

    gc.unfreeze()
    assert bands.banded_png(_two_rows(), 100) is not None
    assert gc.get_freeze_count() == 0
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        assert bands.banded_png(_two_rows(), 100) is not None
        assert gc.get_freeze_count() >= frozen > 0
    finally:
        gc.unfreeze()
