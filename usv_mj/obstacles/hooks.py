"""The obstacles' part of a run: the static plan and the per-step hook (assembled by :func:`usv_mj.build`).

:func:`make_plan` plans the reference around the obstacles (when ``[guidance] avoid``);
:class:`ObstacleHook` is the per-step work that the loop calls before it evaluates the (guided)
reference: move the mocap obstacles to time t, measure the clearance and contacts, and let the
guidance re-time the reference.
"""

from __future__ import annotations

import math

import numpy as np

from .planner import Guidance, Plan, SafetyEnvelope, plan_reference
from .sink import ObstacleLog


class ObstacleHook:
    """The obstacle work of one control step, as a :func:`usv_mj.simulation.simulate` hook: move
    the moving obstacles to time t, measure clearance and contacts, log them, and let the guidance
    re-time or shift the reference before the loop evaluates it."""

    def __init__(self, plant, monitor, log: ObstacleLog, guidance: Guidance | None = None):
        self.monitor, self.log, self.guidance = monitor, log, guidance
        moving = any(o.moving for o in getattr(plant, "obstacles", ()))
        self._move = getattr(plant, "move_obstacles", None) if moving else None

    def kernel(self):
        """The step as a kernel of the compiled loop (:mod:`usv_mj.obstacles.native_step`), when
        the obstacles stand still and no guidance runs; None otherwise (the Python loop)."""
        from usv_mj.kernels import Kernel

        from . import native_step
        from .clearance import GeometricClearance, MuJoCoClearance

        log, monitor = self.log, self.monitor
        if self._move is not None or self.guidance is not None or any(o.moving for o in log.obstacles):
            return None
        if type(log) is not ObstacleLog:  # the kernel stores the rows as ObstacleLog.record_step does
            return None
        rows = np.zeros(1, np.int64)

        def sync():  # the rows the kernel stored count as recorded (ObstacleLog.n_rows)
            log.n_rows = max(log.n_rows, int(rows[0]))

        tail = log.kernel_state()
        if type(monitor) is MuJoCoClearance:
            return Kernel(native_step.mujoco_obstacle_step,
                          monitor.kernel_args() + tail + (native_step.CONTACT_WATCH, rows), sync)
        if type(monitor) is GeometricClearance and monitor.method != "shapely":
            return Kernel(native_step.geometric_obstacle_step, monitor.kernel_args() + tail + (rows,), sync)
        return None

    def __call__(self, t, k, plant):
        if self._move is not None:
            self._move(t)
        clearance = self.monitor.update(t, plant)
        self.log.record_step(t, clearance, self.monitor.normal_force, self.monitor.in_contact)
        if self.guidance is not None:
            self.guidance.update(t)


def make_plan(sc, duration: float | None = None) -> Plan:
    """The static plan of an obstacle scenario: start = trajectory.points[0] (waypoints) or
    trajectory.start (line), goal = the last waypoint (or 1 km along the line), speed =
    trajectory.speed, psi0 = initial heading."""
    tr = sc.trajectory
    if tr.kind == "waypoints":
        start, goal = tr.points[0], tr.points[-1]
    elif tr.kind == "line":
        h = math.radians(tr.heading_deg)
        start, goal = tr.start, (tr.start[0] + 1000.0 * math.cos(h), tr.start[1] + 1000.0 * math.sin(h))
    else:
        raise ValueError(f"guidance.avoid needs trajectory.kind = 'waypoints' or 'line' (start and goal), "
                         f"got {tr.kind!r}")
    envelope = SafetyEnvelope.from_scenario(sc, sc.guidance.margin_m)
    return plan_reference(start, goal, sc.obstacles, envelope, sc.guidance, tr.speed,
                          duration or sc.duration, sc.initial.eta[2])
