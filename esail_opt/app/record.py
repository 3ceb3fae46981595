"""Frozen records written to JSON from their fields and read back by the same fields.

A record is a frozen dataclass deriving from :class:`Record`: each field is one key of its
JSON object, named as the field unless :func:`key` gives a ``name`` (a dotted one nests:
``"refinement.rounds"``).  A key is left out when the field's ``omit(record, value)`` holds
(:func:`if_none`: absent rather than null).  A ``flat`` dict field puts its items in the
record's own object: the keys it lists, or with :data:`REST` every key no other field names.
Values convert by their annotation (dataclasses by their fields, an ``Enum`` by its value,
lists and tuples item by item); a field without a default must be in the file.  A record
holds plain JSON values only (:func:`plain`), so one built in memory equals the same one
read back from its file.
"""

import dataclasses
import enum
import functools
import math
import typing

import numpy as np

#: The ``flat`` of a field that takes every key no other field of its record names.
REST = "*"
_ABSENT = object()
#: The JSON values a record keeps as they are (floats are checked to be finite).
_SCALARS = (str, int, bool, type(None))


class BadField(ValueError):
    """A JSON value that cannot be read as its field: ``field`` is its dotted key (""
    for the object itself), ``why`` what is wrong with it."""

    def __init__(self, field, why):
        super().__init__(f"{field} {why}".strip())
        self.field, self.why = field, why

    def within(self, name):
        """The same fault, named from the object that holds field ``name``."""
        return BadField(f"{name}.{self.field}" if self.field else name, self.why)


def key(name=None, *, omit=None, flat=None, default=dataclasses.MISSING):
    """A record's field with its place in the JSON object (see the module's docstring)."""
    meta = {k: v for k, v in (("key", name), ("omit", omit), ("flat", flat)) if v is not None}
    return dataclasses.field(default=default, metadata=meta)


def if_none(record, value):
    """``omit`` of a key that is absent, rather than null, when its field is None."""
    return value is None


@functools.lru_cache(maxsize=None)
def _hints(cls):
    return typing.get_type_hints(cls)


def _unwrap(hint):
    """``X`` of ``Optional[X]``; any other hint as it is."""
    if typing.get_origin(hint) is typing.Union:
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        return args[0] if len(args) == 1 else hint
    return hint


def plain(value):
    """``value`` as plain JSON values: numpy numbers as Python ones, NaN and infinity as
    None, arrays and tuples as lists; records and enums as they are, other dataclasses
    field by field."""
    kind = type(value)
    if kind is float:
        return value if math.isfinite(value) else None
    if kind in _SCALARS or isinstance(value, (Record, enum.Enum)):
        return value
    if kind is list or kind is tuple:
        return [plain(v) for v in value]
    if kind is dict:
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (np.ndarray, np.generic)):
        return plain(value.tolist())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return type(value)(**{f.name: plain(getattr(value, f.name))
                              for f in dataclasses.fields(value)})
    return value


def _field_value(hint, value):
    """A field's value made plain, in the container its annotation names."""
    if isinstance(value, (list, tuple)) and typing.get_origin(_unwrap(hint)) is tuple:
        return tuple(plain(v) for v in value)
    return plain(value)


class Record:
    """Base of the records: plain values on construction, JSON by the fields."""

    def __post_init__(self):
        hints = _hints(type(self))
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _field_value(hints[f.name], getattr(self, f.name)))

    def to_json(self):
        """The record's JSON object: a new dict of plain JSON values each call."""
        return write(self)

    @classmethod
    def from_json(cls, data):
        """The record that :meth:`to_json` wrote as ``data`` (None for None)."""
        return None if data is None else read(cls, data)


def encode(value):
    """A field's value as JSON."""
    kind = type(value)
    if kind is float or kind in _SCALARS:
        return value
    if kind is list or kind is tuple:
        return [encode(v) for v in value]
    if kind is dict:
        return {k: encode(v) for k, v in value.items()}
    if isinstance(value, enum.Enum):
        return value.value
    if hasattr(value, "to_json"):
        return value.to_json()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return write(value)
    return value


