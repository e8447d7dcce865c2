"""The public API's arguments checked at its door (issue 38, item 21).

Each check raises :class:`usv_mj.core.errors.ArgumentTypeError` (a TypeError) for an argument of
the wrong kind, or :class:`usv_mj.core.errors.ArgumentValueError` (a ValueError) for a value the
function cannot take, with one line naming the function, the argument, what it takes and what it
got (:func:`usv_mj.core.errors.expected`): never an AttributeError or a numpy cast error from deep
inside, and never a bool or a string taken for a number (``duration=True``, ``duration='1'``).
A leaf module: it imports nothing of the package but the errors.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping

from usv_mj.core.errors import ArgumentValueError, expected


def is_real(value) -> bool:
    """A real number (int, float, numpy's), not a bool (nor a string that reads as one)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and type(value).__name__ != "bool_"


def is_integer(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool) and type(value).__name__ != "bool_"


def seconds(where: str, name: str, value, *, none: bool = True) -> float | None:
    """``value`` as a finite number of seconds > 0 (None passes when ``none``)."""
    if value is None and none:
        return None
    what = "a number of seconds > 0" + (" or None" if none else "")
    if not is_real(value):
        raise expected(where, name, what, value)
    if not (math.isfinite(value) and value > 0):
        raise ArgumentValueError(f"{where}: {name} must be {what}, got {value!r}")
    return float(value)


def integer(where: str, name: str, value, minimum: int, what: str | None = None) -> int:
    """``value`` as an integer >= ``minimum`` (not a bool, not a float)."""
    what = what or f"an integer >= {minimum}"
    if not is_integer(value):
        raise expected(where, name, what, value)
    if value < minimum:
        raise ArgumentValueError(f"{where}: {name} must be {what}, got {value!r}")
    return int(value)


def callable_or_none(where: str, name: str, value, what: str):
    if value is not None and not callable(value):
        raise expected(where, name, what, value)
    return value


def having(where: str, name: str, value, attributes, what: str):
    """``value`` when it has every one of ``attributes`` (an object of an interface)."""
    missing = [a for a in attributes if not hasattr(value, a)]
    if missing:
        raise expected(where, name, f"{what} (with {', '.join(attributes)}; it has no {', '.join(missing)})", value)
    return value


def each(where: str, name: str, values, what: str, check, many: str) -> tuple:
    """``values`` (an iterable, not a string) as a tuple, each item passing ``check(item)``;
    ``what`` names one item (the message says which one failed), ``many`` the list."""
    if isinstance(values, (str, bytes, Mapping)) or not isinstance(values, Iterable):
        raise expected(where, name, many, values)
    items = tuple(values)
    for i, item in enumerate(items):
        if not check(item):
            raise expected(where, f"{name}[{i}]", what, item)
    return items


def string_keys(where: str, name: str, value, path: str = "") -> None:
    """Every key of the nested mapping ``value`` is a string (a scenario's table keys)."""
    for key, item in value.items():
        here = f"{path}[{key!r}]"
        if not isinstance(key, str):
            raise expected(where, f"{name}{path} key", "a scenario key (a string, e.g. 'duration' or 'controller')",
                           key)
        if isinstance(item, Mapping):
            string_keys(where, name, item, here)


def mapping_or_none(where: str, name: str, value, what: str):
    if value is not None and not isinstance(value, Mapping):
        raise expected(where, name, what, value)
    return value
