"""Vessels from data files: one TOML file of derivatives is one vessel kind (docs/vessels.md).

The built-in files are ``usv_mj/vessels/data/<kind>.toml`` (importing this module registers each
under its file name); a file of the user's is registered under its path by :func:`register_file`,
or by naming it in a scenario: ``[vessel] kind = "path/to/boat.toml"``. A file::

    description = "CyberShip II, 1:70 supply-ship model"       # one line
    source = "Skjetne, Smogeli and Fossen (2004), MIC 25(1), Tables 1-2"
    notes = ["what the 3-DOF model leaves out", ...]            # optional
    coriolis = "full"            # C = C_RB + C_A (Munk moment); "rigid": C = C_RB only; "none": C = 0
    [derivatives]                # SI units, Fossen's notation (usv_mj.vessels.from_derivatives)
    m = 23.8                     # kg
    x_g = 0.046                  # m, COM ahead of the body origin
    I_z = 1.76                   # kg m^2 about the body origin
    X_udot = -2.0                # kg ... and Y_vdot, Y_rdot, N_vdot, N_rdot
    X_u = -0.72253               # N s/m ... X_uu (X_|u|u), X_uuu, Y_v, Y_vv (Y_|v|v), Y_rv (Y_|r|v),
                                 #   Y_r, Y_vr (Y_|v|r), Y_rr (Y_|r|r), N_v, N_vv, N_rv, N_r, N_vr, N_rr
    [dimensions]
    L = 1.255                    # m (and B, T)
    [crossflow]                  # optional: Fossen's strip-theory cross-flow drag
    cd = 1.0                     # 2-D drag coefficient; rho [kg/m^3] and strips (20) optional
    [actuators]                  # optional: the vessel's own [actuators] table (usv_mj.physics.actuators)
    kind = "twin"
    [manoeuvre]                  # optional: its own defaults of the manoeuvres' options
    approach_speed = 2.34        # m/s (otherwise the paper hull's test Froude-scaled to L:
    yaw_moment = 15.8            # N m  usv_mj.scenario.manoeuvre.vessel_defaults)

Every number of ``[derivatives]``, ``[dimensions]`` and ``[crossflow]`` is an option of the kind,
so a scenario may change one (``[vessel] kind = "otter"``, ``m = 90.0``); the options dataclass of
a file is made from it (its defaults are the file's numbers).
"""

from __future__ import annotations

import dataclasses
import math
import os
from importlib import resources
from typing import Any

from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import MANOEUVRES, VESSELS
from usv_mj.support.toml_values import read_toml

from usv_mj.vessels import CORIOLIS, Dimensions, Vessel, from_derivatives

DERIVATIVES = ("m", "x_g", "I_z", "X_udot", "Y_vdot", "Y_rdot", "N_vdot", "N_rdot",
               "X_u", "X_uu", "X_uuu", "Y_v", "Y_vv", "Y_rv", "Y_r", "Y_vr", "Y_rr",
               "N_v", "N_vv", "N_rv", "N_r", "N_vr", "N_rr")
REQUIRED = ("m", "x_g", "I_z", "X_udot", "Y_vdot", "Y_rdot", "N_vdot", "N_rdot")
TOP_KEYS = {"description", "source", "notes", "coriolis", "uncertainty_scale", "derivatives", "dimensions",
            "crossflow", "actuators", "manoeuvre"}
RHO_WATER = 1025.0  # kg/m^3, the cross-flow drag's default density
UNITS = {"m": "kg", "x_g": "m", "I_z": "kg m^2", "X_udot": "kg", "Y_vdot": "kg", "Y_rdot": "kg m", "N_vdot": "kg m",
         "N_rdot": "kg m^2", "X_u": "kg/s", "X_uu": "kg/m", "X_uuu": "kg s/m^2", "Y_v": "kg/s", "Y_vv": "kg/m",
         "Y_rv": "kg", "Y_r": "kg m/s", "Y_vr": "kg", "Y_rr": "kg m", "N_v": "kg m/s", "N_vv": "kg", "N_rv": "kg m",
         "N_r": "kg m^2/s", "N_vr": "kg m", "N_rr": "kg m^2", "L": "m", "B": "m", "T": "m", "crossflow_cd": "-",
         "rho": "kg/m^3", "strips": "-", "uncertainty_scale": "-", "coriolis": ""}


