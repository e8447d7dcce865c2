"""The obstacles' part of a run: the static plan and the per-step hook (assembled by :func:`usv_mj.build`).

:func:`make_plan` plans the reference around the obstacles (when ``[guidance] avoid``);
:class:`ObstacleHook` is the per-step work that the loop calls before it evaluates the (guided)
reference: move the mocap obstacles to time t, measure the clearance and contacts, and let the
guidance re-time the reference.
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from usv_mj.references.planner import Guidance, Plan, SafetyEnvelope, plan_reference
from usv_mj.obstacles.sink import ObstacleLog


class ObstacleHook:
    """The obstacle work of one control step, as a :func:`usv_mj.loop.simulate.simulate` hook: move
    the moving obstacles to time t, measure clearance and contacts, log them, and let the guidance
    re-time or shift the reference before the loop evaluates it."""

    def __init__(self, plant, monitor, log: ObstacleLog, guidance: Guidance | None = None):
        self.monitor, self.log, self.guidance = monitor, log, guidance
        moving = any(o.moving for o in getattr(plant, "obstacles", ()))
        self._move = getattr(plant, "move_obstacles", None) if moving else None

    def kernel(self):
        """The step as a kernel of the compiled loop (:mod:`usv_mj.obstacles.native_step`), when
        the obstacles stand still and no guidance runs; None otherwise (the Python loop)."""
        from usv_mj.core.kernels import Kernel

        from usv_mj.obstacles import native_step
        from usv_mj.obstacles.clearance import GeometricClearance, MuJoCoClearance

        log, monitor = self.log, self.monitor
        if self._move is not None or self.guidance is not None or any(o.moving for o in log.obstacles):
            return None
        if type(log) is not ObstacleLog:  # the kernel stores the rows as ObstacleLog.record_step does
            return None
        rows = log.kernel_rows

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


#: how many plans :func:`make_plan` keeps (a job asks for one plan three times: the input check,
#: the build and the half-step check's build; a sweep's worker, for one plan per scenario)
PLAN_CACHE_SIZE = 4
_plans: OrderedDict[str, Plan] = OrderedDict()


def plan_inputs(sc, duration: float | None = None) -> tuple:
    """Everything :func:`plan_reference` reads from ``sc``: (start, goal, envelope, duration), and
    the cache key of :func:`make_plan` is the repr of these and of the obstacles and guidance (the
    floats' repr is exact, so two scenarios share a plan only when every input is equal)."""
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
    return start, goal, envelope, float(duration or sc.duration)


def make_plan(sc, duration: float | None = None) -> Plan:
    """The static plan of an obstacle scenario: start = trajectory.points[0] (waypoints) or
    trajectory.start (line), goal = the last waypoint (or 1 km along the line), speed =
    trajectory.speed, psi0 = initial heading, verified over ``duration`` [s] (default the scenario's).

    Planned once per content: the last :data:`PLAN_CACHE_SIZE` plans are kept, keyed by every
    input (:func:`plan_inputs`), and each call gets the plan with a reference of its own
    (:meth:`Plan.fresh`), so a changed scenario is planned again and no run sees another's
    re-timing."""
    start, goal, envelope, horizon = plan_inputs(sc, duration)
    f = sc.funnel
    key = repr((tuple(start), tuple(goal), tuple(sc.obstacles), sc.guidance, (f.rho_xy[0], f.rho_xy[1], f.rate),
                envelope.eps, envelope.hull_radius, envelope.margin, sc.trajectory.speed, horizon,
                float(sc.initial.eta[2])))
    plan = _plans.get(key)
    if plan is None:
        plan = plan_reference(start, goal, sc.obstacles, envelope, sc.guidance, sc.trajectory.speed, horizon,
                              sc.initial.eta[2])
        _plans[key] = plan
        while len(_plans) > PLAN_CACHE_SIZE:
            _plans.popitem(last=False)
    _plans.move_to_end(key)
    return plan.fresh()
