"""One figure drawn by two processes at once, each a horizontal band of it.

A solve's timeline takes its figures' process longer to draw than anything else they
need, and the trajectory, drawn beside it (:mod:`esail_opt.app.plot_worker`), is
written well before it, which leaves a core waiting.  So the timeline's process forks
once more: each of the two draws the whole figure with only its own band's axes
visible (the upper band also has the figure's own texts, such as its title), and
deflates its own rows (:func:`esail_opt.app.png.deflate_rows`); the file is the two
bands joined (:func:`esail_opt.app.png.assemble`).  Neither sends the other pixels.

The bands are split between two rows of axes, where the split shares the axes out most
evenly.  Joined, they are the figure drawn whole, pixel for pixel, as long as every
artist stays inside its band: so each process checks that its picture outside its own
band is the bare background, and when either finds more there (a label reaching
across the split), or the forked process fails, the figure is drawn whole instead.
"""

import gc
import multiprocessing
import os
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from esail_opt.app import png
from esail_opt.processes import quiet_child

#: Pixels between the top of the lower band and the top edge of its first row of axes:
#: room for the width of that edge's line, which is drawn centred on it.
PAD_PX = 3


@dataclass(frozen=True)
class Split:
    """Where a figure is cut: ``row`` is the first image row (from the top) of the
    lower band; ``upper`` and ``lower`` are the artists that only the upper or the
    lower band's process draws."""

    row: int
    upper: tuple
    lower: tuple


def split(fig, dpi):
    """The :class:`Split` of ``fig`` drawn at ``dpi``, or None when its axes make one
    row (or the gap between two rows is too narrow to cut in)."""
    rows = []  # [y0, y1, axes] in figure fractions, top row first
    for ax in sorted(fig.axes, key=lambda ax: -ax.get_position().y1):
        box = ax.get_position()
        if rows and box.y1 > rows[-1][0]:  # overlaps the row above it
            rows[-1][0] = min(rows[-1][0], box.y0)
            rows[-1][2].append(ax)
        else:
            rows.append([box.y0, box.y1, [ax]])
    if len(rows) < 2:
        return None
    height = fig.get_figheight() * dpi
    counts = np.cumsum([len(axes) for _, _, axes in rows])
    k = int(np.argmin(np.abs(2 * counts[:-1] - counts[-1])))  # the last upper row
    row = int(np.floor(height * (1 - rows[k + 1][1]))) - PAD_PX
    if row <= np.ceil(height * (1 - rows[k][0])):
        return None
    upper = [ax for _, _, axes in rows[:k + 1] for ax in axes]
    figure_level = [a for a in fig.get_children() if a is not fig.patch and a not in fig.axes]
    lower = [ax for _, _, axes in rows[k + 1:] for ax in axes]
    return Split(row, tuple(upper + figure_level), tuple(lower))


def banded_png(fig, dpi):
    """PNG bytes of ``fig`` drawn at ``dpi`` as two bands at once, or None when it has
    no two bands, an artist crossed between them, or the forked process failed.

    Call it only from a process that may fork (the figures' own, which holds no
    threads); the caller then draws the figure whole.
    """
    cut = split(fig, dpi)
    # A daemonic process may not start processes of its own.
    if cut is None or multiprocessing.current_process().daemon:
        return None
    background = _background(fig, dpi)
    context = multiprocessing.get_context("fork")
    ours, theirs = context.Pipe(duplex=False)
    # As before the figures' own forks (plot_worker): the collector's passes would
    # copy the pages the two processes still share.  A caller that had not frozen its
    # objects itself gets them back unfrozen once both bands are in (freezing does not
    # nest), and collects as before.
    frozen_here = gc.get_freeze_count() == 0
    gc.freeze()
    child = context.Process(target=_lower_band,
                            args=(fig, dpi, cut, background, theirs, os.getpid()), daemon=True)
    try:
        child.start()
    except OSError:  # no fork to be had (memory, a process limit)
        ours.close()
        if frozen_here:
            gc.unfreeze()
        return None
    finally:
        theirs.close()
    try:
        upper = _band(fig, dpi, cut, background, upper=True)
        try:
            lower = ours.recv()
        except EOFError:  # it died
            lower = None
    finally:
        ours.close()
        child.join()
        if frozen_here:
            gc.unfreeze()
    if upper is None or lower is None:
        return None
    return png.assemble([upper, lower], dpi)


def figure_png(fig, dpi):
    """PNG bytes of ``fig`` drawn at ``dpi``: in two bands at once where
    :func:`banded_png` can, else whole (the same pixels either way)."""
    return banded_png(fig, dpi) or png.figure_png(fig, dpi)


def _background(fig, dpi):
    """The pixel of ``fig``'s face alone, as Agg draws it."""
    blank = Figure(figsize=(4 / dpi, 4 / dpi), dpi=dpi, facecolor=fig.get_facecolor())
    return png.figure_pixels(blank, dpi)[0, 0].copy()


def _band(fig, dpi, cut, background, upper):
    """The :class:`~esail_opt.app.png.Band` of one side of ``cut``, drawn with the
    other side's artists hidden; None if anything shows outside it."""
    hidden = cut.lower if upper else cut.upper
    shown = [artist.get_visible() for artist in hidden]
    for artist in hidden:
        artist.set_visible(False)
    try:
        rgba = png.figure_pixels(fig, dpi)
    finally:
        for artist, visible in zip(hidden, shown):
            artist.set_visible(visible)
    mine, other = ((rgba[:cut.row], rgba[cut.row:]) if upper
                   else (rgba[cut.row:], rgba[:cut.row]))
    if not np.all(other == background):
        return None
    return png.deflate_rows(mine, last=not upper)


def _lower_band(fig, dpi, cut, background, conn, parent):
    """The forked process: draw the lower band and send it (None on any failure)."""
    quiet_child(parent)
    try:
        band = _band(fig, dpi, cut, background, upper=False)
    except Exception:  # the caller draws the figure whole, and meets it there
        band = None
    try:
        conn.send(band)
    except OSError:
        pass  # the caller stopped waiting
