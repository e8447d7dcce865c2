"""Running a scenario with obstacles through the standard loop (issue 8).

:func:`run_obstacle_scenario` builds the plant (a :class:`~usv_mj.obstacles.compose.HarbourPlant`
for ``plant = "mujoco"``, the analytic plant otherwise), the clearance monitor, the
:class:`~usv_mj.obstacles.sink.ObstacleLog`, the plan and the online :class:`~usv_mj.obstacles.planner.Guidance`,
and runs :func:`usv_mj.simulation.simulate` with an :class:`ObstacleStepper` around the controller.

Until ``simulate`` takes a reference and per-step hooks itself (see the integration notes), the
stepper does the per-step work inside the controller call, which the loop makes once per row
before the plant step: move the mocap obstacles to time t, measure the clearance and contacts,
let the guidance re-time the reference, and write the guided reference into the loop's reference
vector (which the loop then records in the row).
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
from .planner import Guidance, GuidedReference, Plan, SafetyEnvelope, plan_reference
from .sink import ObstacleLog
from .spec import ObstacleScenario


class ObstacleStepper:
    """A controller wrapper doing the obstacle work once per control step (module docstring)."""

    def __init__(self, controller, plant, monitor, log: ObstacleLog, reference: GuidedReference | None = None,
                 guidance: Guidance | None = None):
        self.inner, self.plant, self.monitor, self.log = controller, plant, monitor, log
        self.reference, self.guidance = reference, guidance
        self.name = controller.name
        moving = any(o.moving for o in getattr(plant, "obstacles", ()))
        self._move = getattr(plant, "move_obstacles", None) if moving else None

    def reset(self) -> None:
        self.inner.reset()

    def __call__(self, t, x, ref):
        if self._move is not None:
            self._move(t)
        monitor = self.monitor
        clearance = monitor.update(t, self.plant)
        self.log.record_step(t, clearance, monitor.normal_force, monitor.in_contact)
        if self.reference is not None:
            if self.guidance is not None:
                self.guidance.update(t)
            ref[:] = self.reference.evaluate(t)
        return self.inner(t, x, ref)


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


def run_obstacle_scenario(osc: ObstacleScenario, plant_kind: str | None = None, duration: float | None = None,
                          sinks=(), contact: ContactParams = ContactParams(), controller=None,
                          show_safety: bool = True) -> ObstacleRun:
    """Run ``osc`` in closed loop with obstacles (module docstring); the plant is closed at the end."""
    sc = osc.scenario
    duration = sc.duration if duration is None else float(duration)
    kind = plant_kind or sc.plant.kind
    start_clearance = GeometricClearance(osc.obstacles, exact_within=math.inf).update(0.0, np.r_[sc.initial.eta, 0, 0, 0])
    for i in np.flatnonzero(start_clearance <= 0.0):
        raise ScenarioError(f"{sc.source}: initial.eta = {list(sc.initial.eta)} puts the hull inside obstacles[{i}] "
                            f"({osc.obstacles[i].name}, clearance {start_clearance[i]:.3f} m)")
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
        stepper = ObstacleStepper(controller or make_controller(sc), plant, monitor, log, reference, guidance)
        if plan is not None:
            for event in plan.events:
                log.add_event(event)
        record = simulate(sc, plant, stepper, sinks=[log, *sinks], duration=duration)
    finally:
        plant.close()
    record.metadata["guidance"] = {"avoid": osc.guidance.avoid, "margin_m": osc.guidance.margin_m,
                                   "plan_verified": None if plan is None else plan.verified,
                                   "plan_iterations": None if plan is None else plan.iterations,
                                   "hull_radius_m": HULL_RADIUS, "eps_m": sc.ship.eps,
                                   "contact": dataclasses.asdict(contact) if kind == "mujoco" else None}
    return ObstacleRun(record, log, plan, guidance)
