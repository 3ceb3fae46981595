"""A scan's journal on disk: a header line, then one JSON row per finished row, each on disk
before the next, so that an interrupted scan resumes from the rows it kept.  A row is a
dict of a frozen dataclass's fields, checked against their annotations when read back; a
journal resumes only under the same header.  What a row holds is the caller's
(:mod:`esail_opt.app.engine`).
"""

import contextlib
import dataclasses
import errno
import json
import os
import typing
from pathlib import Path

from esail_opt.errors import InputError, OutputError
from esail_opt.runtime.files import atomic_path


def _short(value):
    """A one-line, bounded repr for a journal mismatch message."""
    if isinstance(value, list) and len(value) > 6:
        return f"[{', '.join(map(repr, value[:3]))}, ..., {value[-1]!r}] ({len(value)} values)"
    return repr(value)


#: How a refusal names each JSON type a field may hold.
_WORDS = {float: "a number", int: "a whole number", bool: "true or false", str: "a string",
          dict: "a JSON object", list: "a JSON list"}


def _why_not(value, hint):
    """Why the JSON ``value`` cannot fill a field annotated ``hint`` (``int``, ``float``,
    ``bool``, ``str``, ``dict``, ``list``, or one of them Optional: or null), or None.
    A bool is not a number; an int fills a float field."""
    kind = next((t for t in typing.get_args(hint) if t is not type(None)), hint)
    if value is None:
        return None if kind is not hint else "is missing"
    if isinstance(value, bool) is not (kind is bool) \
            or not isinstance(value, (int, float) if kind is float else kind):
        return f"= {_short(value)} is not {_WORDS[kind]}"
    return None


def fields(row_type):
    """The field names of a row's dataclass, in declaration order."""
    return tuple(f.name for f in dataclasses.fields(row_type))


