"""PNG files of figures: rendered by matplotlib's Agg, encoded here.

The pixels are Agg's, unchanged (8-bit RGBA).  The encoding is the plainest PNG
allows: no row filter, and zlib's fastest level.  Matplotlib's own PNG path hands the
pixels to Pillow, whose adaptive row filters cost more than the deflate itself, for
files only a little smaller; every figure a solve writes waits for its encoding.
``tests/test_png.py`` decodes these files with Pillow and compares their pixels with
matplotlib's own.
"""

import struct
import zlib

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_METRES_PER_INCH = 0.0254


def figure_pixels(fig, dpi):
    """The figure drawn at ``dpi`` by Agg, as an (height, width, 4) uint8 RGBA array.

    The figure keeps ``dpi`` afterwards (a saved figure is not drawn again at another).
    These are the pixels ``savefig`` writes at that resolution: it draws the same
    figure on the same canvas, with the figure's own face colour.
    """
    fig.set_dpi(dpi)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())


def encode(rgba, dpi):
    """PNG bytes of an (height, width, 4) uint8 RGBA array, with ``dpi`` recorded."""
    height, width, channels = rgba.shape
    if channels != 4 or rgba.dtype != np.uint8:
        raise ValueError(f"expected 8-bit RGBA pixels, not {channels} x {rgba.dtype}")
    rows = np.empty((height, 4 * width + 1), np.uint8)
    rows[:, 0] = 0  # filter type 0 (None) on every row
    rows[:, 1:] = rgba.reshape(height, 4 * width)
    per_metre = round(dpi / _METRES_PER_INCH)
    return b"".join([
        _SIGNATURE,
        _chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)),
        _chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)),
        _chunk(b"IDAT", zlib.compress(rows.tobytes(), 1)),
        _chunk(b"IEND", b""),
    ])


def figure_png(fig, dpi):
    """PNG bytes of ``fig`` drawn at ``dpi``."""
    return encode(figure_pixels(fig, dpi), dpi)


def _chunk(kind, data):
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data)))
