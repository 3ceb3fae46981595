"""A command's files: JSON records, CSV tables, figures and a scan's set of the three,
each written whole or not at all (:mod:`esail_opt.runtime.files`)."""

import csv
import io
import json
from pathlib import Path

from esail_opt.app.record import plain
from esail_opt.runtime.files import atomic_path, publish


def write_json(path, data):
    """Write ``data`` as indented JSON, atomically: numpy numbers as Python ones, NaN
    and infinity as null (``record.plain``), so that the JSON stays standard."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(plain(data), indent=1, allow_nan=False) + "\n")


#: zlib's level for the PNGs: the fastest; matplotlib's default (6) spent a quarter of a
#: solve's figure time for files about 10 % smaller.
PNG_COMPRESS_LEVEL = 1


def figure_bytes(fig, fmt="png", dpi=150):
    """The file of a matplotlib Figure in format ``fmt`` as bytes (a PNG at
    :data:`PNG_COMPRESS_LEVEL`).  Drawing is kept apart from writing: an error here is the
    figure's (:func:`esail_opt.app.plots.write_plots`), one while writing the disk's."""
    buffer = io.BytesIO()
    options = {"pil_kwargs": {"compress_level": PNG_COMPRESS_LEVEL}} if fmt == "png" else {}
    fig.savefig(buffer, format=fmt, dpi=dpi, **options)
    return buffer.getvalue()


def save_figure(fig, path, dpi=150):
    """Save a matplotlib Figure atomically, in the format of ``path``'s suffix (PNG
    without one); made without pyplot, it needs no closing."""
    data = figure_bytes(fig, Path(path).suffix.lstrip(".") or "png", dpi)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def csv_text(rows, fields, digits=10):
    """The dicts ``rows`` as CSV text under a header of ``fields``: None as an empty
    cell, floats to ``digits`` significant digits (None: as Python writes them)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row[k] is None else f"{row[k]:.{digits}g}"
                             if digits and isinstance(row[k], float) else row[k])
                         for k in fields})
    return buf.getvalue()


def write_table_set(out_dir, names, csv_text, data, fig):
    """A scan's table, record and picture (``names``: the CSV, JSON and PNG file names;
    ``fig`` None for no picture) written into ``out_dir`` as one set (:func:`publish`);
    their paths.  OutputError when the folder cannot be written (the old set stays)."""
    out = Path(out_dir)
    names_written = names if fig is not None else names[:2]
    with publish(out, family=names) as stage:
        (stage / names[0]).write_text(csv_text)
        write_json(stage / names[1], data)
        if fig is not None:
            save_figure(fig, stage / names[2])
    return [out / name for name in names_written]