class _DataOptions:
    """Base of a data file's options dataclass: every number finite (checked at construction).

    An instance pickles as the file's kind, its contents and the values (:func:`_data_options`), not
    by its class's name: the class is made at runtime by the process that read the file, so another
    process (a sweep's Dask worker) has no such class until it registers the kind from those contents.
    """

    _datafile = ("", {})   # (kind, contents of read_file): set on each file's class

    def __reduce__(self):
        kind, contents = type(self)._datafile
        return _data_options, (kind, contents, {f.name: getattr(self, f.name) for f in dataclasses.fields(self)})

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, float) and not math.isfinite(value):
                raise ValueError(f"vessel.{f.name} must be a finite number, got {value!r}")
        if self.coriolis not in CORIOLIS:
            raise ValueError(f"vessel.coriolis must be one of {', '.join(CORIOLIS)}, got {self.coriolis!r}")
        if self.strips < 1:
            raise ValueError(f"vessel.strips must be >= 1, got {self.strips!r}")
        if self.crossflow_cd < 0 or self.rho <= 0:
            raise ValueError(f"vessel.crossflow_cd must be >= 0 and vessel.rho > 0, got {self.crossflow_cd!r}, "
                             f"{self.rho!r}")


def _number(path, where, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ScenarioError(f"{path}: {where} must be a finite number, got {value!r}")
    return float(value)


def _table(path, data, key) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise ScenarioError(f"{path}: [{key}] must be a table, got {value!r}")
    return value


def read_file(path) -> dict:
    """The checked contents of a vessel data file: {"options": {name: default}, "description", "source",
    "notes", "actuators"}; :class:`ScenarioError` names the file and the key of anything wrong."""
    data = read_toml(path, ScenarioError, "vessel data file")
    for key in data:
        if key not in TOP_KEYS:
            raise ScenarioError(f"{path}: unknown key {key!r}; a vessel file has {', '.join(sorted(TOP_KEYS))}")
    der, dims, cf = _table(path, data, "derivatives"), _table(path, data, "dimensions"), _table(path, data, "crossflow")
    for key in der:
        if key not in DERIVATIVES:
            raise ScenarioError(f"{path}: unknown derivative {key!r}; derivatives: {', '.join(DERIVATIVES)}")
    missing = [k for k in REQUIRED if k not in der] + [k for k in ("L", "B", "T") if k not in dims]
    if missing:
        raise ScenarioError(f"{path}: missing {', '.join(missing)} (the rigid body, the added mass and L, B, T "
                            f"are required)")
    for key in dims:
        if key not in ("L", "B", "T"):
            raise ScenarioError(f"{path}: unknown key dimensions.{key!r}; dimensions: L, B, T")
    for key in cf:
        if key not in ("cd", "rho", "strips"):
            raise ScenarioError(f"{path}: unknown key crossflow.{key!r}; crossflow: cd, rho, strips")
    options: dict[str, Any] = {k: _number(path, f"derivatives.{k}", der.get(k, 0.0)) for k in DERIVATIVES}
    options.update({k: _number(path, f"dimensions.{k}", dims[k]) for k in ("L", "B", "T")})
    options["crossflow_cd"] = _number(path, "crossflow.cd", cf.get("cd", 0.0))
    options["rho"] = _number(path, "crossflow.rho", cf.get("rho", RHO_WATER))
    strips = cf.get("strips", 20)
    if isinstance(strips, bool) or not isinstance(strips, int) or strips < 1:
        raise ScenarioError(f"{path}: crossflow.strips must be an integer >= 1, got {strips!r}")
    options["strips"] = strips
    options["coriolis"] = data.get("coriolis", "full")
    if options["coriolis"] not in CORIOLIS:
        raise ScenarioError(f"{path}: coriolis must be one of {', '.join(CORIOLIS)}, got {options['coriolis']!r}")
    options["uncertainty_scale"] = _number(path, "uncertainty_scale", data.get("uncertainty_scale", 0.0))
    notes = data.get("notes", [])
    if not (isinstance(notes, list) and all(isinstance(n, str) for n in notes)):
        raise ScenarioError(f"{path}: notes must be a list of strings, got {notes!r}")
    actuators = data.get("actuators")
    if actuators is not None and not isinstance(actuators, dict):
        raise ScenarioError(f"{path}: [actuators] must be a table, got {actuators!r}")
    manoeuvre = data.get("manoeuvre")
    if manoeuvre is not None:
        if not isinstance(manoeuvre, dict):
            raise ScenarioError(f"{path}: [manoeuvre] must be a table, got {manoeuvre!r}")
        kinds = {e.kind: e.options_class for e in MANOEUVRES.entries()}   # the manoeuvres' options, by kind
        known = {f.name for cls in kinds.values() for f in dataclasses.fields(cls)}
        items = [(k, v) for k, v in manoeuvre.items() if not (k in kinds and isinstance(v, dict))]
        for kind in (k for k, v in manoeuvre.items() if k in kinds and isinstance(v, dict)):
            own = {f.name for f in dataclasses.fields(kinds[kind])}   # [manoeuvre.KIND]: that kind's options
            for key, value in manoeuvre[kind].items():
                if key not in own:
                    raise ScenarioError(f"{path}: unknown key manoeuvre.{kind}.{key!r}; the {kind} options are "
                                        f"{', '.join(sorted(own))}")
                items.append((f"{kind}.{key}", value))
        for key, value in items:
            if "." not in key and key not in known:
                raise ScenarioError(f"{path}: unknown key manoeuvre.{key!r}; the manoeuvres' options are "
                                    f"{', '.join(sorted(known))}")
            if not isinstance(value, str):
                _number(path, f"manoeuvre.{key}", value)
    return {"options": options, "description": str(data.get("description", "")),
            "source": str(data.get("source", "")), "notes": tuple(notes), "actuators": actuators,
            "manoeuvre": manoeuvre}


def _options_class(kind: str, defaults: dict):
    """The options dataclass of one file: a field per number, the file's numbers as defaults."""
    name = "VesselOptions_" + "".join(c if c.isalnum() else "_" for c in kind)
    fields = [(k, type(v), dataclasses.field(default=v, metadata={"unit": UNITS.get(k, "")}))
              for k, v in defaults.items()]
    cls = dataclasses.make_dataclass(name, fields, bases=(_DataOptions,), frozen=True, namespace={
        "__doc__": f"Options of the vessel {kind!r} (docs/vessels.md): its data file's numbers, SI units."})
    cls.__module__ = __name__
    globals()[name] = cls  # importable by name (a pickled scenario finds it)
    return cls


class DataVessel:
    """The factory of a data-file vessel kind: ``from_scenario(options, scenario)`` -> :class:`Vessel`."""

    def __init__(self, kind: str, contents: dict):
        self.kind = kind
        self.contents = contents
        self.options = _options_class(kind, contents["options"])
        self.options._datafile = (kind, contents)
        self.__doc__ = contents["description"] or f"vessel data file {kind}"
        self.__qualname__ = f"DataVessel({os.path.basename(kind)})"

    def __call__(self, options, scenario=None) -> Vessel:
        o = options if options is not None else self.options()
        der = {k: getattr(o, k) for k in DERIVATIVES}
        k_cf = 0.5 * o.rho * o.T * o.crossflow_cd
        ship, split = from_derivatives(**der, coriolis=o.coriolis, crossflow_k=k_cf, crossflow_L=o.L,
                                       strips=o.strips, uncertainty_scale=o.uncertainty_scale, where="vessel")
        return Vessel(self.kind, ship, split, Dimensions(o.L, o.B, o.T), self.contents["actuators"],
                      self.contents["source"], self.contents["notes"], manoeuvre=self.contents.get("manoeuvre"))


def register_file(path, kind: str | None = None, replace: bool = False) -> str:
    """Register the data file ``path`` as a vessel kind (``kind``: default the path as given);
    returns the kind. A kind already registered from the same file is kept. The registry calls it
    for a kind that ends in ``.toml`` (:data:`usv_mj.core.registry.VESSELS`: the scenario's
    ``[vessel] kind``, resolved to an absolute path)."""
    kind = kind or str(path)
    entry = VESSELS._entries.get(kind)
    if entry is not None and not replace and isinstance(entry.obj, DataVessel):
        return kind  # read once per process (edit a file, then start again or pass replace=True)
    if not os.path.isfile(path):
        raise ScenarioError(f"vessel.kind: no vessel data file {str(path)!r}")
    _register(kind, read_file(path))
    return kind


def _register(kind: str, contents: dict) -> DataVessel:
    factory = DataVessel(kind, contents)
    VESSELS._decorator(kind, factory.options, {"doc": factory.__doc__}, _source(kind), True)(factory)
    return factory


def _data_options(kind: str, contents: dict, values: dict):
    """An unpickled data-file options instance (:meth:`_DataOptions.__reduce__`): the kind registered
    in this process from the contents that came with it (the same contents already registered: kept),
    so that a worker needs neither the file nor the process that read it."""
    entry = VESSELS._entries.get(kind)
    factory = entry.obj if entry is not None else None
    if not isinstance(factory, DataVessel) or factory.contents != contents:
        factory = _register(kind, contents)
    return factory.options(**values)


def _source(kind: str) -> str:
    from usv_mj.core.registry import BUILT_IN

    return BUILT_IN if VESSELS._builtins.get(kind) == __name__ else f"data file {kind}"


def builtin_files() -> dict[str, str]:
    """kind -> path of each built-in data file."""
    folder = resources.files("usv_mj.vessels.data")
    return {p.name[:-5]: str(p) for p in folder.iterdir() if p.name.endswith(".toml")}


for _kind, _path in sorted(builtin_files().items()):
    register_file(_path, _kind, replace=True)
