"""The ``[manoeuvre]`` table: the options of the standard manoeuvres, typed and validated.

Each kind's options dataclass is registered in :data:`usv_mj.core.registry.MANOEUVRES` (the kind's
object is the dataclass, as a disturbance's); the run each manoeuvre is (its controller, the
approach force) is the job's: :mod:`usv_mj.jobs.manoeuvres.trial`.

A manoeuvre is an ordinary run of the scenario with its controller replaced by an open-loop or a
heading-switching input (``controllers/open_loop.py``, ``controllers/zigzag.py``), started on a
straight course at the approach speed. The vessel's "rudder" is its commanded yaw moment tau_r [N m]
(the paper's hull has no rudder; a vessel with twin propellers realizes it as differential thrust
through its ``[actuators]``); positive tau_r turns to port (README, Conventions).

::

    [manoeuvre]
    kind = "turning"           # "turning" | "zigzag" | "spiral" | "stopping"
    approach_speed = 0.6       # m/s, the straight run before the execute
    yaw_moment = 10.0          # N m, the "rudder"
    side = "starboard"

The approach is held by the constant surge force that balances the hull's drag at the approach
speed (:func:`usv_mj.jobs.manoeuvres.trial.approach_force`, found on the scenario's analytic plant: any
vessel it integrates).

``conditions = "calm"`` (the default) runs the test as trials are run: calm water, no d(t), no
Delta (its side force 0.2 u^2 would turn the hull by itself), no quantizer (so that the commanded
forces are the applied ones); ``"scenario"`` keeps the scenario's sea, disturbance, Delta and
quantizer.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields

from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import MANOEUVRES
from usv_mj.physics.channels import FORCES

SIDES = {"starboard": -1.0, "port": 1.0}
CONDITIONS = ("calm", "scenario")


def _check_duration(obj, section="manoeuvre"):
    """The run must pass its approach (the execute at ``approach_s``) and take at least one control
    step: refused here, before the run, not after it when there is nothing to measure."""
    duration, period = obj.duration, obj.control_period
    approach = getattr(obj, "approach_s", 0.0)
    if hasattr(obj, "approach_s") and not duration > approach:
        raise ScenarioError(f"{section}.duration = {duration!r} s does not pass the approach: the execute is at "
                            f"{section}.approach_s = {approach!r} s; give a duration longer than approach_s")
    if not duration >= period:
        raise ScenarioError(f"{section}.duration = {duration!r} s is shorter than one control period "
                            f"({section}.control_period = {period!r} s)")


def _check(obj, positive=(), nonnegative=(), section="manoeuvre"):
    for f in fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, str):
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ScenarioError(f"{section}.{f.name} must be a finite number, got {v!r}")
    for name in positive:
        if not getattr(obj, name) > 0:
            raise ScenarioError(f"{section}.{name} must be > 0, got {getattr(obj, name)!r}")
    for name in nonnegative:
        if not getattr(obj, name) >= 0:
            raise ScenarioError(f"{section}.{name} must be >= 0, got {getattr(obj, name)!r}")
    for name, allowed in (("side", SIDES), ("first_turn", SIDES), ("conditions", CONDITIONS)):
        if hasattr(obj, name) and getattr(obj, name) not in allowed:
            raise ScenarioError(f"{section}.{name} must be one of {', '.join(map(repr, allowed))}, "
                                f"got {getattr(obj, name)!r}")


@dataclass(frozen=True)
class TurningOptions:
    """The turning circle: a straight approach, then the "rudder" held."""

    approach_speed: float = 0.6      # m/s: the speed of the straight approach
    approach_s: float = 5.0          # s: the straight run before the execute
    yaw_moment: float = 10.0         # N m: the "rudder", |tau_r| held from the execute
    side: str = "starboard"          # "starboard" (tau_r < 0) or "port"
    rudder_deg: float = 35.0         # deg: a ruddered vessel's rudder angle (in place of yaw_moment)
    steady_after_deg: float = 360.0  # deg: heading change after which the turn counts as steady
    duration: float = 60.0           # s: the whole run (approach included)
    control_period: float = 0.01     # s
    conditions: str = "calm"         # "calm" or "scenario" (module docstring)

    def __post_init__(self):
        _check(self, positive=("approach_speed", "yaw_moment", "duration", "control_period", "steady_after_deg",
                               "rudder_deg"),
               nonnegative=("approach_s",))
        if self.steady_after_deg < 180:
            raise ScenarioError(f"manoeuvre.steady_after_deg must be >= 180, got {self.steady_after_deg!r}")
        _check_duration(self)


@dataclass(frozen=True)
class ZigzagOptions:
    """The zig-zag (Kempf): the "rudder" reversed at +-``angle_deg`` of heading change (10/10, 20/20)."""

    approach_speed: float = 0.6      # m/s
    yaw_moment: float = 10.0         # N m: the "rudder" amplitude
    angle_deg: float = 10.0          # deg: the switching heading change (10 for 10/10, 20 for 20/20)
    first_turn: str = "starboard"    # "starboard" or "port"
    duration: float = 60.0           # s
    control_period: float = 0.001    # s: the switch acts within one period (10 ms moved the overshoot 0.4 deg)
    conditions: str = "calm"

    def __post_init__(self):
        _check(self, positive=("approach_speed", "yaw_moment", "angle_deg", "duration", "control_period"))
        if not self.angle_deg < 180:
            raise ScenarioError(f"manoeuvre.angle_deg must be < 180, got {self.angle_deg!r}")
        _check_duration(self)


@dataclass(frozen=True)
class SpiralOptions:
    """Dieudonné's spiral: the "rudder" stepped from +max down to -max, then back up, each held."""

    approach_speed: float = 0.6      # m/s: the start (the surge force stays the approach's)
    max_yaw_moment: float = 10.0     # N m: the largest |tau_r| of the steps
    max_rudder_deg: float = 20.0     # deg: a ruddered vessel's largest |rudder angle| (in place of max_yaw_moment)
    steps: int = 5                   # steps from 0 to the maximum (2 steps + 1 commands per branch)
    hold_s: float = 30.0             # s: each command held
    settle_fraction: float = 0.25    # the last part of each hold averaged for the steady yaw rate
    control_period: float = 0.01     # s
    conditions: str = "calm"

    def __post_init__(self):
        _check(self, positive=("approach_speed", "max_yaw_moment", "max_rudder_deg", "hold_s", "control_period",
                               "settle_fraction"))
        if isinstance(self.steps, bool) or not isinstance(self.steps, int) or self.steps < 1:
            raise ScenarioError(f"manoeuvre.steps must be an integer >= 1, got {self.steps!r}")
        if not self.settle_fraction <= 1:
            raise ScenarioError(f"manoeuvre.settle_fraction must be in (0, 1], got {self.settle_fraction!r}")
        if not self.hold_s >= self.control_period:
            raise ScenarioError(f"manoeuvre.hold_s = {self.hold_s!r} s is shorter than one control period "
                                f"(manoeuvre.control_period = {self.control_period!r} s)")

    @property
    def duration(self) -> float:
        return len(self.commands()) * self.hold_s

    def commands(self, amplitude: float | None = None) -> list[tuple[float, str]]:
        """The held commands in order, each with its branch ("down" or "up"): steps of ``amplitude``
        (default ``max_yaw_moment`` [N m]; a ruddered vessel's ``max_rudder_deg``, in its unit)."""
        amplitude = self.max_yaw_moment if amplitude is None else amplitude
        levels = [amplitude * i / self.steps for i in range(self.steps, -self.steps - 1, -1)]
        return [(c, "down") for c in levels] + [(c, "up") for c in levels[::-1][1:]]