@functools.lru_cache(maxsize=None)
def _as_is(hint):
    """Whether JSON is a field annotated ``hint`` as it is: no record, enum or other
    dataclass is in it (the record's construction makes its containers)."""
    hint = _unwrap(hint)
    if typing.get_origin(hint) in (list, tuple):
        return _as_is(typing.get_args(hint)[0])
    return not (isinstance(hint, type) and (issubclass(hint, enum.Enum)
                                            or hasattr(hint, "from_json")
                                            or dataclasses.is_dataclass(hint)))


def decode(hint, value):
    """JSON ``value`` as a field annotated ``hint``."""
    if value is None or _as_is(hint):
        return value
    hint = _unwrap(hint)
    origin = typing.get_origin(hint)
    if origin in (list, tuple):
        if not isinstance(value, list):
            raise BadField("", f"= {_short(value)} is not a list")
        item = typing.get_args(hint)[0]
        return origin(decode(item, v) for v in value)
    if issubclass(hint, enum.Enum):
        return hint(value)
    if hasattr(hint, "from_json"):
        return hint.from_json(value)
    return read(hint, value)


def _name(f):
    return f.metadata.get("key", f.name)


def write(record):
    """The JSON object of a dataclass ``record``, its keys in the order of its fields."""
    out = {}
    for f in dataclasses.fields(record):
        value = getattr(record, f.name)
        omit = f.metadata.get("omit")
        if omit is not None and omit(record, value):
            continue
        if "flat" in f.metadata:
            out.update(encode(value or {}))
            continue
        *parents, last = _name(f).split(".")
        where = out
        for parent in parents:
            where = where.setdefault(parent, {})
        where[last] = encode(value)
    return out


def _lookup(data, name, required):
    """The value at a dotted ``name`` in ``data``; ``_ABSENT`` when it is not there and
    not ``required`` (a missing required key raises KeyError naming it)."""
    for part in name.split("."):
        if not required and part not in data:
            return _ABSENT
        data = data[part]
    return data


def _nullable(hint):
    return typing.get_origin(hint) is typing.Union and type(None) in typing.get_args(hint)


def _short(value):
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def read(cls, data):
    """The dataclass ``cls`` from the JSON object ``data`` that :func:`write` made; raises
    :class:`BadField` naming the dotted key missing, null where not nullable, or mistyped."""
    if not isinstance(data, dict):
        raise BadField("", f"= {_short(data)} is not a JSON object")
    fields = dataclasses.fields(cls)
    named = {_name(f).split(".")[0] for f in fields if "flat" not in f.metadata}
    hints, values = _hints(cls), {}
    for f in fields:
        flat = f.metadata.get("flat")
        if flat == REST:
            values[f.name] = {k: v for k, v in data.items() if k not in named}
        elif flat is not None:
            values[f.name] = {k: data[k] for k in flat if k in data} or None
        else:
            values[f.name] = _read_field(f, hints[f.name], data)
            if values[f.name] is _ABSENT:
                del values[f.name]
    try:
        return cls(**values)
    except (TypeError, ValueError) as err:  # a record's own check of its fields
        raise BadField("", f"is not valid: {err}") from None


def _read_field(f, hint, data):
    """Field ``f`` (annotated ``hint``) of the JSON object ``data``, or ``_ABSENT``."""
    name = _name(f)
    required = f.default is dataclasses.MISSING
    try:
        value = _lookup(data, name, required)
    except KeyError:
        raise BadField(name, "is missing") from None
    except TypeError:
        raise BadField(name.rpartition(".")[0], "is not a JSON object") from None
    if value is None and required and not _nullable(hint):
        raise BadField(name, "is null")
    if value is _ABSENT:
        return value
    try:
        return decode(hint, value)
    except BadField as err:
        raise err.within(name) from None
    except (TypeError, ValueError, AttributeError, KeyError):
        raise BadField(name, f"= {_short(value)} is not a {_kind(hint)}") from None


def _kind(hint):
    hint = _unwrap(hint)
    return getattr(hint, "__name__", None) or str(hint).replace("typing.", "")
