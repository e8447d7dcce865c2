"""``usv-mj kinds``: every kind of every registry, where it comes from, and its options.

For each registry of :data:`usv_mj.core.registry.REGISTRIES` (controller, trajectory, plant,
disturbance, vessel, manoeuvre, and the environments' tasks with their tags) and each kind: its source ("built-in", "entry point GROUP (dist
NAME VERSION)", "module:Name", "registered at runtime (module M)"), the object that makes it, and
its options dataclass's fields (name, type, default, unit). A kind that cannot be loaded (a broken
entry point) is listed with its one-line error.

Units follow one convention, the house rule of parameter dataclasses: the unit is the first
``[...]`` in the field's documentation, its trailing comment (``speed: float = 0.6  # [m/s] ...``)
or else its entry in the class docstring's ``Attributes`` section (``l1, l2: ... [1/s]``; a
bracket listing one unit per name, ``[N s/m, N/m]``, is split among them). A bracket of numbers
(``[-16, 16]``) is not a unit. ``[-]``: dimensionless.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import re

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import UnknownKindError
from usv_mj.core.registry import REGISTRIES
from usv_mj.scenario.kinds import scenario_kinds, worker_imports  # noqa: F401 (re-exported)

_BRACKET = re.compile(r"\[([^\[\]]+)\]")
_NUMBERS = re.compile(r"[-+\d.,\s eE]*")


def _first_unit(text: str) -> str:
    for m in _BRACKET.finditer(text or ""):
        if not _NUMBERS.fullmatch(m.group(1)):
            return m.group(1).strip()
    return ""


def _comment_units(cls) -> dict:
    """name -> the unit of the field's trailing comment (fields of ``cls`` and its bases)."""
    out: dict = {}
    for klass in reversed(cls.__mro__):
        try:
            lines = inspect.getsource(klass).splitlines()
        except (OSError, TypeError):
            continue
        for line in lines:
            m = re.match(r"^\s*(\w+)\s*:[^#]*#(.*)$", line)
            if m and _first_unit(m.group(2)):
                out[m.group(1)] = _first_unit(m.group(2))
    return out


def _docstring_units(cls) -> dict:
    """name -> the unit of its numpydoc ``Attributes`` entry (the built-ins' older convention)."""
    out: dict = {}
    doc = inspect.getdoc(cls) or ""
    lines = doc.splitlines()
    try:
        start = next(i for i, l in enumerate(lines) if l.strip() == "Attributes") + 2
    except StopIteration:
        return out
    entries, names, text = [], None, ""
    for line in lines[start:]:
        if line.strip() and not line.startswith(" "):
            m = re.match(r"^([\w, ]+):(.*)$", line)
            if m is None:
                break
            if names is not None:
                entries.append((names, text))
            names, text = [n.strip() for n in m.group(1).split(",") if n.strip()], m.group(2)
        elif names is not None:
            text += " " + line.strip()
    if names is not None:
        entries.append((names, text))
    for names, text in entries:
        brackets = [m.group(1) for m in _BRACKET.finditer(text) if not _NUMBERS.fullmatch(m.group(1))]
        parts = [p.strip() for b in brackets for p in b.split(",")]
        for i, name in enumerate(names):
            # one unit per name (over one or more brackets), else the first bracket for every name
            out[name] = parts[i] if len(names) > 1 and len(parts) == len(names) else _first_unit(text)
    return out


def describe_options(cls, derived: dict | None = None) -> list[dict]:
    """The fields of an options dataclass: ``{"name", "type", "default", "unit"}`` each, and
    ``"derived": true`` for a gain the class derives from the vessel (its ``DERIVED``, docs/gains.md:
    the default shown is the paper hull's, or ``derived``'s value for the vessel asked for)."""
    if cls is None:
        return []
    derived_names = set(getattr(cls, "DERIVED", ()) if hasattr(cls, "for_vessel") else ())
    units = _docstring_units(cls)
    units.update(_comment_units(cls))
    out = []
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = None
        unit = f.metadata.get("unit") if f.metadata else None
        row = {"name": f.name, "type": f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type)),
               "default": _plain(derived[f.name] if derived and f.name in derived else default),
               "unit": unit or units.get(f.name, "")}
        if f.name in derived_names:
            row["derived"] = True
        out.append(row)
    return out