@dataclass(frozen=True)
class StoppingOptions:
    """The stopping test: from the approach speed the surge force goes to ``astern_force``."""

    approach_speed: float = 0.6      # m/s
    approach_s: float = 5.0          # s: the straight run before the execute
    astern_force: float = 0.0        # N: surge force after the execute (0: thrust off; < 0: astern)
    stop_speed: float = 0.02         # m/s: the speed over ground below which the vessel counts as stopped
    duration: float = 60.0           # s
    control_period: float = 0.01     # s
    conditions: str = "calm"

    def __post_init__(self):
        _check(self, positive=("approach_speed", "stop_speed", "duration", "control_period"),
               nonnegative=("approach_s",))
        if self.astern_force > 0:
            raise ScenarioError(f"manoeuvre.astern_force must be <= 0 N (thrust off or astern), "
                                f"got {self.astern_force!r}")
        if not self.stop_speed < self.approach_speed:   # "stopped" at the execute: a time to stop of 0
            raise ScenarioError(f"manoeuvre.stop_speed = {self.stop_speed!r} m/s must be below manoeuvre.approach_speed "
                                f"= {self.approach_speed!r} m/s (the vessel would count as stopped at the execute)")
        _check_duration(self)


KINDS = {"turning": TurningOptions, "zigzag": ZigzagOptions, "spiral": SpiralOptions, "stopping": StoppingOptions}
for _kind, _cls in KINDS.items():
    MANOEUVRES.register(_kind, options=_cls, doc=(_cls.__doc__ or "").strip().splitlines()[0])(_cls)


def options_of(kind: str, where: str = "manoeuvre.kind"):
    """The options dataclass of manoeuvre ``kind`` (:data:`usv_mj.core.registry.MANOEUVRES`)."""
    return MANOEUVRES.get(kind, where).options_class


@dataclass(frozen=True)
class ManoeuvreSpec:
    """``[manoeuvre]``: ``kind`` and that kind's options dataclass (:data:`KINDS`)."""

    kind: str = "turning"
    options: object = None

    def __post_init__(self):
        if self.kind not in MANOEUVRES:
            raise ScenarioError(f"manoeuvre.kind must be one of {', '.join(map(repr, MANOEUVRES.kinds()))}, "
                                f"got {self.kind!r}")
        if self.options is None:
            object.__setattr__(self, "options", options_of(self.kind)())

    def __getattr__(self, name):
        if name.startswith("_") or name == "options":
            raise AttributeError(name)
        return getattr(self.options, name)