class Journal:
    """A scan's record on disk: a header line, then one JSON row per finished row; of two rows of
    one index the later holds (a job's end replaces a row it told of).

    Each row is one ``write`` of a whole line in append mode, then ``fsync``: a crash or a kill
    leaves at most a torn last line, which :meth:`read` ignores and :meth:`start` cuts off.

    ``header`` identifies the scan (``journal``, ``problem``, ``source_sha256``, ``param``,
    ``values``, ``polish``, ``tolerance`` and what its kind adds); a journal resumes only under
    the same header, every key of it.  ``row_type`` is the rows' frozen dataclass: a row read is
    checked against its fields' annotations (:func:`_why_not`) and kept as a dict of its
    fields, in order.  The grid has ``count`` rows; ``belongs(index, row)`` says whether a row
    is this grid's (default: its index is in ``range(count)``), ``invalid(row)`` why a row of
    the right types is still not valid, or None.  The header and the rows are JSON values
    already (None, not NaN); NaN is refused.
    """

    def __init__(self, path, header, row_type, count, belongs=None, invalid=None):
        self.path = Path(path)
        self.header, self.row_type, self.count = header, row_type, count
        self.belongs = belongs or (lambda i, row: True)
        self.invalid = invalid or (lambda row: None)
        self.fresh = False  # started afresh, and no row written yet

    def read(self, resume):
        """With ``resume``, the rows the journal holds (index -> row); changes nothing.
        InputError, one line naming the file and the line, if the journal is not this kind's,
        belongs to another scan, or a whole line of it is not UTF-8 JSON or not a valid row."""
        if not resume or not self.path.exists():
            return {}
        lines = self._lines()
        self._check_header(lines)
        kept = {}
        for number, line in lines[1:]:
            if line.strip():
                row = self._row(number, line)
                i = row["index"]
                if 0 <= i < self.count and self.belongs(i, row):
                    kept[i] = row  # a later row of a cell replaces an earlier one
        return kept

    def start(self, kept):
        """Make the journal ready for appending, once the run is accepted: with rows
        ``kept``, cut a torn last line off.  Without, the old journal is replaced by
        this one's header only with the first row (:meth:`append`) or at the run's end
        (:meth:`close`): a fresh run stopped before either leaves the old scan's
        journal, which its outputs beside it match, to be resumed."""
        self.fresh = not kept
        if kept:
            raw = self.path.read_bytes()
            whole = raw.rfind(b"\n") + 1
            if whole < len(raw):
                with open(self.path, "r+b") as handle:
                    handle.truncate(whole)
                    os.fsync(handle.fileno())

    def close(self):
        """At a run's end: a fresh journal that no row reached is written (its header),
        so that it, not the old scan's, sits beside the run's outputs."""
        if self.fresh:
            self._replace()

    def _replace(self, row=None):
        # The header replaces any old journal whole: no stale row is read as this scan's.
        with atomic_path(self.path) as tmp:
            tmp.write_text(self._line(self.header) + ("" if row is None else self._line(row)))
            with open(tmp, "rb") as handle:
                os.fsync(handle.fileno())
        self.fresh = False

    def open(self, resume):
        """:meth:`read`, then :meth:`start`: the rows kept."""
        kept = self.read(resume)
        self.start(kept)
        return kept

    def append(self, row):
        """Add one finished row, on disk before returning; OutputError (one line) if it cannot
        be written, the journal left as it was.  A write that fails part-way (a full disk) is cut
        back off, so no half line is left for the next row to be glued to."""
        if self.fresh:
            try:
                self._replace(row)
            except OSError as err:
                raise OutputError(f"cannot write the journal {str(self.path)!r}: "
                                  f"{os.strerror(err.errno) if err.errno else err}") from None
            return
        data = self._line(row).encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            size = os.fstat(fd).st_size
            try:
                written = os.write(fd, data)
                if written != len(data):
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                os.fsync(fd)
            except OSError as err:
                with contextlib.suppress(OSError):
                    os.ftruncate(fd, size)
                raise OutputError(f"cannot append to the journal {str(self.path)!r}: "
                                  f"{os.strerror(err.errno) if err.errno else err}") from None
        finally:
            os.close(fd)

    @staticmethod
    def _line(obj):
        return json.dumps(obj, allow_nan=False) + "\n"

    def _fail(self, number, why):
        raise InputError(f"resume: {self.path} line {number} {why}; delete that line, or "
                         "run without --resume to start fresh")

    def _lines(self):
        """The journal's whole lines as (number, text); a torn last line is left out."""
        raw = self.path.read_bytes()
        lines = []
        for number, chunk in enumerate(raw[:raw.rfind(b"\n") + 1].split(b"\n")[:-1],
                                       start=1):
            try:
                lines.append((number, chunk.decode("utf-8")))
            except UnicodeDecodeError as err:
                self._fail(number, f"is not UTF-8 (byte {err.start + 1})")
        return lines

    def _check_header(self, lines):
        try:
            header = json.loads(lines[0][1]) if lines else None
        except json.JSONDecodeError:
            header = None
        kind = self.header["journal"].split()[-1]  # "sweep" or "porkchop"
        if not isinstance(header, dict) or header.get("journal") != self.header["journal"]:
            raise InputError(f"resume: {self.path} is not a {kind} journal (line 1 is not "
                             "its header); run without --resume to start fresh")
        for key in [*self.header, *(k for k in header if k not in self.header)]:
            if header.get(key) != self.header.get(key):
                what = ("the problem file changed since it was written" if key == "source_sha256"
                        else f"its {key} is {_short(header.get(key))}, not "
                             f"{_short(self.header.get(key))}")
                raise InputError(f"resume: {self.path} belongs to another {kind}: {what}; "
                                 "run without --resume to start fresh")

    def _row(self, number, line):
        """The row of journal line ``number``, every field checked (InputError)."""
        def constant(name):  # NaN and Infinity: never written, so never accepted
            self._fail(number, f"holds {name}, which is not a number")

        try:
            row = json.loads(line, parse_constant=constant)
        except json.JSONDecodeError as err:
            self._fail(number, f"is not JSON ({err.msg}, column {err.colno})")
        if not isinstance(row, dict):
            self._fail(number, "is not a row (a JSON object)")
        for field, hint in typing.get_type_hints(self.row_type).items():
            why = _why_not(row.get(field), hint)
            if why is not None:
                self._fail(number, f"is not a valid row: {field} {why}")
        why = self.invalid(row)
        if why is not None:
            self._fail(number, f"is not a valid row: {why}")
        return {field: row.get(field) for field in fields(self.row_type)}
