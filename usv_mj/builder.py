"""One build: a scenario in, every running part of a run out (the one place that constructs a plant).

::

    from usv_mj import build, load_scenario, simulate
    parts = build(load_scenario("examples/scenarios/harbour_gap.toml", overrides={"sea": {"preset": "moderate"}}))
    record = simulate(parts)          # the plant is closed when the run ends

:func:`build` turns a :class:`~usv_mj.scenario.spec.Scenario` into :class:`Parts`:

- the **plant**, by ``[plant] kind`` from :data:`usv_mj.core.registry.PLANTS`: the analytic plant, or
  the MuJoCo plant on ``models/usv.xml`` alone or composed with the scenario's obstacles (with the
  contact model); both take the scenario's sea as their environment and its d(t) and Delta;
- the **controller**, by kind from :data:`usv_mj.core.registry.CONTROLLERS` with its own gains
  (``[controller]``, or ``[baseline]`` for the baseline's kind);
- the **reference**, by ``[trajectory] kind`` from :data:`usv_mj.core.registry.TRAJECTORIES`, or
  planned around the obstacles when ``[guidance] avoid``;
- the **quantizers** (the actuator channel, one per input) and the **actuators**
  (:class:`usv_mj.physics.actuators.Actuators` from ``[actuators]``: what the thrusters realize of the
  quantized command, the same on both plants);
- the **hooks** the loop calls before every step (clearance, contacts, online guidance) and the
  **sinks** that collect their results (the obstacle log);
- the **statics** the outputs need and must not rebuild: the sea the plant saw, the obstacles, the
  planned path.

Every command (``run``, ``compare``, ``render``, ``plot``, ``sweep``, ``capability``, ``env``) and
every dm_control task goes through here.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from usv_mj.core import arguments
from usv_mj.core.errors import ScenarioError, expected
from usv_mj.core.registry import CONTROLLERS, PLANTS
from usv_mj.physics.channels import RunChannels, run_channels
from usv_mj.physics.sea.environment import run_sea
from usv_mj.scenario.spec import Scenario
from usv_mj.references.trajectories import make_reference



@dataclass
class Statics:
    """What a run's outputs need besides its rows (plain data; no live plant).

    Attributes
    ----------
    environment: the :class:`usv_mj.physics.sea.Environment` the plant saw (None in calm water).
    obstacles: the scenario's :class:`~usv_mj.scenario.obstacles.ObstacleSpec` tuple.
    plan: the guidance's :class:`~usv_mj.references.planner.Plan` (None without ``avoid``).
    obstacle_log: the :class:`~usv_mj.obstacles.sink.ObstacleLog` (clearance per step), or None.
    guidance: the online guidance of moving obstacles, or None.
    reference: the reference the run tracked (a pure function of t; sampled for drawn paths).
    """

    environment: Any = None
    obstacles: tuple = ()
    plan: Any = None
    obstacle_log: Any = None
    guidance: Any = None
    reference: Any = None


@dataclass
class Parts:
    """Everything :func:`usv_mj.simulate` needs for one run (see the module docstring)."""

    scenario: Scenario
    duration: float
    plant: Any
    controller: Any
    reference: Any
    quantizers: tuple
    actuators: Any = None
    hooks: tuple = ()
    sinks: tuple = ()
    statics: Statics = field(default_factory=Statics)
    metadata: dict = field(default_factory=dict)
    own_plant: bool = True

    def close(self) -> None:
        """Release the plant (a MuJoCo callback, a composed model file) if this build made it."""
        if self.own_plant and self.plant is not None:
            self.plant.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def make_environment(scenario: Scenario, duration: float | None = None):
    """The scenario's sea (waves, current, wind; docs/sea.md), or None when it is calm."""
    return run_sea(scenario.sea, scenario.ship, scenario.duration if duration is None else duration)


