"""Scenario tables: a TOML table into a validated dataclass, tables merged, a dataclass back into a table.

The generic part of reading a scenario (:mod:`usv_mj.scenario.spec`): every section's dataclass,
a registered kind's options and the ``[manoeuvre]`` table are built by :func:`build_table`, whose
errors name the file and the key (an unknown key with "did you mean").
"""

from __future__ import annotations

import dataclasses
import difflib
from typing import Any

from usv_mj.core.errors import ScenarioError
from usv_mj.support.toml_values import coerce


class KindOptions:
    """A ``[section]`` of ``kind`` plus the kind's own options dataclass (``options``); the options
    read as attributes of the spec too (``scenario.trajectory.speed``, ``.points``)."""

    def __getattr__(self, name):
        if name.startswith("_") or name == "options":
            raise AttributeError(name)
        try:
            return getattr(self.options, name)
        except AttributeError:
            raise AttributeError(f"{type(self).__name__}: kind {self.kind!r} has no option {name!r}") from None


def merge_tables(base: dict, over: dict) -> dict:
    """``base`` with ``over`` merged in, tables recursively (``over`` wins); neither is changed."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge_tables(out[key], value)
        else:
            out[key] = value
    return out


def unknown_key(source, section, key, known):
    hint = difflib.get_close_matches(key, sorted(known), n=1)
    where = f"{section}.{key}" if section else key
    raise ScenarioError(
        f"{source}: unknown key {where!r}" + (f" (did you mean {hint[0]!r}?)" if hint else "")
        + f"; known keys{' of [' + section + ']' if section else ''}: {', '.join(sorted(known))}")


def convert(source: str, where: str, value: Any, default: Any) -> Any:
    return coerce(source, where, value, default, ScenarioError)


def build_table(cls, table: Any, source: str, section: str, extra_known: set | None = None):
    """The dataclass ``cls`` from the scenario table ``[section]``: each key converted to its field's
    type and validated (ScenarioError naming ``source`` and the key; an unknown key with "did you
    mean"); keys in ``extra_known`` are skipped, the fields not given keep their defaults."""
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [{section}] must be a table, got {table!r}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    defaults = cls()
    kwargs = {}
    for key, value in table.items():
        if extra_known and key in extra_known:
            continue
        if key not in fields:
            unknown_key(source, section, key, set(fields) | (extra_known or set()))
        kwargs[key] = convert(source, f"{section}.{key}", value, getattr(defaults, key))
    return construct(cls, kwargs, source, section)


def construct(cls, kwargs, source, section):
    try:
        return cls(**kwargs)
    except ValueError as exc:
        msg = str(exc)
        prefix = f"{section}." if section else ""
        if prefix and msg.startswith(prefix):
            prefix = ""
        # the type is kept (TooManyStepsError), the message gets its place
        raise (type(exc) if isinstance(exc, ScenarioError) else ScenarioError)(f"{source}: {prefix}{msg}") from None


def to_plain(obj):
    if isinstance(obj, KindOptions):  # as its TOML table: kind, the common keys, the kind's own keys
        out = {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)
               if f.name not in ("options", "model")}
        out.update(to_plain(obj.options) if obj.options is not None else {})
        return out
    if dataclasses.is_dataclass(obj):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if f.name not in ("raw",)}
    if isinstance(obj, (tuple, list)):
        return [to_plain(v) for v in obj]
    return obj
