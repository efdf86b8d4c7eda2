"""Where a session's results hold something their record classes do not declare (issue #24: typed
records to the leaves). A stage result is typed when every value of every record field is of
the field's declared type (a record, an array, a number, a string, or a map of them keyed by
the data's own names: sensors, segments, joints, steps, columns) and nothing is left in a
record's ``more`` (the keys a newer motionlab wrote, which this version does not know)."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

import numpy as np

NUMBER = (int, float, np.integer, np.floating)


def _fits(value: Any, hint: Any) -> bool:
    """Whether ``value`` is of the declared type ``hint`` (as far as a stored value can be: a
    list read back from the file may be an array, a float may be a NumPy scalar)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any:
        return True
    if hint is type(None):
        return value is None
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, a) for a in args)
    if origin is dict:
        return isinstance(value, dict) and all(
            isinstance(k, str) and _fits(v, args[1]) for k, v in value.items()
        )
    if origin in (list, tuple) or hint in (list, tuple):
        return isinstance(value, (list, tuple, np.ndarray))
    if hint is float:
        return isinstance(value, NUMBER) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if hint is bool:
        return isinstance(value, (bool, np.bool_))
    if hint is str:
        return isinstance(value, str)
    if hint is np.ndarray:
        return isinstance(value, np.ndarray)
    if isinstance(hint, type):
        return isinstance(value, hint)
    return False


def untyped(value: Any, where: str = "results") -> list[str]:
    """One line per place under ``value`` (a record, or a map of them) holding something its
    record does not declare: a field whose value is not of the field's type, or a ``more`` that
    is not empty."""
    found: list[str] = []
    if dataclasses.is_dataclass(value):
        hints = typing.get_type_hints(type(value))
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            if f.name == "more":
                if v:
                    found.append(f"{where}.more holds {sorted(v)}")
            elif not _fits(v, hints[f.name]):
                found.append(f"{where}.{f.name} is a {type(v).__name__}, not {hints[f.name]}")
            else:
                found += untyped(v, f"{where}.{f.name}")
    elif isinstance(value, dict):
        for k, v in value.items():
            found += untyped(v, f"{where}[{k!r}]")
    return found