def make_plant(scenario: Scenario, kind: str | None = None, environment="scenario", *, control_period: float | None = None,
               substeps: int | None = None, contact=None, safety_radii=None, rangefinders=()):
    """The plant ``kind`` (default ``[plant] kind``) of ``scenario`` from :data:`usv_mj.core.registry.PLANTS`,
    in the scenario's sea (or ``environment``: an Environment, or None for calm water), with the
    scenario's obstacles in its scene; ``control_period`` [s] / ``substeps`` override the scenario's
    (the convergence studies of ``usv-mj compare``); ``rangefinders``: body-frame angles [rad] of
    range sensors on the hull (the harbor task's; a plant kind that has none raises ScenarioError).
    The caller closes it."""
    if control_period is not None or substeps is not None:
        over = {}
        if control_period is not None:
            over["control_period"] = float(control_period)
        if substeps is not None:
            over["plant"] = {"substeps": int(substeps)}
        scenario = scenario.with_overrides(over)
    kind = kind or scenario.plant.kind
    entry = PLANTS.get(kind, "plant.kind")
    extra = {}
    if len(rangefinders):
        if not entry.info.get("rangefinders"):
            raise ScenarioError(f"{scenario.source}: the {kind!r} plant has no rangefinders")
        extra["rangefinders"] = tuple(float(a) for a in rangefinders)
    env = make_environment(scenario) if isinstance(environment, str) and environment == "scenario" else environment
    if kind == scenario.plant.kind:
        options = scenario.plant.options
    else:
        options = entry.options_class() if entry.options_class is not None else None
    return entry.make(options, scenario, environment=env, obstacles=tuple(scenario.obstacles), contact=contact,
                      safety_radii=safety_radii, **extra)


def make_controller(scenario: Scenario, kind: str | None = None):
    """The controller ``kind`` (default ``[controller] kind``) with its gains from the scenario:
    ``[controller]``'s when it is that kind, ``[baseline]``'s when it is the baseline's, its
    defaults otherwise."""
    kind = kind or scenario.controller.kind
    entry = CONTROLLERS.get(kind, "controller")
    section = "controller" if kind == scenario.controller.kind else "baseline" if kind == scenario.baseline.kind else None
    if section is not None:
        gains = getattr(scenario, section).gains
    else:
        gains = entry.gains() if entry.info.get("gains") else None
    check_channel_values(scenario, kind, entry.obj, gains, section)
    return entry.make(gains, scenario)


def check_channel_values(scenario: Scenario, kind: str, controller, gains, section: str | None) -> None:
    """A controller whose numbers are the vessel's own channels (``commands = "any"``: the open-loop
    and zig-zag inputs) declares those gains by ``metadata={"channel": "surge" | "yaw"}``; their
    defaults are a force [N] and a moment [N m]. On a vessel whose channels are not forces (KVLCC2's
    n_P and rudder angle) each such gain must be given in the scenario, in the channel's unit: a
    default taken as rev/s or rad (the rudder hard over) is refused, naming the key and the unit."""
    if getattr(controller, "commands", "forces") != "any" or gains is None or not dataclasses.is_dataclass(gains):
        return
    channels = scenario.vessel.model.channels
    if channels.forces:
        return
    given = scenario.raw.get(section) if section else None
    given = given if isinstance(given, dict) else {}
    for f in dataclasses.fields(gains):
        which = f.metadata.get("channel")
        if which in ("surge", "yaw") and f.name not in given and getattr(gains, f.name) is not None:
            ch = getattr(channels, which)
            raise ScenarioError(
                f"{scenario.source}: {section or 'controller'}.{f.name}: the {kind!r} controller's default "
                f"{getattr(gains, f.name)!r} is a force or moment for a vessel whose channels are forces; the vessel "
                f"{scenario.vessel.kind!r} takes the {ch.quantity} {ch.symbol} [{ch.unit}] there: give "
                f"{section or 'controller'}.{f.name} in {ch.unit}")


