"""The exceptions the command line turns into one line and an exit status; in the lowest
layer, since every layer may raise them.

:class:`InputError` is bad user input, its message naming the field and the allowed range
(exit 2); :class:`NoStart` a valid problem no start can be flown for (exit 1);
:class:`OutputError` an output that cannot be written (exit 3); :class:`FigureError` a figure
not drawn while the rest of its set was written (exit 4); :class:`Terminated` SIGTERM
(exit 143; :mod:`esail_opt.runtime.signals` raises it).
"""

import math
import unicodedata


class InputError(ValueError):
    """Bad input from a user: a problem file, a command-line option or an API argument."""


class NoStart(Exception):
    """A valid problem for which no start can be flown: at the seed's constant pitch the sail
    escapes the Sun (which the closed form cannot follow), winds past ``max_revolutions``, or
    needs its target body after the dates it is known at.  Not bad input: the command says
    why in one line, writes nothing and exits 1."""


class OutputError(Exception):
    """An output cannot be written (a full disk, a read-only folder, a path under a
    regular file); the message is one line that names the path and what to do."""


class FigureError(Exception):
    """One or more figures could not be drawn; every other file of the set was written.  The
    message joins each figure's failure (``esail_opt.app.plots.figure_failure``) by "; ";
    ``written`` lists the paths written."""

    def __init__(self, failures, written=()):
        super().__init__("; ".join(failures))
        self.failures = list(failures)
        self.written = list(written)


class Terminated(KeyboardInterrupt):
    """SIGTERM (or another signal but SIGINT) as a KeyboardInterrupt, so that every clean-up
    written for Ctrl-C runs for it too; the exit status is 128 + ``signum``."""

    def __init__(self, signum=15):
        super().__init__(signum)
        self.signum = signum


#: Most values one START:STOP:COUNT range may give.
MAX_RANGE_COUNT = 10_000


def number_range(field, text, max_count=MAX_RANGE_COUNT):
    """``START:STOP:COUNT`` -> COUNT numbers from START to STOP, both ends included, by numpy's
    linspace (so exactly STOP, and the same floats for the same text): the one reader of a
    numeric range for every command.

    Raises InputError naming ``field`` for not three parts, START or STOP not finite numbers,
    COUNT not an integer in [1, ``max_count``], COUNT = 1 between two ends, or COUNT > 1
    between equal ones.
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
    """Return ``float(value)`` if it lies in the stated interval, else raise InputError reading
    e.g. ``e0 = 1.2 is outside [0, 1)``.  A string is refused even when it spells a number
    (``"650"``): the field would keep the string and fail later, naming no field."""
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
    """Return ``value`` if it is a non-empty string of printable characters
    (:meth:`str.isprintable`: a space, but no control, lone surrogate, format or line-separator
    character), else raise InputError naming ``name`` and ``allowed``, what the field takes.
    Such names go into folder names, files and one-line messages, where a control character
    would rewrite or split the line."""
    if not isinstance(value, str) or not value:
        raise InputError(f"{name} = {value!r} is not a non-empty string of {allowed}")
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        kind = {"Cc": "a control character", "Cs": "a lone surrogate"}.get(
            unicodedata.category(bad), "a non-printable character")
        code = f"U+{ord(bad):04X}" + (f" {_CONTROLS[bad]}" if bad in _CONTROLS else "")
        raise InputError(f"{name} = {value!r} holds {kind} ({code}); allowed: {allowed}")
    return value
