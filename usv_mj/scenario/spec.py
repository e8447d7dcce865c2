"""Scenarios: a preset plus overrides, as typed and validated parameters (docs/model.md §5 and §7).

A scenario file is TOML::

    preset = "paper"               # the base; every other key overrides it
    duration = 300.0               # s
    [initial]
    eta = [2.0, -3.0, 0.0]
    [controller]
    k1 = 5.0

Presets are TOML files shipped in ``usv_mj/scenario/presets/`` (``paper``, ``paper-printed``, ``harsh``); a
preset may itself name a base preset. Every value is checked at construction and a bad one raises
:class:`ScenarioError` with a message that names its key; unknown keys are errors too.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import functools
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from usv_mj.physics.actuators import ActuatorSpec
from usv_mj.core.errors import (PluginContractError, ScenarioError, SeaSettingsError, TooManyStepsError,
                                UnknownKindError)
from usv_mj.scenario.fleet import vessels_from_tables
from usv_mj.scenario.manoeuvre import manoeuvre_from_table
from usv_mj.scenario.obstacles import GuidanceSpec, from_tables, guidance_from_table
from usv_mj.core.registry import CONTROLLERS, DISTURBANCES, PLANTS, TRAJECTORIES, VESSELS
from usv_mj.physics.sea.settings import SeaSettings, merge_sea_tables, sea_preset_table
from usv_mj.physics.design import DesignPoint, Scaling
from usv_mj.physics.disturbances import check_disturbance
from usv_mj.physics.ship import PaperDisturbance, ShipParams
from usv_mj.support.toml_values import read_toml
from usv_mj.scenario.tables import (KindOptions, build_table, construct, convert, merge_tables, to_plain,  # noqa: F401
                                    unknown_key)  # (merge_tables, build_table: the loader's API, used by the jobs)

__all__ = ["Scenario", "ScenarioError", "load_scenario", "from_dict", "preset_names"]


@dataclass(frozen=True)
class InitialState:
    """Initial pose eta = (x [m], y [m], psi [rad]) and body velocity nu = (u [m/s], v [m/s], r [rad/s])."""

    eta: tuple[float, float, float] = (2.0, -3.0, 0.0)
    nu: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class TrajectorySpec(KindOptions):
    """The reference path (see :mod:`usv_mj.references.trajectories`).

    Attributes
    ----------
    kind: a registered trajectory (:data:`usv_mj.core.registry.TRAJECTORIES`): "paper" | "line" | "circle" |
        "waypoints", or a plug-in's.
    options: the kind's own options dataclass (every other key of ``[trajectory]``; the built-ins':
        :class:`usv_mj.references.trajectories.PaperOptions`, ``LineOptions``, ``CircleOptions``,
        ``WaypointsOptions``); None: the kind's defaults.
    """

    kind: str = "paper"
    options: Any = None

    def __post_init__(self) -> None:
        if self.options is None:
            cls = TRAJECTORIES.get(self.kind, "kind").options_class
            object.__setattr__(self, "options", cls() if cls is not None else None)


@dataclass(frozen=True)
class QuantizerSpec:
    """The hysteresis quantizers of both input channels (Eq. 3, docs/model.md §2).

    Attributes
    ----------
    enabled: quantize the inputs (False: Q(tau) = tau).
    delta_u, u_min_u: surge channel delta in (0, 1) and smallest level [N] (paper: 0.3, 0.003).
    delta_r, u_min_r: yaw channel delta in (0, 1) and smallest level [N m] (paper: 0.15, 0.002).
    """

    enabled: bool = True
    delta_u: float = 0.3
    u_min_u: float = 0.003
    delta_r: float = 0.15
    u_min_r: float = 0.002

    def __post_init__(self) -> None:
        for name in ("delta_u", "delta_r"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value < 1.0):
                raise ValueError(f"{name} must be in (0, 1), got {value!r}")
        for name in ("u_min_u", "u_min_r"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be > 0, got {value!r}")


@dataclass(frozen=True)
class FunnelSpec:
    """Prescribed-performance bounds (Eq. 9).

    Attributes
    ----------
    rho_xy: (rho_0, rho_inf) of rho_1 = rho_2 [m] (paper: 18, 2).
    rho_psi: (rho_0, rho_inf) of rho_3 [rad] (paper: 3, pi/6).
    rate: kappa [1/s] (paper: 0.05).
    """

    rho_xy: tuple[float, float] = (18.0, 2.0)
    rho_psi: tuple[float, float] = (3.0, math.pi / 6)
    rate: float = 0.05

    def __post_init__(self) -> None:
        for name in ("rho_xy", "rho_psi"):
            r0, rinf = getattr(self, name)
            if not (math.isfinite(rinf) and rinf > 0):
                raise ValueError(f"{name}: rho_inf must be > 0, got {rinf!r}")
            if not (math.isfinite(r0) and r0 > rinf):
                raise ValueError(f"{name}: rho_inf must be < rho_0, got rho_0 = {r0!r}, rho_inf = {rinf!r}")
        if not (math.isfinite(self.rate) and self.rate > 0):
            raise ValueError(f"rate must be > 0 1/s, got {self.rate!r}")


@dataclass(frozen=True)
class PlantSpec(KindOptions):
    """Which plant integrates the ship.

    Attributes
    ----------
    kind: a registered plant (:data:`usv_mj.core.registry.PLANTS`): "mujoco", "analytic", or a plug-in's.
    substeps: integrator steps per control period (>= 1; every plant's).
    options: the kind's own options dataclass (the other keys of ``[plant]``; None for the built-ins).
    """

    kind: str = "mujoco"
    substeps: int = 1
    options: Any = None

    def __post_init__(self) -> None:
        if self.kind not in PLANTS:
            raise ValueError(f"kind must be one of {', '.join(PLANTS.kinds())}, got {self.kind!r}")
        if self.substeps < 1:
            raise ValueError(f"substeps must be >= 1, got {self.substeps!r}")


@dataclass(frozen=True)
class VesselSpec(KindOptions):
    """The hull (docs/vessels.md): ``[vessel] kind`` names a registered vessel
    (:data:`usv_mj.core.registry.VESSELS`: "paper", "cybership2", "otter", "clarke83", a data file's path
    or a plug-in's) whose options dataclass validates the other keys; ``[ship]`` is the paper
    vessel's options under their old name.

    Attributes
    ----------
    kind: the vessel kind.
    model_mismatch: the controllers' nominal model is the vessel's with every mass and damping
        coefficient times this factor (> 0; 1: the true model).
    options: the kind's options dataclass (paper: :class:`usv_mj.physics.ship.ShipParams`).
    model: the resolved :class:`usv_mj.vessels.Vessel` (made from kind and options when not given).
    """

    kind: str = "paper"
    model_mismatch: float = 1.0
    options: Any = None
    model: Any = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.model_mismatch) and self.model_mismatch > 0):
            raise ValueError(f"model_mismatch must be a number > 0, got {self.model_mismatch!r}")
        if self.model is None:
            entry = VESSELS.get(self.kind, "vessel.kind")
            if self.options is None and entry.options_class is not None:
                object.__setattr__(self, "options", entry.options_class())
            object.__setattr__(self, "model", entry.make(self.options, None))


def _default_gains(kind: str):
    return CONTROLLERS.get(kind).gains()


@dataclass(frozen=True)
class ControllerSpec:
    """Which controller drives the ship; its gains sit beside ``kind`` in ``[controller]``.

    Attributes
    ----------
    kind: a registered controller (:data:`usv_mj.core.registry.CONTROLLERS`): "ppc" (the paper's law),
        "pi" (the baseline), or one registered by the user.
    gains: the chosen controller's own gains dataclass (PPC: :class:`usv_mj.controllers.ppc.PPCGains`),
        the gains the run uses: those the table gives, the others derived from the vessel when the
        gains class can (its ``for_vessel``: PI and LOS, docs/gains.md), else its defaults.
    derived: the names of the gains derived from the vessel (not given by the scenario).
    """

    kind: str = "ppc"
    gains: Any = field(default_factory=lambda: _default_gains("ppc"))
    derived: tuple = ()


@dataclass(frozen=True)
class BaselineSpec:
    """The comparison controller (the PI baseline of docs/model.md) run beside the main one for the figures.

    Attributes
    ----------
    enabled: also run the baseline on the same plant and scenario.
    kind: a registered controller ("pi" by default).
    gains: that controller's gains dataclass (flat keys in the TOML section; derived from the vessel
        where not given, as :class:`ControllerSpec`'s).
    derived: the names of the gains derived from the vessel.
    """

    enabled: bool = True
    kind: str = "pi"
    gains: Any = field(default_factory=lambda: _default_gains("pi"))
    derived: tuple = ()


@dataclass(frozen=True)
class LimitsSpec:
    """When a run counts as diverged and stops (a recorded event, never a NaN).

    Attributes
    ----------
    max_speed: |u|, |v| above this [m/s] is divergence.
    max_yaw_rate: |r| above this [rad/s] is divergence.
    max_distance: distance from the reference point above this [m] is divergence.
    max_force: |tau_u| or |tau_r| above this [N, N m] is divergence of the controller.
    """

    max_speed: float = 50.0
    max_yaw_rate: float = 50.0
    max_distance: float = 1000.0
    max_force: float = 1e9

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{f.name} must be > 0, got {value!r}")


@dataclass(frozen=True)
class Scenario:
    """A complete, validated run description. Build it with :func:`load_scenario` or :func:`from_dict`."""

    preset: str = "paper"
    duration: float = 300.0
    control_period: float = 0.001
    initial: InitialState = field(default_factory=InitialState)
    trajectory: TrajectorySpec = field(default_factory=TrajectorySpec)
    disturbance: PaperDisturbance = field(default_factory=PaperDisturbance)
    ship: ShipParams = field(default_factory=ShipParams)  # the vessel's packed hull (vessel.model.ship)
    vessel: VesselSpec = field(default_factory=VesselSpec)
    quantizer: QuantizerSpec = field(default_factory=QuantizerSpec)
    funnel: FunnelSpec = field(default_factory=FunnelSpec)
    plant: PlantSpec = field(default_factory=PlantSpec)
    controller: ControllerSpec = field(default_factory=ControllerSpec)
    baseline: BaselineSpec = field(default_factory=BaselineSpec)
    limits: LimitsSpec = field(default_factory=LimitsSpec)
    actuators: ActuatorSpec = field(default_factory=ActuatorSpec)
    sea: SeaSettings = field(default_factory=SeaSettings)
    obstacles: tuple = ()  # ObstacleSpec per [[obstacles]] table (usv_mj.scenario.obstacles)
    guidance: GuidanceSpec = field(default_factory=GuidanceSpec)  # [guidance]
    manoeuvre: Any = None  # [manoeuvre]: a ManoeuvreSpec (usv_mj.scenario.manoeuvre), None: no manoeuvre
    vessels: tuple = ()  # [[vessels]]: a VesselEntry per vessel (usv_mj.scenario.fleet); (): one vessel, this one
    source: str = field(default="", compare=False)
    raw: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be > 0 s, got {self.duration!r}")
        if not (math.isfinite(self.control_period) and 0 < self.control_period <= 1.0):
            raise ValueError(f"control_period must be in (0, 1] s, got {self.control_period!r}")
        if self.duration / self.control_period > 5e7:
            raise TooManyStepsError("duration / control_period is over 5e7 steps: too long a run")

    @property
    def nominal_ship(self) -> ShipParams:
        """The controllers' nominal model: the vessel's hull times ``[vessel] model_mismatch``."""
        return self.ship.scaled(self.vessel.model_mismatch)

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.control_period))

    def with_overrides(self, overrides: dict) -> "Scenario":
        """A new scenario: this one's TOML table with ``overrides`` merged in and validated again."""
        return from_dict(merge_overrides(self.raw, overrides, self.source), source=self.source or "<overrides>")

    def without(self, *sections: str) -> "Scenario":
        """A new scenario without these top-level tables (e.g. ``"obstacles"``: the same run in open
        water), validated again."""
        return from_dict({k: v for k, v in self.raw.items() if k not in sections}, source=self.source or "<dict>")

    def to_dict(self) -> dict:
        """Every parameter as plain data (for metadata and summaries)."""
        return to_plain(self)


# --- loading ------------------------------------------------------------------------------------


def preset_names() -> list[str]:
    return sorted(p.name[:-5] for p in resources.files("usv_mj.scenario.presets").iterdir() if p.name.endswith(".toml"))


def _read_preset(name: str) -> dict:
    """The merged TOML table of a preset (a fresh copy: callers may change it)."""
    return copy.deepcopy(_parsed_preset(name, ()))


@functools.lru_cache(maxsize=64)
def _parsed_preset(name: str, chain: tuple) -> dict:
    # cached: a sweep validates thousands of scenarios of the same preset (parsing was 60 % of it)
    if name in chain:
        raise ScenarioError(f"preset {name!r} names itself as a base (cycle {' -> '.join(chain + (name,))})")
    path = resources.files("usv_mj.scenario.presets") / f"{name}.toml"
    if name not in preset_names():  # a name, never a path ("../x" would read any TOML file)
        hint = difflib.get_close_matches(name, preset_names(), n=1)
        raise ScenarioError(
            f"unknown preset {name!r}; presets are {', '.join(preset_names())}"
            + (f" (did you mean {hint[0]!r}?)" if hint else ""))
    data = tomllib.loads(path.read_text())
    base = data.pop("preset", None)
    if base is not None:
        data = merge_tables(_parsed_preset(base, chain + (name,)), data)
    return data




def load_scenario(path: str | Path | None = None, preset: str | None = None, overrides: dict | None = None) -> Scenario:
    """Load a scenario file (or only a preset) and apply ``overrides`` (a nested dict).

    Raises :class:`ScenarioError` with the file, the key and the bad value on any problem, and
    :class:`usv_mj.core.errors.ArgumentTypeError` for an argument of the wrong type.
    """
    from usv_mj.core.errors import expected

    if path is not None and not isinstance(path, (str, Path)):
        raise expected("load_scenario", "path", "a scenario file's path (str or pathlib.Path)", path)
    if preset is not None and not isinstance(preset, str):
        raise expected("load_scenario", "preset", f"a preset name ({', '.join(preset_names())})", preset)
    if overrides is not None and not isinstance(overrides, Mapping):
        raise expected("load_scenario", "overrides", "a nested dict of scenario keys, e.g. {'duration': 5.0}",
                       overrides)
    if overrides is not None:
        from usv_mj.core.arguments import string_keys

        string_keys("load_scenario", "overrides", overrides)
    data: dict = {}
    source = f"preset {preset or 'paper'}"
    if path is not None:
        from usv_mj.support.example_files import resolve

        path = resolve(path, "scenarios")     # an example's name (harbour_gap) finds its file
        source = str(path)
        data = read_toml(path, ScenarioError, "scenario file")
    if preset is not None:
        data["preset"] = preset
    if overrides:
        data = merge_overrides(data, overrides, source)
    return from_dict(data, source=source)


#: the sections whose ``kind`` selects the other keys' meaning, and each one's default kind
KIND_DEFAULTS = {"controller": "ppc", "baseline": "pi", "trajectory": "paper", "plant": "mujoco",
                 "disturbance": "paper"}


def switched_kind(section: str, table: dict, kind, source: str = "<dict>") -> dict:
    """``[section]`` (a table of :data:`KIND_DEFAULTS`) when its kind becomes ``kind``: unchanged if it
    is the table's own kind; else a controller's (baseline's) gains are dropped, they belong to the
    old kind (the baseline keeps ``enabled``), and a trajectory, plant or disturbance keeps only the
    keys the new kind also has (the plant's ``substeps`` always). The one rule of a kind switch, for a preset under
    a scenario (:func:`from_dict`) and for a sweep's or a suite's ``[set] "controller.kind"``
    (:func:`usv_mj.jobs.sweep.spec.apply_values`). ``kind`` itself is not written into the result."""
    if kind == table.get("kind", KIND_DEFAULTS[section]):
        return table
    if section in ("controller", "baseline"):
        return {k: v for k, v in table.items() if k == "enabled"}
    keep = ("substeps",) if section == "plant" else ()
    registry = {"trajectory": TRAJECTORIES, "plant": PLANTS, "disturbance": DISTURBANCES}[section]
    known = set(keep)
    if isinstance(kind, str) and (set(table) - {"kind", *keep}):
        cls = registry.get(kind, f"{source}: {section}.kind").options_class
        known |= {f.name for f in dataclasses.fields(cls)} if cls is not None else set()
    return {k: v for k, v in table.items() if k in known}


def merge_overrides(data: dict, overrides: dict, source: str = "<dict>") -> dict:
    """``data`` (a scenario table) with ``overrides`` merged in, a section whose ``kind`` the overrides
    switch first cut to the new kind's keys (:func:`switched_kind`), so ``{"controller": {"kind":
    "los"}}`` over a file's PPC gains is LOS with its own, as over a preset."""
    base = dict(data)
    for section in KIND_DEFAULTS:
        over = overrides.get(section)
        if isinstance(over, dict) and "kind" in over and isinstance(base.get(section), dict):
            base[section] = switched_kind(section, base[section], over["kind"], source)
    return merge_tables(base, overrides)


def from_dict(data: dict, source: str = "<dict>") -> Scenario:
    """Build a validated :class:`Scenario` from a TOML-like nested dict (``preset`` key = the base)."""
    name = data.get("preset", "paper")
    if not isinstance(name, str):
        raise ScenarioError(f"{source}: preset must be a string, got {name!r}")
    try:
        base = _read_preset(name)
    except ScenarioError as exc:
        msg = str(exc)
        raise ScenarioError(msg if msg.startswith(source) else f"{source}: preset: {msg}") from None
    for section in KIND_DEFAULTS:
        # another kind than the preset's: the preset's keys of its own kind stay behind
        over = data.get(section)
        if isinstance(over, dict) and isinstance(base.get(section), dict) and "kind" in over:
            base[section] = switched_kind(section, base[section], over["kind"], source)
    merged = merge_tables(base, {k: v for k, v in data.items() if k != "preset"})
    merged["preset"] = name
    return _build_scenario(merged, source, own_actuators="actuators" in data,
                           own_table=data.get("actuators") if isinstance(data.get("actuators"), dict) else None)


_SECTIONS = {
    "initial": InitialState,
    "quantizer": QuantizerSpec, "funnel": FunnelSpec,
    "limits": LimitsSpec, "actuators": ActuatorSpec,
}


def _build_scenario(data: dict, source: str, own_actuators: bool = True, own_table: dict | None = None) -> Scenario:
    top = {}
    known = {f.name for f in dataclasses.fields(Scenario)} - {"source", "raw"}
    for key in data:
        if key not in known:
            unknown_key(source, "", key, known)
    if "vessel" in data or "ship" in data:
        top["vessel"] = _build_vessel(data.get("vessel", {}), data.get("ship"), source)
        top["ship"] = top["vessel"].model.ship
        own = top["vessel"].model.actuators
        if own is not None and not own_actuators:
            data["actuators"] = dict(own)  # the vessel's, unless the scenario's own
        elif own is not None and top["vessel"].model.actuators_merged and own_table is not None:
            # a steering gear that is the ship's own (a ruddered vessel's, with its n_P cap): the
            # scenario's keys change it one by one (--set actuators.yaw_rate_nm_s=...), never take it away
            data["actuators"] = {**own, **own_table}
        channels = top["vessel"].model.channels
        for key, channel in (("max_surge_n", channels.surge), ("max_yaw_nm", channels.yaw)):
            limit = data.get("actuators", {}).get(key) if isinstance(data.get("actuators"), dict) else None
            if isinstance(limit, (int, float)) and not limit < channel.largest_limit:
                raise ScenarioError(f"{source}: actuators.{key} = {limit!r} is the limit of the vessel "
                                    f"{top['vessel'].kind!r}'s {channel.quantity} [{channel.unit}] and must be < "
                                    f"{channel.largest_limit:.6g} {channel.unit}")
    for key in ("duration", "control_period"):
        if key in data:
            top[key] = convert(source, key, data[key], 0.0)
    top["preset"] = data["preset"]
    for key, cls in _SECTIONS.items():
        if key in data:
            top[key] = build_table(cls, data[key], source, key)
    if "trajectory" in data:
        top["trajectory"] = _kind_spec(TrajectorySpec, TRAJECTORIES, data["trajectory"], source, "trajectory",
                                       "paper", ())
    if "plant" in data:
        top["plant"] = _kind_spec(PlantSpec, PLANTS, data["plant"], source, "plant", "mujoco", ("substeps",))
    for key in ("controller", "baseline", "sea", "guidance"):
        if key in data and not isinstance(data[key], dict):
            raise ScenarioError(f"{source}: [{key}] must be a table, got {data[key]!r}")
    if "disturbance" in data:
        top["disturbance"] = _build_disturbance(data["disturbance"], source)
    design = _design_scaling(top.get("vessel"))
    top["controller"] = _controller_spec(data.get("controller", {}), source, "controller", "ppc", design)
    base = data.get("baseline", {})
    if not isinstance(base, dict):
        raise ScenarioError(f"{source}: [baseline] must be a table, got {base!r}")
    base = dict(base)
    enabled = base.pop("enabled", True)
    if not isinstance(enabled, bool):
        raise ScenarioError(f"{source}: baseline.enabled must be true or false, got {enabled!r}")
    spec = _controller_spec(base, source, "baseline", "pi", design)
    top["baseline"] = BaselineSpec(enabled=enabled, kind=spec.kind, gains=spec.gains, derived=spec.derived)
    if "sea" in data:
        top["sea"] = _build_sea(data["sea"], source)
        vessel = getattr(top.get("vessel"), "model", None)
        why = getattr(vessel, "limitations", {}).get("sea")
        if why and not top["sea"].calm:
            raise ScenarioError(f"{source}: [sea]: the vessel {top['vessel'].kind!r} cannot run in a sea: {why}; "
                                f"remove the sea (docs/vessels.md)")
    if "obstacles" in data or "guidance" in data:
        top["obstacles"] = from_tables(data.get("obstacles"), source)
        top["guidance"] = guidance_from_table(data.get("guidance"), source)
    if "manoeuvre" in data:
        vessel = top.get("vessel")
        top["manoeuvre"] = manoeuvre_from_table(data["manoeuvre"], source,
                                                vessel.model if vessel is not None else None)
    if "vessels" in data:
        top["vessels"] = vessels_from_tables(data["vessels"], {k: v for k, v in data.items() if k != "vessels"},
                                             source, from_dict)
    scenario = construct(Scenario, top, source, "")
    return dataclasses.replace(scenario, source=source, raw=data)


def _build_vessel(table: Any, ship: Any, source: str) -> VesselSpec:
    """``[vessel]`` (and ``[ship]``, the paper vessel's options): the kind, ``model_mismatch`` and the
    kind's options; a kind ending in ".toml" is a vessel data file (relative to the scenario's
    folder, else to the working directory), registered on first use (usv_mj.vessels.datafile)."""
    import os

    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [vessel] must be a table, got {table!r}")
    if ship is not None and not isinstance(ship, dict):
        raise ScenarioError(f"{source}: [ship] must be a table, got {ship!r}")
    table = dict(table)
    kind = table.pop("kind", "paper")
    if not isinstance(kind, str):
        raise ScenarioError(f"{source}: vessel.kind must be a string, got {kind!r}")
    kwargs = {}
    if "model_mismatch" in table:
        kwargs["model_mismatch"] = convert(source, "vessel.model_mismatch", table.pop("model_mismatch"), 1.0)
    if kind.endswith(".toml"):   # a data file: relative to the scenario's folder, else to the working one
        here = os.path.join(os.path.dirname(source), kind) if os.path.isfile(source) else kind
        kind = os.path.abspath(here if os.path.isfile(here) else kind)
        try:
            VESSELS.get(kind)    # registered under its absolute path (usv_mj.vessels.datafile)
        except ScenarioError as exc:
            raise ScenarioError(f"{source}: vessel.kind: {exc}") from None
    if ship:
        if kind != "paper":
            raise ScenarioError(f"{source}: [ship] holds the paper vessel's parameters; with vessel.kind = "
                                f"{kind!r} give the vessel's own keys in [vessel] and remove [ship]")
        table = {**ship, **table}
    entry = VESSELS.get(kind, f"{source}: vessel.kind")
    cls = entry.options_class
    if cls is None:
        if table:
            raise ScenarioError(f"{source}: vessel kind {kind!r} takes no options, got {', '.join(sorted(table))}")
        options = None
    else:
        section = "ship" if kind == "paper" and ship else "vessel"
        options = build_table(cls, table, source, section)
    try:
        model = entry.make(options, None)
    except ValueError as exc:
        raise ScenarioError(f"{source}: vessel {kind!r}: {exc}") from None
    return construct(VesselSpec, {"kind": kind, "options": options, "model": model, **kwargs}, source, "vessel")


def _design_scaling(vessel: VesselSpec | None):
    """A function returning the :class:`usv_mj.physics.design.Scaling` of the scenario's hull (its
    nominal model: the vessel's times ``model_mismatch``, its length), made when first asked."""
    made = []

    def scaling():
        if not made:
            spec = vessel if vessel is not None else VesselSpec()
            nominal = spec.model.ship.scaled(spec.model_mismatch)
            made.append(Scaling(DesignPoint.of(nominal, spec.model.dimensions.L)))
        return made[0]

    return scaling


def _controller_spec(table: Any, source: str, section: str, default_kind: str, design=None) -> ControllerSpec:
    """``[controller]`` / ``[baseline]``: ``kind`` names a registered controller, whose own gains
    dataclass validates every other key of the table (the error lists that controller's keys). A
    gains class with ``for_vessel(scaling)`` (docs/gains.md) has its defaults derived from the hull
    (``design()``: the scenario's :class:`usv_mj.physics.design.Scaling`) for every gain the table
    does not give."""
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [{section}] must be a table, got {table!r}")
    table = dict(table)
    kind = table.pop("kind", default_kind)
    if not isinstance(kind, str):
        raise ScenarioError(f"{source}: {section}.kind must be a string, got {kind!r}")
    entry = CONTROLLERS.get(kind, f"{source}: {section}.kind")
    gains_cls = entry.info.get("gains")
    if gains_cls is None:
        if table:
            raise ScenarioError(f"{source}: controller {kind!r} takes no gains, got {', '.join(sorted(table))}")
        return ControllerSpec(kind=kind, gains=None)
    extra = {"kind", "enabled"} if section == "baseline" else {"kind"}
    for_vessel = getattr(gains_cls, "for_vessel", None)
    derived = ()
    if for_vessel is not None and design is not None:
        given = set(table)
        try:
            defaults = {k: v for k, v in for_vessel(design()).items() if k not in given}
        except ValueError as exc:
            raise ScenarioError(f"{source}: {section}: the gains of {kind!r} for this vessel: {exc}") from None
        derived = tuple(defaults)
        table = {**defaults, **table}
    gains = build_table(gains_cls, table, source, section, extra_known=extra)
    return ControllerSpec(kind=kind, gains=gains, derived=derived)


def _kind_spec(spec_cls, registry, table: Any, source: str, section: str, default_kind: str, common: tuple):
    """``[trajectory]`` / ``[plant]``: ``kind`` names a registered kind whose own options dataclass
    validates every key of the table but ``kind`` and the section's ``common`` keys (the plant's
    ``substeps``). A built-in kind that takes no options is not imported to say so (a plant's
    module imports MuJoCo) unless the table holds other keys."""
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [{section}] must be a table, got {table!r}")
    table = dict(table)
    kind = table.pop("kind", default_kind)
    if not isinstance(kind, str):
        raise ScenarioError(f"{source}: {section}.kind must be a string, got {kind!r}")
    own = {k: v for k, v in table.items() if k not in common}
    defaults = spec_cls.__dataclass_fields__
    kwargs = {k: convert(source, f"{section}.{k}", table[k], defaults[k].default) for k in common if k in table}
    if own or kind not in registry.builtin_kinds() or spec_cls is TrajectorySpec:
        options_cls = registry.get(kind, f"{source}: {section}.kind").options_class
        if options_cls is None:
            if own:
                raise ScenarioError(f"{source}: {section} kind {kind!r} takes no options"
                                    + (f" besides {', '.join(common)}" if common else "")
                                    + f", got {', '.join(sorted(own))}")
        else:
            kwargs["options"] = build_table(options_cls, own, source, section, extra_known={"kind", *common})
    return construct(spec_cls, {"kind": kind, **kwargs}, source, section)


def _build_disturbance(table: Any, source: str):
    """``[disturbance]``: ``kind`` (default "paper") names a registered disturbance, whose
    parameter dataclass validates the other keys; the result keeps the kind's contract
    (:func:`usv_mj.physics.disturbances.check_disturbance`: a njit kernel, a short ``as_array()``).
    A plug-in kind's errors name the kind."""
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [disturbance] must be a table, got {table!r}")
    table = dict(table)
    kind = table.pop("kind", "paper")
    entry = DISTURBANCES.get(kind, f"{source}: disturbance.kind")
    cls = entry.options_class or entry.obj
    if not dataclasses.is_dataclass(cls):
        raise PluginContractError(f"{source}: disturbance kind {kind!r}: {_name(cls)} must be a dataclass (its "
                                  f"fields are the [disturbance] table's keys; usv_mj.physics.disturbances)")
    try:
        disturbance = build_table(cls, table, source, "disturbance", extra_known={"kind"})
    except ScenarioError as exc:
        if kind == "paper" or isinstance(exc, UnknownKindError):
            raise
        msg = str(exc)  # "source: disturbance.key ...": the kind goes after the source
        rest = msg[len(source) + 2:] if msg.startswith(f"{source}: ") else msg
        raise type(exc)(f"{source}: disturbance kind {kind!r}: {rest}") from None
    except (TypeError, AttributeError) as exc:  # a dataclass that cannot be made from its own defaults
        raise PluginContractError(f"{source}: disturbance kind {kind!r}: {_name(cls)} cannot be made "
                                  f"({type(exc).__name__}: {exc})") from None
    try:
        check_disturbance(disturbance, kind)
    except PluginContractError as exc:
        raise PluginContractError(f"{source}: {exc}") from None
    return disturbance


def _name(obj) -> str:
    return f"{getattr(obj, '__module__', '?')}.{getattr(obj, '__qualname__', repr(obj))}"


def _build_sea(table, source: str) -> SeaSettings:
    """``[sea]`` (docs/sea.md); ``preset = "moderate"`` names a sea preset whose tables sit under the
    scenario's own ``[sea.*]`` keys (a direction of the scenario replaces the preset's, any spelling)."""
    try:
        if isinstance(table, dict) and "preset" in table:
            table = dict(table)
            name = table.pop("preset")
            if not isinstance(name, str):
                raise ScenarioError(f"{source}: sea.preset must be a string, got {name!r}")
            table = merge_sea_tables(sea_preset_table(name), table)
        return SeaSettings.from_table(table, source)
    except SeaSettingsError as exc:
        msg = str(exc)
        raise ScenarioError(msg if msg.startswith(source) else f"{source}: {msg}") from None


def vessel_of_table(table):
    """The :class:`usv_mj.vessels.Vessel` of a scenario's ``to_dict()`` (a run's metadata
    ``scenario``): its ``[vessel]`` resolved (with ``[ship]``, the paper kind's options, for the paper
    kind only: to_dict writes the packed hull under ``ship`` beside every vessel); None when the
    table names no vessel."""
    if not isinstance(table, dict) or not isinstance(table.get("vessel"), dict):
        return None
    kinds = ("vessel", "ship") if table["vessel"].get("kind", "paper") == "paper" else ("vessel",)
    return from_dict({k: table[k] for k in kinds if k in table}, source="<metadata>").vessel.model
