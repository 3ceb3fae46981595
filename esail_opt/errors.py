"""The exceptions the command line turns into one line and an exit status.

:class:`InputError` is bad user input (exit 2); its message names the field and the
allowed range.  :class:`NoStart` is a valid problem that no start can be flown for
(exit 1).  :class:`OutputError` is an output folder or file that cannot be
written (exit 3).  :class:`FigureError` is a figure that could not be drawn while the
rest of its set was written (exit 4).  :class:`Terminated` is SIGTERM, raised where Python would raise
KeyboardInterrupt for SIGINT (exit 143; :mod:`esail_opt.runtime.signals` raises it).  They live
in the lowest layer because every layer may raise them.
"""

import math
import unicodedata


class InputError(ValueError):
    """Bad input from a user: a problem file, a command-line option or an API argument."""


class NoStart(Exception):
    """A valid problem for which no start can be flown: at the seed's constant pitch the
    sail escapes the Sun (which the closed form cannot follow), winds past
    ``max_revolutions``, or needs its target body after the dates it is known at,
    before it reaches its aim.  Not bad input: the command says why in one line,
    writes nothing and exits 1 (nothing was solved)."""


class OutputError(Exception):
    """An output cannot be written (a full disk, a read-only folder, a path under a
    regular file); the message is one line that names the path and what to do."""


class FigureError(Exception):
    """One or more figures could not be drawn; every other file of the set was written.

    The message is one line: each figure's failure
    (``esail_opt.app.plots.figure_failure``), joined by "; ".  ``written`` lists the
    paths that were written.
    """

    def __init__(self, failures, written=()):
        super().__init__("; ".join(failures))
        self.failures = list(failures)
        self.written = list(written)


class Terminated(KeyboardInterrupt):
    """The process was asked to stop by a signal other than SIGINT (SIGTERM).

    A KeyboardInterrupt, so that every clean-up written for Ctrl-C (stopping workers,
    removing temporary files, stopping Ipopt at its next iteration) runs for it too;
    ``signum`` tells the command line which exit status to give (128 + signum).
    """

    def __init__(self, signum=15):
        super().__init__(signum)
        self.signum = signum


#: Most values one START:STOP:COUNT range may give.
MAX_RANGE_COUNT = 10_000


def number_range(field, text, max_count=MAX_RANGE_COUNT):
    """``START:STOP:COUNT`` -> COUNT numbers from START to STOP, both ends included.

    The grid is numpy's linspace, so it ends exactly on STOP and the same text always
    gives the same floats; COUNT = 1 needs START = STOP.  This is the one reader of a
    numeric range for every command (a sweep's parameter, a porkchop's times of flight,
    the propagation's grids), so they all take and refuse the same texts.

    Raises
    ------
    InputError
        One line naming ``field``: not three parts, START or STOP not finite numbers,
        COUNT not an integer in [1, ``max_count``], COUNT = 1 between two ends, or
        COUNT > 1 between equal ones.
    """
    import numpy as np

    parts = str(text).split(":")
    if len(parts) != 3:
        raise InputError(f"{field} = {text!r}: expected START:STOP:COUNT")
    try:
        start, stop = float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"{field} = {text!r}: START and STOP must be numbers") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise InputError(f"{field} = {text!r}: START and STOP must be finite")
    try:
        count = int(parts[2])
    except ValueError:
        raise InputError(f"{field} = {text!r}: COUNT = {parts[2]!r} is not an integer"
                         ) from None
    if not 1 <= count <= max_count:
        raise InputError(f"{field} = {text!r}: COUNT = {count} is outside [1, {max_count}]")
    if count == 1 and start != stop:
        # One value between two ends could mean either end: the user says which.
        raise InputError(f"{field} = {text!r}: COUNT = 1 needs START = STOP")
    if count > 1 and start == stop:
        raise InputError(f"{field} = {text!r}: COUNT = {count} needs START != STOP "
                         "(every value would be the same)")
    return np.linspace(start, stop, count).tolist()


def check_range(name, value, low=-math.inf, high=math.inf, low_open=False, high_open=False,
                unit=""):
    """Return ``float(value)`` if it lies in the stated interval, else raise InputError.

    The message reads e.g. ``e0 = 1.2 is outside [0, 1)`` so a user can fix it.  A
    string is refused even when it spells a number (``"650"``): the field would keep
    the string, and the first arithmetic on it would fail far from the problem file
    with a TypeError that names no field.
    """
    left = "(" if low_open else "["
    right = ")" if high_open else "]"
    suffix = f" {unit}" if unit else ""
    allowed = f"{left}{_fmt(low)}, {_fmt(high)}{right}{suffix}"
    if isinstance(value, (str, bytes)):
        raise InputError(f"{name} = {value!r} is a string, not a number in {allowed}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} = {value!r} is not a number") from None
    below = number <= low if low_open else number < low
    above = number >= high if high_open else number > high
    if math.isnan(number) or below or above:
        raise InputError(f"{name} = {value!r}{suffix} is outside {allowed}")
    return number


def _fmt(bound):
    if math.isinf(bound):
        return "inf" if bound > 0 else "-inf"
    return f"{bound:g}"


#: The control characters a user may meet by name, for :func:`check_printable`'s line.
_CONTROLS = {"\0": "NUL", "\t": "tab", "\n": "newline", "\r": "CR", "\x1b": "ESC"}


def check_printable(name, value, allowed="printable characters"):
    """Return ``value`` if it is a non-empty string of printable characters, else raise
    InputError naming ``name`` and what is allowed.

    Printable is :meth:`str.isprintable`: no control characters (ESC, CR, tab, newline,
    NUL), no lone surrogates (which no file name or terminal can encode), no format or
    line-separator characters; a space is allowed.  Such a name is written into folder
    names, file contents and one-line messages, where a control character would rewrite
    the terminal's line or split a line in two.  ``allowed`` says what the field takes,
    for the message.
    """
    if not isinstance(value, str) or not value:
        raise InputError(f"{name} = {value!r} is not a non-empty string of {allowed}")
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        kind = {"Cc": "a control character", "Cs": "a lone surrogate"}.get(
            unicodedata.category(bad), "a non-printable character")
        code = f"U+{ord(bad):04X}" + (f" {_CONTROLS[bad]}" if bad in _CONTROLS else "")
        raise InputError(f"{name} = {value!r} holds {kind} ({code}); allowed: {allowed}")
    return value