#: the paper hull's length [m], the one the defaults of :data:`KINDS` are chosen for (usv_mj.vessels.PAPER_DIMENSIONS)
PAPER_LENGTH_M = 1.98
#: how each option scales with the length ratio lam = L / 1.98 m under Froude similarity (same
#: Froude number U / sqrt(g L), same density): speeds sqrt(lam), forces lam^3, moments lam^4
FROUDE_POWERS = {"approach_speed": 0.5, "stop_speed": 0.5, "yaw_moment": 4.0, "max_yaw_moment": 4.0,
                 "astern_force": 3.0}


def vessel_defaults(kind: str, vessel_model=None) -> dict:
    """The defaults of manoeuvre ``kind``'s options on a vessel (a :class:`usv_mj.vessels.Vessel`;
    None: the paper hull): the vessel's own, where it declares them (``Vessel.manoeuvre``: a data
    file's ``[manoeuvre]`` table, its keys for every kind that has them and its ``[manoeuvre.KIND]``
    subtables for one kind; e.g. the Otter's turning at the reference's propeller speeds),
    and the speeds and the "rudder" of :data:`KINDS`'s defaults (chosen for the paper hull at
    0.6 m/s, 10 N m) Froude-scaled to the vessel's length otherwise (:data:`FROUDE_POWERS`; the same
    test in nondimensional terms: Fn = 0.136, N' = tau_r / (0.5 rho U^2 L^3) = 0.0070). The paper
    hull's are :data:`KINDS`'s exactly (an empty dict). Only keys ``kind``'s options have."""
    if vessel_model is None:
        return {}
    names = {f.name for f in fields(options_of(kind))}
    dims = getattr(vessel_model, "dimensions", None)
    out = {}
    # a ruddered vessel's "rudder" is an angle, not a moment: nothing of the paper's test scales to it
    if dims is not None and float(dims.L) != PAPER_LENGTH_M and getattr(vessel_model, "channels", FORCES).forces:
        lam = float(dims.L) / PAPER_LENGTH_M
        base = options_of(kind)()
        out = {k: getattr(base, k) * lam ** p for k, p in FROUDE_POWERS.items() if k in names}
    own = getattr(vessel_model, "manoeuvre", None) or {}
    out.update({k: v for k, v in own.items() if k in names and not isinstance(v, dict)})
    out.update({k: v for k, v in (own.get(kind) or {}).items() if k in names})  # the kind's own table wins
    return out


def manoeuvre_from_table(table, source: str = "<dict>", vessel_model=None) -> ManoeuvreSpec:
    """A validated :class:`ManoeuvreSpec` from a ``[manoeuvre]`` table (every key checked); a key the
    table does not give takes the vessel's default (:func:`vessel_defaults`), then the kind's."""
    from usv_mj.scenario.tables import build_table

    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [manoeuvre] must be a table, got {table!r}")
    table = dict(table)
    kind = table.pop("kind", "turning")
    if not isinstance(kind, str) or kind not in MANOEUVRES:
        raise ScenarioError(f"{source}: manoeuvre.kind must be one of {', '.join(map(repr, MANOEUVRES.kinds()))}, "
                            f"got {kind!r}")
    vessel_model = getattr(vessel_model, "model", vessel_model)   # a scenario's VesselSpec or its Vessel
    given = table
    defaults = vessel_defaults(kind, vessel_model)
    table = {**defaults, **table}
    why = getattr(vessel_model, "limitations", {}).get(kind)
    if why:
        possible = [k for k in MANOEUVRES.kinds() if k not in vessel_model.limitations]
        raise ScenarioError(f"{source}: manoeuvre {kind!r} is not available on the vessel {vessel_model.kind!r}: {why}; "
                            f"{', '.join(possible)} are (docs/manoeuvres.md)")
    try:
        options = build_table(options_of(kind), table, source, "manoeuvre", extra_known={"kind"})
    except ScenarioError as exc:
        msg = str(exc)
        msg = msg if msg.startswith(source) else f"{source}: {msg}"
        own = {k: v for k, v in ((getattr(vessel_model, "manoeuvre", None) or {}).items()) if k in defaults}
        own.update({k: v for k, v in ((getattr(vessel_model, "manoeuvre", None) or {}).get(kind) or {}).items()
                    if k in defaults})
        blamed = {k: defaults[k] for k in own if k not in given}
        if blamed:   # the table alone is fine: the vessel's own [manoeuvre] values are what does not fit
            try:
                build_table(options_of(kind), given, source, "manoeuvre", extra_known={"kind"})
            except ScenarioError:
                blamed = {}
        if blamed:
            blamed = {k: v for k, v in blamed.items() if f"manoeuvre.{k}" in msg} or blamed
            values = ", ".join(f"{k} = {v!r}" for k, v in blamed.items())
            raise ScenarioError(f"vessel {vessel_model.kind!r}: its own [manoeuvre] defaults ({values}, from its data "
                                f"file) do not fit the {kind}: {msg.removeprefix(source + ': ')}") from None
        raise ScenarioError(msg) from None
    return ManoeuvreSpec(kind, options)
