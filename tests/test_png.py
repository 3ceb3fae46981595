"""The PNG encoder (``app.png``) against matplotlib's own PNG, both decoded by Pillow."""

import io
import zlib

import numpy as np
import pytest
from conftest import RESULTS, png_pixels
from matplotlib.figure import Figure
from PIL import Image

from esail_opt.app import plots, png
from esail_opt.app.files import save_figure
from esail_opt.app.solution import Solution



def _matplotlib_png(fig, dpi):
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def _small_figure():
    fig = Figure(figsize=(3.2, 2.4), dpi=100)
    ax = fig.subplots()
    t = np.linspace(0, 10, 400)
    ax.plot(t, np.sin(t), color="tab:blue", lw=1.4, label="sin")
    ax.plot(t, np.cos(t), color="tab:red", ls="-.", label="cos")
    ax.fill_between(t, 0, np.sin(t) / 2, alpha=0.3)
    ax.set_title("a title")
    ax.legend()
    return fig


@pytest.mark.parametrize("dpi", [100, 150])
def test_a_figure_encodes_to_matplotlibs_pixels(dpi):
    """Decoded, the file holds the pixels matplotlib writes at that resolution (the
    figure drawn at its own dpi, and at another), in RGBA, with the dpi recorded."""
    ours_png = png.figure_png(_small_figure(), dpi)
    theirs_png = _matplotlib_png(_small_figure(), dpi)
    ours, theirs = Image.open(io.BytesIO(ours_png)), Image.open(io.BytesIO(theirs_png))
    assert ours.mode == theirs.mode == "RGBA"
    assert ours.size == theirs.size == (round(3.2 * dpi), round(2.4 * dpi))
    assert np.array_equal(png_pixels(ours_png), png_pixels(theirs_png))
    # Both record the dpi as whole pixels per metre, which reads back a little off.
    assert ours.info["dpi"] == theirs.info["dpi"] == pytest.approx((dpi, dpi), rel=1e-3)


def test_a_solutions_figures_encode_to_matplotlibs_pixels(tmp_path):
    """Both figures of a shipped polished solve, written by ``save_figure``, decode to
    the pixels of matplotlib's own PNG of the same figure."""
    source = RESULTS / "earth_mars_min_time_polished" / "solution.json"
    sol = Solution.load(source)
    for name, draw in plots.FIGURES:
        path = tmp_path / name
        save_figure(draw(sol), path, dpi=plots.DPI)
        ours = png_pixels(path.read_bytes())
        theirs = png_pixels(_matplotlib_png(draw(sol), plots.DPI))
        assert ours.shape == theirs.shape and ours.shape[2] == 4
        assert np.array_equal(ours, theirs), name


def test_only_8_bit_rgba_is_encoded():
    with pytest.raises(ValueError, match="8-bit RGBA"):
        png.encode(np.zeros((4, 4, 3), np.uint8), 100)
    with pytest.raises(ValueError, match="8-bit RGBA"):
        png.encode(np.zeros((4, 4, 4), np.float32), 100)


def test_adler32_combine_is_zlibs_checksum_of_the_joined_bytes():
    rng = np.random.default_rng(3)
    for first_size, second_size in [(0, 5), (7, 0), (1, 1), (65520, 65522), (200003, 99991)]:
        first = rng.integers(0, 256, first_size, dtype=np.uint8).tobytes()
        second = rng.integers(0, 256, second_size, dtype=np.uint8).tobytes()
        combined = png.adler32_combine(zlib.adler32(first), zlib.adler32(second), second_size)
        assert combined == zlib.adler32(first + second)


def test_bands_deflated_apart_join_into_the_whole_image():
    """Three bands, each deflated on its own, decode as the image encoded whole; bands
    out of order or of another width are refused."""
    rng = np.random.default_rng(4)
    rgba = rng.integers(0, 256, (61, 37, 4), dtype=np.uint8)
    rgba[10:40] = 255  # long runs, as a figure's background
    bands = [png.deflate_rows(rgba[:20], last=False), png.deflate_rows(rgba[20:21], last=False),
             png.deflate_rows(rgba[21:], last=True)]
    joined = png_pixels(png.assemble(bands, 100))
    whole = png_pixels(png.encode(rgba, 100))
    assert np.array_equal(joined, rgba) and np.array_equal(whole, rgba)
    with pytest.raises(ValueError, match="only the last"):
        png.assemble(bands[::-1], 100)
    with pytest.raises(ValueError, match="one width"):
        png.assemble([bands[0], png.deflate_rows(rgba[:, :5], last=True)], 100)
