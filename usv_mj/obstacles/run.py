"""Running a scenario with obstacles through the standard loop (issue 8).

:func:`run_obstacle_scenario` builds the plant (a :class:`~usv_mj.obstacles.compose.HarbourPlant`
for ``plant = "mujoco"``, the analytic plant otherwise), the clearance monitor, the
:class:`~usv_mj.obstacles.sink.ObstacleLog`, the plan and the online :class:`~usv_mj.obstacles.planner.Guidance`,
and runs :func:`usv_mj.simulation.simulate` with an :class:`ObstacleHook` called before every step.

The per-step obstacle work is an :class:`ObstacleHook` that the loop calls before it evaluates the
(guided) reference: move the mocap obstacles to time t, measure the clearance and contacts, and let
the guidance re-time the reference.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from usv_mj.plants.analytic import AnalyticPlant
from usv_mj.scenario import ScenarioError
from usv_mj.simulation import make_controller, simulate

from .clearance import GeometricClearance, make_clearance_monitor
from .compose import HULL_RADIUS, ContactParams, HarbourPlant
from .planner import Guidance, Plan, SafetyEnvelope, plan_reference
from .sink import ObstacleLog
from .spec import ObstacleScenario


class ObstacleHook:
    """The obstacle work of one control step, as a :func:`usv_mj.simulation.simulate` hook: move
    the moving obstacles to time t, measure clearance and contacts, log them, and let the guidance
    re-time or shift the reference before the loop evaluates it."""

    def __init__(self, plant, monitor, log: ObstacleLog, guidance: Guidance | None = None):
        self.monitor, self.log, self.guidance = monitor, log, guidance
        moving = any(o.moving for o in getattr(plant, "obstacles", ()))
        self._move = getattr(plant, "move_obstacles", None) if moving else None

    def __call__(self, t, k, plant):
        if self._move is not None:
            self._move(t)
        clearance = self.monitor.update(t, plant)
        self.log.record_step(t, clearance, self.monitor.normal_force, self.monitor.in_contact)
        if self.guidance is not None:
            self.guidance.update(t)


@dataclass
class ObstacleRun:
    """What :func:`run_obstacle_scenario` returns: the record, the obstacle log, the plan (None with
    ``guidance.avoid = false``) and the guidance (None without moving obstacles)."""

    record: object
    log: ObstacleLog
    plan: Plan | None
    guidance: Guidance | None


def make_plan(osc: ObstacleScenario, duration: float | None = None) -> Plan:
    """The static plan of an obstacle scenario: start = trajectory.points[0] (waypoints) or
    trajectory.start (line), goal = the last waypoint (or 1 km along the line), speed =
    trajectory.speed, psi0 = initial heading."""
    sc = osc.scenario
    tr = sc.trajectory
    if tr.kind == "waypoints":
        start, goal = tr.points[0], tr.points[-1]
    elif tr.kind == "line":
        h = math.radians(tr.heading_deg)
        start, goal = tr.start, (tr.start[0] + 1000.0 * math.cos(h), tr.start[1] + 1000.0 * math.sin(h))
    else:
        raise ValueError(f"guidance.avoid needs trajectory.kind = 'waypoints' or 'line' (start and goal), "
                         f"got {tr.kind!r}")
    envelope = SafetyEnvelope.from_scenario(sc, osc.guidance.margin_m)
    return plan_reference(start, goal, osc.obstacles, envelope, osc.guidance, tr.speed,
                          duration or sc.duration, sc.initial.eta[2])


def check_start_clearance(sc, obstacles) -> None:
    """ScenarioError when the start pose puts the hull inside one of ``obstacles`` (also checked by
    :mod:`usv_mj.preflight` before a run creates anything)."""
    start_clearance = GeometricClearance(obstacles, exact_within=math.inf).update(0.0, np.r_[sc.initial.eta, 0, 0, 0])
    for i in np.flatnonzero(start_clearance <= 0.0):
        raise ScenarioError(f"{sc.source}: initial.eta = {list(sc.initial.eta)} puts the hull inside obstacles[{i}] "
                            f"({obstacles[i].name}, clearance {start_clearance[i]:.3f} m)")


def run_obstacle_scenario(osc: ObstacleScenario, plant_kind: str | None = None, duration: float | None = None,
                          sinks=(), contact: ContactParams = ContactParams(), controller=None,
                          show_safety: bool = True, progress=None) -> ObstacleRun:
    """Run ``osc`` in closed loop with obstacles (module docstring); the plant is closed at the end."""
    sc = osc.scenario
    duration = sc.duration if duration is None else float(duration)
    kind = plant_kind or sc.plant.kind
    check_start_clearance(sc, osc.obstacles)
    plan = make_plan(osc, duration) if osc.guidance.avoid else None
    inflation = plan.safety_radius if plan is not None else None
    if kind == "mujoco":
        plant = HarbourPlant(sc.ship, sc.disturbance, osc.obstacles, sc.control_period, sc.plant.substeps, contact,
                             safety_radii=np.nan_to_num(inflation, nan=0.0) if (show_safety and inflation is not None)
                             else None)
    elif kind == "analytic":
        plant = AnalyticPlant(sc.ship, sc.disturbance, sc.control_period, sc.plant.substeps)
    else:
        raise ValueError(f"unknown plant kind {kind!r}")
    try:
        monitor = make_clearance_monitor(plant, osc.obstacles)
        n_rows = int(round(duration / sc.control_period)) + 1
        log = ObstacleLog(osc.obstacles, n_rows, osc.guidance.margin_m, sc.control_period, monitor.note, inflation)
        guidance = None
        reference = plan.reference if plan is not None else None
        if plan is not None and any(o.moving for o in osc.obstacles):
            guidance = Guidance(plan.reference, osc.obstacles, plan.envelope, osc.guidance, sc.trajectory.speed, log,
                                goal=plan.polyline[-1])
        hook = ObstacleHook(plant, monitor, log, guidance)
        if plan is not None:
            for event in plan.events:
                log.add_event(event)
        for sink in sinks:   # a run-log sink writes the log's arrays on P/obstacles (usv_mj.runlog.extra_topics)
            attach = getattr(sink, "attach_obstacle_log", None)
            if attach is not None:
                attach(log)
        record = simulate(sc, plant, controller or make_controller(sc), sinks=[log, *sinks], duration=duration,
                          reference=reference, hooks=[hook], progress=progress)
    finally:
        plant.close()
    record.metadata["guidance"] = {"avoid": osc.guidance.avoid, "margin_m": osc.guidance.margin_m,
                                   "plan_verified": None if plan is None else plan.verified,
                                   "plan_iterations": None if plan is None else plan.iterations,
                                   "hull_radius_m": HULL_RADIUS, "eps_m": sc.ship.eps,
                                   "contact": dataclasses.asdict(contact) if kind == "mujoco" else None}
    return ObstacleRun(record, log, plan, guidance)
