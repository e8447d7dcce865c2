"""Obstacles with real contact physics and guidance that keeps clear (issue 8).

- :mod:`.spec`: ``[[obstacles]]`` / ``[guidance]`` tables -> :class:`ObstacleSpec`, :class:`GuidanceSpec`;
  :func:`load_obstacle_scenario`.
- :mod:`.compose`: the harbour model composed with dm_control.mjcf, :class:`HarbourPlant`.
- :mod:`.clearance`: per-step signed distances and contacts (:class:`MuJoCoClearance`,
  :class:`GeometricClearance`).
- :mod:`.planner`: :func:`plan_reference` (visibility graph + smoothing, verified against the funnel),
  :class:`GuidedReference`, :class:`Guidance` (re-timing for moving obstacles), :class:`SafetyEnvelope`.
- :mod:`.sink`: :class:`ObstacleLog` (RunSink; clearance per step, events, summary).
- :mod:`.run`: :func:`run_obstacle_scenario`.
"""

from .clearance import GeometricClearance, MuJoCoClearance, make_clearance_monitor
from .compose import (HULL_RADIUS, ContactParams, HarbourPlant, compose_scene, export_scene, hull_footprint,
                      place_moving_obstacles)
from .planner import (Guidance, GuidedReference, Plan, PlanningError, SafetyEnvelope, plan_reference)
from .run import ObstacleRun, ObstacleStepper, make_plan, run_obstacle_scenario
from .sink import ObstacleLog
from .spec import (GuidanceSpec, ObstacleScenario, ObstacleSpec, from_tables, guidance_from_table,
                   load_obstacle_scenario)

__all__ = [
    "ContactParams", "GeometricClearance", "Guidance", "GuidanceSpec", "GuidedReference", "HULL_RADIUS",
    "HarbourPlant", "MuJoCoClearance", "ObstacleLog", "ObstacleRun", "ObstacleScenario", "ObstacleSpec",
    "ObstacleStepper", "Plan", "PlanningError", "SafetyEnvelope", "compose_scene", "export_scene",
    "from_tables", "guidance_from_table", "hull_footprint", "load_obstacle_scenario", "make_clearance_monitor",
    "make_plan", "place_moving_obstacles", "plan_reference", "run_obstacle_scenario",
]