def commands_error(scenario: Scenario, controller, kind: str) -> str | None:
    """Why controller ``kind`` (an instance or its registered class) cannot drive the scenario's
    vessel (None: it can): :func:`usv_mj.physics.channels.run_channels` of the vessel's channels and
    the controller's ``commands`` ("forces" unless it says otherwise; "any": its numbers are the
    vessel's own channels, as the open-loop and zig-zag controllers'; "rudder": a ruddered ship's
    n_P and rudder angle). A force controller drives a ruddered vessel (KVLCC2) through the
    allocation of :func:`make_actuators`."""
    try:
        run_channels(scenario.vessel.model.channels, getattr(controller, "commands", "forces"),
                     f"the vessel {scenario.vessel.kind!r}")
    except ValueError as exc:
        return f"the {kind!r} controller cannot drive the vessel: {exc}"
    return None


def check_commands(scenario: Scenario, kind: str, note: str = "") -> None:
    """:func:`commands_error` for the registered controller ``kind``, as one ScenarioError (+ ``note``)."""
    problem = commands_error(scenario, CONTROLLERS.get(kind, "controller").obj, kind)
    if problem is not None:
        raise ScenarioError(f"{scenario.source}: {problem}{note}")


def allocation_of(scenario: Scenario):
    """The packed MMG block a force command is allocated through on the scenario's vessel
    (its channels' ``allocation``), or None: a vessel whose channels are forces needs none."""
    return scenario.vessel.model.channels.allocation


def make_quantizers(scenario: Scenario, commands: str = "forces"):
    """The hysteresis quantizers of the surge and yaw channels (Eq. 3), from ``[quantizer]``: on
    when it is enabled and the command's channels are quantized (forces; a ruddered vessel's n_P
    and rudder angle commanded as they are are not: Eq. 3 is a quantizer of forces)."""
    from usv_mj.controllers.hysteresis_quantizer import HysteresisQuantizer, QuantizerParams

    q = scenario.quantizer
    on = q.enabled and channels_of(scenario, commands).command.quantized
    return (HysteresisQuantizer(QuantizerParams(q.delta_u, q.u_min_u), on),
            HysteresisQuantizer(QuantizerParams(q.delta_r, q.u_min_r), on))


def channels_of(scenario: Scenario, commands: str = "forces") -> RunChannels:
    """What the run's channel columns hold for a controller commanding ``commands``
    (:class:`usv_mj.physics.channels.RunChannels`: the command's channels and the applied ones; they
    differ when a force command is allocated to a ruddered vessel's n_P and rudder angle). Its
    ``to_metadata()`` is the record's ``metadata["channels"]``."""
    return run_channels(scenario.vessel.model.channels, commands, f"the vessel {scenario.vessel.kind!r}")


def allocated_force_limits(scenario: Scenario):
    """(tau_u_min, tau_u_max, tau_r_min, tau_r_max) [N, N m] a force command can reach through the
    allocation of a ruddered vessel at its approach speed going straight (:func:`usv_mj.physics.mmg.mmg_force_limits`;
    0 the least surge force: the MMG's propeller does not pull astern), or None: no allocation."""
    mmg = allocation_of(scenario)
    if mmg is None:
        return None
    import numpy as np

    from usv_mj.physics.mmg import mmg_force_limits

    _, n_hi, _, delta_hi = scenario.actuators.generalized_limits()
    speed = float((scenario.vessel.model.manoeuvre or {}).get("approach_speed", 1.0))
    x_max, n_max = mmg_force_limits(np.asarray(mmg, dtype=float), 0, speed, n_hi, delta_hi)
    return 0.0, float(x_max), -float(n_max), float(n_max)


def make_actuators(scenario: Scenario, commands: str = "forces"):
    """The actuator model of ``[actuators]`` at the scenario's control period (:mod:`usv_mj.physics.actuators`);
    with the allocation of a force command to the rudder and the propeller when the command is
    ``"forces"`` (a controller's ``commands``; the environments' action) and the vessel is ruddered
    (:func:`allocation_of`)."""
    from usv_mj.physics.actuators import Actuators

    run = channels_of(scenario, commands)
    return Actuators.from_scenario(scenario, run.applied.allocation if run.allocated else None)


