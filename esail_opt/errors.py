"""The one exception type for bad user input.

The command line prints its message on one line and exits with status 2; the
message names the field and the allowed range.
"""

import math


class InputError(ValueError):
    """Bad input from a user: a problem file, a command-line option or an API argument."""


def check_range(name, value, low=-math.inf, high=math.inf, low_open=False, high_open=False,
                unit=""):
    """Return ``float(value)`` if it lies in the stated interval, else raise InputError.

    The message reads e.g. ``e0 = 1.2 is outside [0, 1)`` so a user can fix it.
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} = {value!r} is not a number") from None
    below = number <= low if low_open else number < low
    above = number >= high if high_open else number > high
    if math.isnan(number) or below or above:
        left = "(" if low_open else "["
        right = ")" if high_open else "]"
        suffix = f" {unit}" if unit else ""
        raise InputError(
            f"{name} = {value!r}{suffix} is outside {left}{_fmt(low)}, {_fmt(high)}{right}{suffix}"
        )
    return number


def _fmt(bound):
    if math.isinf(bound):
        return "inf" if bound > 0 else "-inf"
    return f"{bound:g}"
