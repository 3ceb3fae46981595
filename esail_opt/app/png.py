"""PNG files of figures: rendered by matplotlib's Agg, encoded here.

The pixels are Agg's, unchanged (8-bit RGBA).  The encoding is the plainest PNG
allows: no row filter, and zlib's fastest level.  Matplotlib's own PNG path hands the
pixels to Pillow, whose adaptive row filters cost more than the deflate itself, for
files only a little smaller; every figure a solve writes waits for its encoding.
``tests/test_png.py`` decodes these files with Pillow and compares their pixels with
matplotlib's own.

An image can be deflated in horizontal bands, each on its own (:func:`deflate_rows`),
and the bands joined into one file (:func:`assemble`): all but the last band end on a
byte boundary without ending the stream, as a parallel deflate does, and the stream's
Adler-32 checksum is combined from the bands' own (:func:`adler32_combine`).  So two
processes that each drew a band of a figure (:mod:`esail_opt.app.bands`) need not send
each other their pixels.
"""

import struct
import zlib
from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_METRES_PER_INCH = 0.0254
#: zlib's stream header for a 32 KiB window at its fastest level (RFC 1950).
_ZLIB_HEADER = b"\x78\x01"
_ADLER_BASE = 65521


@dataclass(frozen=True)
class Band:
    """Rows of an image, filtered and deflated on their own (:func:`deflate_rows`)."""

    width: int
    rows: int
    deflated: bytes  # raw deflate (no zlib header or checksum)
    adler32: int  # of the filtered rows alone
    size: int  # bytes of the filtered rows
    last: bool  # ends the deflate stream


def figure_pixels(fig, dpi):
    """The figure drawn at ``dpi`` by Agg, as an (height, width, 4) uint8 RGBA array.

    The figure keeps ``dpi`` afterwards (a saved figure is not drawn again at another).
    These are the pixels ``savefig`` writes at that resolution: it draws the same
    figure on the same canvas, with the figure's own face colour.
    """
    fig.set_dpi(dpi)
    # The canvas the figure was laid out on (plots' margins measure its texts) keeps
    # its renderer, and with it the metrics of every text measured: a new one would
    # lay them all out again.
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())


def deflate_rows(rgba, last):
    """A :class:`Band` of an (rows, width, 4) uint8 RGBA array; ``last`` for the band
    that ends the image."""
    height, width, channels = rgba.shape
    if channels != 4 or rgba.dtype != np.uint8:
        raise ValueError(f"expected 8-bit RGBA pixels, not {channels} x {rgba.dtype}")
    filtered = np.empty((height, 4 * width + 1), np.uint8)
    filtered[:, 0] = 0  # filter type 0 (None) on every row
    filtered[:, 1:] = rgba.reshape(height, 4 * width)
    data = filtered.tobytes()
    deflate = zlib.compressobj(1, zlib.DEFLATED, -15)
    body = deflate.compress(data) + deflate.flush(zlib.Z_FINISH if last else zlib.Z_SYNC_FLUSH)
    return Band(width, height, body, zlib.adler32(data), len(data), last)


def adler32_combine(first, second, second_size):
    """The Adler-32 of two byte strings joined, from each one's and the second's length
    (zlib's ``adler32_combine``, which Python's ``zlib`` does not expose)."""
    a1, b1 = first & 0xFFFF, first >> 16
    a2, b2 = second & 0xFFFF, second >> 16
    a = (a1 + a2 - 1) % _ADLER_BASE
    b = (b1 + b2 + second_size * (a1 - 1)) % _ADLER_BASE
    return (b << 16) | a


def assemble(bands, dpi):
    """PNG bytes of an image made of ``bands``, top first, with ``dpi`` recorded."""
    widths = {band.width for band in bands}
    if len(widths) != 1 or not bands[-1].last or any(band.last for band in bands[:-1]):
        raise ValueError("the bands must share one width, and only the last may end the image")
    checksum = bands[0].adler32
    for band in bands[1:]:
        checksum = adler32_combine(checksum, band.adler32, band.size)
    stream = b"".join([_ZLIB_HEADER, *(band.deflated for band in bands),
                       struct.pack(">I", checksum)])
    height = sum(band.rows for band in bands)
    per_metre = round(dpi / _METRES_PER_INCH)
    return b"".join([
        _SIGNATURE,
        _chunk(b"IHDR", struct.pack(">IIBBBBB", widths.pop(), height, 8, 6, 0, 0, 0)),
        _chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)),
        _chunk(b"IDAT", stream),
        _chunk(b"IEND", b""),
    ])


def encode(rgba, dpi):
    """PNG bytes of an (height, width, 4) uint8 RGBA array, with ``dpi`` recorded."""
    return assemble([deflate_rows(rgba, last=True)], dpi)


def figure_png(fig, dpi):
    """PNG bytes of ``fig`` drawn at ``dpi``."""
    return encode(figure_pixels(fig, dpi), dpi)


def _chunk(kind, data):
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data)))