def check_start_clear(scenario: Scenario) -> None:
    """ScenarioError if the start pose puts the hull inside an obstacle (checked before anything runs)."""
    if not scenario.obstacles:
        return
    from usv_mj.obstacles.clearance import GeometricClearance

    clearance = GeometricClearance(scenario.obstacles, exact_within=math.inf,
                                   dimensions=scenario.vessel.model.dimensions).update(
        0.0, np.r_[scenario.initial.eta, 0, 0, 0])
    for i in np.flatnonzero(clearance <= 0.0):
        raise ScenarioError(f"{scenario.source}: initial.eta = {list(scenario.initial.eta)} puts the hull inside "
                            f"obstacles[{i}] ({scenario.obstacles[i].name}, clearance {clearance[i]:.3f} m)")


def as_scenario(scenario, where: str) -> Scenario:
    """``scenario`` as a :class:`Scenario`: a preset name ("paper") is loaded; anything else but a
    Scenario is an :class:`usv_mj.core.errors.ArgumentTypeError` naming ``where``."""
    from usv_mj.core.errors import expected

    if isinstance(scenario, str):
        from usv_mj.scenario.spec import load_scenario

        return load_scenario(preset=scenario)
    if not isinstance(scenario, Scenario):
        hint = " (a dict: load_scenario(preset=..., overrides={...}))" if isinstance(scenario, dict) else ""
        raise expected(where, "scenario", "a Scenario (usv_mj.load_scenario) or a preset name such as 'paper'"
                       + hint, scenario)
    return scenario


#: what a plant or a controller handed to :func:`build` must have (usv_mj.plants.base.Plant; the laws)
PLANT_ATTRIBUTES = ("name", "control_period", "reset", "step", "state", "close")
CONTROLLER_ATTRIBUTES = ("name", "reset", "__call__")


def check_part(part, where: str, name: str, attributes) -> None:
    """An :class:`usv_mj.core.errors.ArgumentTypeError` unless ``part`` has every one of ``attributes``."""
    from usv_mj.core.errors import expected

    missing = [a for a in attributes if not hasattr(part, a)]
    if missing:
        raise expected(where, name, f"a {name} with {', '.join(attributes)} (it has no {', '.join(missing)})", part)


def build(scenario: Scenario, *, plant_kind: str | None = None, controller_kind: str | None = None,
          duration: float | None = None, plant=None, controller=None, reference=None, environment="scenario",
          contact=None, show_safety: bool = True, plan=None) -> Parts:
    """The running parts of ``scenario`` (module docstring).

    ``plant_kind`` / ``controller_kind`` choose other registered kinds than the scenario's (the
    baseline run, the other plant of a comparison); ``duration`` [s] another horizon. ``plant``,
    ``controller`` and ``reference`` hand in ready-made parts instead (a plant handed in is not
    closed by :meth:`Parts.close`). ``environment`` overrides the scenario's sea (None: calm).
    ``contact`` is the MuJoCo contact model (:class:`usv_mj.scene.compose.ContactParams`).
    ``plan``: the :class:`usv_mj.references.planner.Plan` of an earlier build of this scenario (the
    half-step check runs the main run's plan); by default :func:`usv_mj.obstacles.make_plan`'s.
    """
    scenario = as_scenario(scenario, "build")
    for part, name, attributes in ((plant, "plant", PLANT_ATTRIBUTES), (controller, "controller", CONTROLLER_ATTRIBUTES)):
        if part is not None:
            check_part(part, "build", name, attributes)
    if duration is not None and not arguments.is_real(duration):   # not True, not '1'
        raise expected("build", "duration", "a number of seconds > 0 or None (the scenario's)", duration)
    if reference is not None:
        arguments.having("build", "reference", reference, ("evaluate",), "a reference trajectory")
    duration = scenario.duration if duration is None else float(duration)
    if not (math.isfinite(duration) and duration > 0):
        raise ScenarioError(f"{scenario.source}: duration must be > 0 s, got {duration!r}")
    check_start_clear(scenario)
    env = make_environment(scenario, duration) if environment == "scenario" else environment
    statics = Statics(environment=env, obstacles=tuple(scenario.obstacles))
    metadata: dict = {}
    given, plan = plan, None
    if scenario.obstacles and scenario.guidance.avoid and reference is None:
        from usv_mj.obstacles.hooks import make_plan

        plan = given.fresh() if given is not None else make_plan(scenario, duration)
        statics.plan = plan
    own_plant = plant is None
    if plant is None:
        kind = plant_kind or scenario.plant.kind
        inflation = plan.safety_radius if plan is not None else None
        safety = np.nan_to_num(inflation, nan=0.0) if (show_safety and inflation is not None) else None
        plant = make_plant(scenario, kind, env, contact=contact, safety_radii=safety)
    try:
        controller = controller if controller is not None else make_controller(scenario, controller_kind)
        problem = commands_error(scenario, controller, controller_kind or scenario.controller.kind)
        if problem is not None:
            raise ScenarioError(f"{scenario.source}: {problem}")
        if reference is None:
            reference = plan.reference if plan is not None else make_reference(scenario.trajectory, duration, scenario)
        hooks, sinks = (), ()
        if scenario.obstacles:
            hooks, sinks, metadata = _obstacle_parts(scenario, plant, plan, duration, statics, contact)
            reference = statics.guidance.reference if statics.guidance is not None else reference
        statics.reference = reference
    except BaseException:
        if own_plant:
            plant.close()
        raise
    commands = getattr(controller, "commands", "forces")
    return Parts(scenario, duration, plant, controller, reference, make_quantizers(scenario, commands),
                 make_actuators(scenario, commands), hooks, sinks, statics, metadata, own_plant)


