"""The run each standard manoeuvre is: its open-loop or heading-switching input and the approach.

A manoeuvre is an ordinary run of the scenario with its controller replaced by an open-loop or a
heading-switching input (``controllers/open_loop.py``, ``controllers/zigzag.py``), started on a
straight course at the approach speed held by :func:`approach_force`. Its options are the
scenario's ``[manoeuvre]`` table (:mod:`usv_mj.scenario.manoeuvre`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import fields

from usv_mj.core.errors import ScenarioError
from usv_mj.physics.channels import RUDDER_ANGLE
from usv_mj.scenario.manoeuvre import SIDES, ManoeuvreSpec


def approach_force(scenario, speed: float) -> float:
    """The constant surge force [N] that holds ``speed`` [m/s] on a straight course, from the
    scenario's own analytic plant (the one build's :func:`usv_mj.builder.make_plant`, calm water):
    the F for which one integrator step from nu = (U, 0, 0) leaves the surge speed unchanged, by
    secant iteration (the step is affine in F but for terms of order dt^2). A step of RK4 leaves a
    state unchanged exactly where the vessel's acceleration is zero, so this is the equilibrium of
    whatever hull the plant integrates (the paper's: d11(U) U - s 0.6, docs/model.md §1), with the
    scenario's Delta included when it is on (d(t), a time-varying load, is not part of the drag:
    left out)."""
    import dataclasses

    from usv_mj.builder import make_plant

    vessel = getattr(getattr(scenario, "vessel", None), "model", None)
    guess = getattr(vessel, "nominal_rps", None)   # a ruddered vessel: the force channel is n_P [1/s]
    if hasattr(scenario.disturbance, "scale"):
        scenario = dataclasses.replace(scenario, disturbance=dataclasses.replace(scenario.disturbance, scale=0.0))
    plant = make_plant(scenario, "analytic", environment=None)
    try:
        def gain(force):
            plant.reset((0.0, 0.0, 0.0), (speed, 0.0, 0.0), 0.0)
            plant.step(force, 0.0)
            return float(plant.state[3]) - speed

        f0, f1 = (float(guess), 1.02 * float(guess)) if guess else (0.0, 1.0)
        g0, g1 = gain(f0), gain(f1)
        for _ in range(30):
            if g1 == g0:
                break
            f0, f1, g0 = f1, f1 - g1 * (f1 - f0) / (g1 - g0), g1
            g1 = gain(f1)
            if abs(f1 - f0) <= 1e-12 * max(1.0, abs(f1)):
                break
    finally:
        plant.close()
    if not math.isfinite(f1):
        raise ScenarioError(f"{scenario.source}: no constant surge force holds manoeuvre.approach_speed = {speed!r}")
    return float(f1)


def _no_delta(scenario) -> dict:
    """The override that takes the paper's Delta off the scenario's vessel: ``[ship]`` for the paper
    vessel, its ``[vessel]`` key for a vessel that has one (none: it has no Delta)."""
    vessel = getattr(scenario, "vessel", None)
    if vessel is None or vessel.kind == "paper":
        return {"ship": {"uncertainty_scale": 0.0}}
    options = vessel.options
    if dataclasses.is_dataclass(options) and any(f.name == "uncertainty_scale" for f in dataclasses.fields(options)):
        return {"vessel": {"uncertainty_scale": 0.0}}
    return {}


def manoeuvre_overrides(scenario, spec: ManoeuvreSpec) -> dict:
    """The scenario overrides that make ``scenario`` run manoeuvre ``spec`` (module docstring)."""
    o = spec.options
    calm = o.conditions == "calm"
    over = {"baseline": {"enabled": False}, "control_period": o.control_period,
            "initial": {"eta": [0.0, 0.0, 0.0], "nu": [o.approach_speed, 0.0, 0.0]}}
    if calm:
        over.update(disturbance={"scale": 0.0}, quantizer={"enabled": False}, **_no_delta(scenario))
        scenario = scenario.with_overrides(over)  # the drag with the test's Delta (none)
    limits = scenario.limits
    if not o.approach_speed < limits.max_speed:   # the run would stop as diverged at its first step
        raise ScenarioError(f"{scenario.source}: manoeuvre.approach_speed = {o.approach_speed!r} m/s is not below "
                            f"limits.max_speed = {limits.max_speed!r} m/s, where a run counts as diverged")
    force = approach_force(scenario, o.approach_speed)
    if not abs(force) < limits.max_force:
        raise ScenarioError(f"{scenario.source}: manoeuvre.approach_speed = {o.approach_speed!r} m/s takes a surge "
                            f"force of {force:.6g} N, not below limits.max_force = {limits.max_force!r} N")
    # a ruddered vessel (usv_mj.physics.mmg): the channels are (n_P [1/s], delta [rad]); its [actuators]
    # limit the rudder's angle and rate (docs/manoeuvres.md §2)
    ruddered = scenario.vessel.model.channels.yaw == RUDDER_ANGLE   # the "rudder" is a rudder angle, not a moment
    if ruddered:   # a rudder angle beyond the steering gear's would be held at its limit, measured as asked
        key = {"turning": "rudder_deg", "zigzag": "angle_deg", "spiral": "max_rudder_deg"}.get(spec.kind)
        limit = math.degrees(scenario.actuators.generalized_limits()[3])
        if key is not None and getattr(o, key) > limit + 1e-9:
            raise ScenarioError(f"{scenario.source}: manoeuvre.{key} = {getattr(o, key)!r} deg is beyond the rudder of "
                                f"the vessel {scenario.vessel.kind!r}, {limit:g} deg")
    if spec.kind == "turning":
        sign = SIDES[o.side]
        rudder = math.radians(o.rudder_deg) if ruddered else o.yaw_moment
        ctrl = {"kind": "open_loop", "times": [0.0, o.approach_s], "tau_u": force,
                "tau_r": [0.0, sign * rudder], "interpolation": "step"}
        duration = o.duration
    elif spec.kind == "zigzag":
        rudder = math.radians(o.angle_deg) if ruddered else o.yaw_moment   # the 10/10: 10 deg of rudder
        ctrl = {"kind": "zigzag", "tau_u": force, "tau_r_amplitude": rudder, "psi_switch_deg": o.angle_deg,
                "first_turn": o.first_turn}
        duration = o.duration
    elif spec.kind == "spiral":
        cmds = o.commands(math.radians(o.max_rudder_deg) if ruddered else None)
        ctrl = {"kind": "open_loop", "times": [i * o.hold_s for i in range(len(cmds))], "tau_u": force,
                "tau_r": [c for c, _ in cmds], "interpolation": "step"}
        duration = o.duration
    else:
        ctrl = {"kind": "open_loop", "times": [0.0, o.approach_s], "tau_u": [force, o.astern_force],
                "tau_r": 0.0, "interpolation": "step"}
        duration = o.duration
    over["controller"] = ctrl
    over["duration"] = duration
    # the reference (the original course) runs on at the approach speed while the vessel turns: a
    # manoeuvre is not judged on it, so its distance limit must not end a long one (a spiral)
    reach = 2.0 * o.approach_speed * duration + 100.0
    if reach > scenario.limits.max_distance:
        over["limits"] = {"max_distance": reach}
    return over


def manoeuvre_scenario(scenario, spec: ManoeuvreSpec | None = None):
    """``scenario`` made to run manoeuvre ``spec`` (default: its own ``[manoeuvre]``), validated
    again; its ``[controller]`` is replaced whole by the manoeuvre's input and its ``[trajectory]``
    by the original course (a line from the start at the approach speed)."""
    from usv_mj.scenario.spec import from_dict, merge_tables

    spec = spec if spec is not None else scenario.manoeuvre
    if spec is None:
        raise ScenarioError(f"{scenario.source}: no [manoeuvre] to run (give its kind)")
    over = manoeuvre_overrides(scenario, spec)
    ctrl = over.pop("controller")
    raw = {k: v for k, v in scenario.raw.items() if k not in ("controller", "trajectory")}
    if spec.options.conditions == "calm":
        raw.pop("sea", None)
    data = merge_tables(raw, over)
    data["controller"] = ctrl
    # the reference: the original course at the approach speed (what the run's figures and video
    # show the track against; a manoeuvre is not judged on it)
    data["trajectory"] = {"kind": "line", "speed": spec.options.approach_speed, "start": [0.0, 0.0], "heading_deg": 0.0}
    data["manoeuvre"] = {"kind": spec.kind, **{f.name: getattr(spec.options, f.name) for f in fields(spec.options)}}
    return from_dict(data, source=scenario.source or "<manoeuvre>")


def execute_time(spec: ManoeuvreSpec) -> float:
    """When the "rudder" (or the engine order) is put over [s]."""
    return getattr(spec.options, "approach_s", 0.0)