def vessel_gains(vessel: str) -> dict:
    """``{controller kind: {gain: value}}``: the gains each controller that derives its defaults
    (PI, LOS: ``for_vessel``, docs/gains.md) gets on ``vessel`` (a kind or a data file's path)."""
    from usv_mj.core.registry import CONTROLLERS
    from usv_mj.physics.design import DesignPoint, Scaling
    from usv_mj.scenario.spec import load_scenario

    sc = load_scenario(overrides={"vessel": {"kind": vessel}})
    scaling = Scaling(DesignPoint.of(sc.nominal_ship, sc.vessel.model.dimensions.L))
    out = {}
    for kind in CONTROLLERS.kinds():
        try:
            gains = CONTROLLERS.get(kind).info.get("gains")
        except Exception:   # noqa: BLE001 - a broken entry point is listed by list_kinds with its error
            continue
        if gains is not None and hasattr(gains, "for_vessel"):
            out[kind] = gains.for_vessel(scaling)
    return out


def _plain(value):
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {k: _plain(v) for k, v in dataclasses.asdict(value).items()}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and value != value:
        return None
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    return repr(value)


def list_kinds(sections=None, vessel: str | None = None) -> dict:
    """section -> {"group", "kinds": [{"kind", "source", "object", "options" | "error"}]}; with
    ``vessel``, a controller's derived gains are that vessel's (:func:`vessel_gains`)."""
    derived = vessel_gains(vessel) if vessel else {}
    out = {}
    for section, registry in REGISTRIES.items():
        if sections and section not in sections:
            continue
        rows = []
        for kind in registry.kinds():
            try:
                entry = registry.get(kind, f"{section} kind")
            except UnknownKindError as exc:
                rows.append({"kind": kind, "source": "entry point (cannot be loaded)", "error": str(exc)})
                continue
            obj = entry.obj
            rows.append({"kind": kind, "source": entry.source,
                         "object": f"{getattr(obj, '__module__', '?')}.{getattr(obj, '__qualname__', repr(obj))}",
                         "options": describe_options(entry.options_class,
                                                     derived.get(kind) if section == "controller" else None)})
            if "tags" in entry.info:   # an environment task's (usv_mj.core.registry.TASKS)
                rows[-1]["tags"] = list(entry.info["tags"])
        out[section] = {"group": registry.group, "common": _common_options(section), "kinds": rows}
    return out


def _common_options(section: str) -> list[dict]:
    """The keys of a section that every kind takes (the plant's ``substeps``), beside ``kind``."""
    from usv_mj.scenario.spec import PlantSpec

    if section != "plant":
        return []
    return [o for o in describe_options(PlantSpec) if o["name"] not in ("kind", "options")]


def add_arguments(p) -> None:
    p.add_argument("section", nargs="*", metavar="REGISTRY",
                   help=f"only these registries ({', '.join(REGISTRIES)}); default: all")
    flags.add_vessel_argument(p, use="the gains a controller derives from the vessel (PI, LOS; docs/gains.md) "
                                     "are shown for it instead of the paper hull's")
    flags.add_json_argument(p)


@COMMANDS.register(
    "kinds", arguments=add_arguments,
    help="every controller, trajectory, plant and disturbance kind: where it comes from, its options",
    description="List every kind a scenario may name, registry by registry (controller, trajectory, plant,\n"
                "disturbance): where it comes from (built-in, an entry point's distribution, module:Name,\n"
                "registered at runtime) and its options (name, type, default, unit). A controller's gains derived\n"
                "from the vessel (PI, LOS: docs/gains.md) are marked, shown for the paper hull or --vessel KIND.\n"
                "--json for one object.")
def run(args) -> int:
    for name in args.section:
        if name not in REGISTRIES:
            import difflib

            from usv_mj.core.errors import ScenarioError

            hint = difflib.get_close_matches(name.rstrip("s"), list(REGISTRIES), n=1)
            raise ScenarioError(f"unknown registry {name!r}" + (f" (did you mean {hint[0]!r}?)" if hint else "")
                                + f"; registries: {', '.join(REGISTRIES)}")
    table = list_kinds(args.section or None, vessel=args.vessel)
    if args.json:
        print(json.dumps(table, indent=2))
        return 0
    for section, block in table.items():
        print(f"{section} kinds (entry-point group {block['group']}; or 'package.module:Name'):")
        for o in block["common"]:
            print(f"  every kind: {o['name']} ({o['type']}, default {json.dumps(o['default'])})")
        for row in block["kinds"]:
            if "error" in row:
                print(f"  {row['kind']:14s} {row['source']}: {row['error']}")
                continue
            print(f"  {row['kind']:14s} {row['source']}  ({row['object']})")
            if "tags" in row:
                print(f"      tags: {', '.join(row['tags']) or '(none)'}")
            for o in row["options"]:
                unit = f"[{o['unit']}]" if o["unit"] else ""
                how = (f"  derived from the vessel ({args.vessel or 'paper hull'}'s shown; docs/gains.md)"
                       if o.get("derived") else "")
                print(f"      {o['name']:18s} {o['type']:24s} {json.dumps(o['default']):24s} {unit}{how}")
            if not row["options"]:
                print("      (no options)")
        print()
    return 0
