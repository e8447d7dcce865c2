"""Randomised harbour layouts for the ``harbor`` task, with their guidance plan.

A layout: start at the origin heading along +x (heading offset at most ``max_start_heading`` rad),
goal ``goal_distance`` m ahead (y offset within +-``goal_spread``); two piers (boxes 6-9 m long, 5 m
wide) leaving a gap of ``gap`` m (8-11 m) whose centre is within +-3 m of the straight line, at
x in [10, 16] m; then 3-5 buoys (circles of radius 0.4-0.8 m) in x in [0.55, 0.9] goal_distance,
|y| < 6 m, not within 4 m of the goal or of each other. The guidance is
:func:`usv_mj.references.planner.plan_reference` (visibility graph + smoothing, verified against the
funnel and ``margin_m``); a layout whose plan fails (no path, not verified) is drawn again (at most
50 times; then :class:`usv_mj.references.planner.PlanningError` propagates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PIER_WIDTH = 5.0


@dataclass
class HarbourLayout:
    """Obstacles (:class:`ObstacleSpec` tuple), start (x, y) [m], psi0 [rad], goal (x, y) [m],
    psi_goal [rad] (the planned path's heading at the goal) and the guidance ``plan``."""

    obstacles: tuple
    start: tuple
    psi0: float
    goal: tuple
    psi_goal: float
    plan: object
    draws: int = 1


def draw_obstacles(rng: np.random.RandomState, goal_distance: float):
    from usv_mj.scenario.obstacles import ObstacleSpec

    out = []
    gx = rng.uniform(10.0, 16.0)
    gap = rng.uniform(8.0, 11.0)
    gc = rng.uniform(-3.0, 3.0)
    length = rng.uniform(6.0, 9.0)
    for side, name in ((-1, "pier_south"), (1, "pier_north")):
        cy = gc + side * (0.5 * gap + 0.5 * PIER_WIDTH)
        out.append(ObstacleSpec(kind="box", center=(gx, cy), size=(length, PIER_WIDTH), name=name))
    buoys = []
    for _ in range(rng.randint(3, 6)):
        for _attempt in range(20):
            bx = rng.uniform(0.55, 0.9) * goal_distance
            by = rng.uniform(-6.0, 6.0)
            r = rng.uniform(0.4, 0.8)
            if math.hypot(bx - goal_distance, by) < 4.0 or any(math.hypot(bx - b[0], by - b[1]) < 4.0 for b in buoys):
                continue
            buoys.append((bx, by, r))
            break
    for i, (bx, by, r) in enumerate(buoys):
        out.append(ObstacleSpec(kind="circle", center=(bx, by), radius=r, name=f"buoy_{i + 1}"))
    return tuple(out)


def harbour_layout(rng: np.random.RandomState, scenario, guidance, duration: float, goal_distance: float = 40.0,
                   goal_spread: float = 3.0, max_start_heading: float = 0.2, max_draws: int = 50) -> HarbourLayout:
    """Draw layouts from ``rng`` until the guidance plans a verified reference (module docstring).

    ``scenario`` gives the funnel, eps and speed (``trajectory.speed``); ``guidance`` a
    :class:`usv_mj.scenario.obstacles.GuidanceSpec`; ``duration`` [s] the verification horizon.
    """
    from usv_mj.references.planner import PlanningError, SafetyEnvelope, plan_reference

    envelope = SafetyEnvelope.from_scenario(scenario, guidance.margin_m)
    speed = scenario.trajectory.speed
    last_error = None
    for draw in range(1, max_draws + 1):
        obstacles = draw_obstacles(rng, goal_distance)
        psi0 = rng.uniform(-max_start_heading, max_start_heading)
        goal = (goal_distance, rng.uniform(-goal_spread, goal_spread))
        start = (0.0, 0.0)
        try:
            plan = plan_reference(start, goal, obstacles, envelope, guidance, speed, duration, psi0)
        except PlanningError as exc:
            last_error = exc
            continue
        if not plan.verified:
            last_error = PlanningError(f"plan not verified (slack {np.min(plan.slack):.3f} m)")
            continue
        # heading of the planned path where it comes closest to the goal
        times = np.arange(0.0, duration, 0.1)
        pos = plan.reference.positions(times)
        i = int(np.argmin(np.hypot(pos[:, 0] - goal[0], pos[:, 1] - goal[1])))
        psi_goal = float(plan.reference.pose(float(times[i]))[2])
        return HarbourLayout(obstacles, start, float(psi0), goal, psi_goal, plan, draw)
    raise PlanningError(f"harbour_layout: no plannable layout in {max_draws} draws (last: {last_error})")