def _obstacle_parts(scenario, plant, plan, duration, statics, contact):
    """The clearance monitor, the obstacle log and the online guidance as one loop hook and a sink."""
    from usv_mj.obstacles.clearance import make_clearance_monitor
    from usv_mj.scene.compose import ContactParams
    from usv_mj.scene.hull import vessel_hull_radius
    from usv_mj.obstacles.hooks import ObstacleHook
    from usv_mj.references.planner import Guidance
    from usv_mj.obstacles.sink import ObstacleLog

    obstacles = statics.obstacles
    dims = scenario.vessel.model.dimensions          # the vessel's hull (the paper's: the constants)
    monitor = make_clearance_monitor(plant, obstacles, dims)
    n_rows = int(round(duration / scenario.control_period)) + 1
    inflation = plan.safety_radius if plan is not None else None
    reach = monitor.exact_within if getattr(monitor, "broad_phase", False) else None
    log = ObstacleLog(obstacles, n_rows, scenario.guidance.margin_m, scenario.control_period, monitor.note, inflation,
                      exact_within=reach)
    guidance = None
    if plan is not None and any(o.moving for o in obstacles):
        guidance = Guidance(plan.reference, obstacles, plan.envelope, scenario.guidance, scenario.trajectory.speed,
                            log, goal=plan.polyline[-1])
    if plan is not None:
        for event in plan.events:
            log.add_event(event)
    statics.obstacle_log, statics.guidance = log, guidance
    is_mujoco = hasattr(plant, "obstacle_geoms")
    metadata = {"guidance": {
        "avoid": scenario.guidance.avoid, "margin_m": scenario.guidance.margin_m,
        "plan_verified": None if plan is None else plan.verified,
        "plan_iterations": None if plan is None else plan.iterations,
        "hull_radius_m": vessel_hull_radius(dims), "eps_m": scenario.ship.eps,
        "contact": dataclasses.asdict(contact or ContactParams()) if is_mujoco else None}}
    if monitor.note:
        metadata["note"] = monitor.note
    return (ObstacleHook(plant, monitor, log, guidance),), (log,), metadata


# --- several vessels in one sea (scenario [[vessels]], issue 35) ------------------------------------


@dataclass
class VesselParts:
    """One vessel of a fleet's build: its name, whether it is the own ship, its own scenario (the
    scene's tables with the vessel's merged in: usv_mj.scenario.fleet), and the running parts a
    single run of it would have (controller, reference, quantizers, actuators)."""

    name: str
    own_ship: bool
    scenario: Scenario
    controller: Any
    reference: Any
    quantizers: tuple
    actuators: Any


@dataclass
class FleetParts:
    """Everything :func:`usv_mj.simulate` needs for a run of several vessels: the shared plant (the
    vessel index a dimension: ``reset_vessel``, ``step_vessels``, ``states``), one
    :class:`VesselParts` per vessel in the scenario's order, the statics (the shared sea)."""

    scenario: Scenario
    duration: float
    plant: Any
    vessels: tuple
    statics: Statics = field(default_factory=Statics)
    metadata: dict = field(default_factory=dict)
    own_plant: bool = True

    def close(self) -> None:
        if self.own_plant and self.plant is not None:
            self.plant.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def make_fleet_plant(scenario: Scenario, kind: str | None = None, environment="scenario"):
    """The plant of a fleet scenario: the plant kind's own fleet (the registry's ``fleet`` factory:
    the MuJoCo plant's, every hull in one model with contacts between them), else one plant of the
    kind per vessel (usv_mj.plants.fleet.SeparateHulls: the analytic plant's)."""
    from usv_mj.plants.fleet import SeparateHulls

    kind = kind or scenario.plant.kind
    env = make_environment(scenario) if isinstance(environment, str) and environment == "scenario" else environment
    factory = PLANTS.get(kind, "plant.kind").info.get("fleet")
    if factory is not None:
        return factory([(v.name, v.scenario) for v in scenario.vessels], environment=env,
                       obstacles=tuple(scenario.obstacles))
    plants = []
    try:
        for v in scenario.vessels:
            plants.append(make_plant(v.scenario, kind, env))
    except BaseException:
        for p in plants:
            p.close()
        raise
    return SeparateHulls(plants, [v.name for v in scenario.vessels])


def build_fleet(scenario: Scenario, *, plant_kind: str | None = None, duration: float | None = None,
                environment="scenario") -> FleetParts:
    """The running parts of a scenario with ``[[vessels]]`` (:class:`FleetParts`): each vessel's
    controller, reference, quantizers and actuators as its own single build makes them, and one
    plant for all. ``plant_kind`` / ``duration`` / ``environment`` as :func:`build`'s."""
    scenario = as_scenario(scenario, "build_fleet")
    if not scenario.vessels:
        raise ScenarioError(f"{scenario.source}: build_fleet: the scenario has no [[vessels]]")
    duration = scenario.duration if duration is None else float(duration)
    if not (math.isfinite(duration) and duration > 0):
        raise ScenarioError(f"{scenario.source}: duration must be > 0 s, got {duration!r}")
    if scenario.obstacles and scenario.guidance.avoid:
        raise ScenarioError(f"{scenario.source}: [guidance] avoid (true by default beside obstacles) plans one "
                            f"vessel's path around the obstacles; with [[vessels]] each vessel's controller keeps "
                            f"clear itself: set [guidance] avoid = false (--set guidance.avoid=false)")
    env = make_environment(scenario, duration) if environment == "scenario" else environment
    vessels = []
    for v in scenario.vessels:
        sc = v.scenario
        controller = make_controller(sc)
        problem = commands_error(sc, controller, sc.controller.kind)
        if problem is not None:
            raise ScenarioError(f"{sc.source}: {problem}")
        commands = getattr(controller, "commands", "forces")
        vessels.append(VesselParts(v.name, v.own_ship, sc, controller, make_reference(sc.trajectory, duration, sc),
                                   make_quantizers(sc, commands), make_actuators(sc, commands)))
    plant = make_fleet_plant(scenario, plant_kind, env)
    return FleetParts(scenario, duration, plant, tuple(vessels), Statics(environment=env,
                                                                          obstacles=tuple(scenario.obstacles)))
