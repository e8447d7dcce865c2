"""Obstacles with real contact physics and guidance that keeps clear.

- the ``[[obstacles]]`` / ``[guidance]`` tables are the scenario's (:mod:`usv_mj.obstacle_tables`).
- :mod:`.compose`: the harbour model composed with dm_control.mjcf, :class:`HarbourPlant`.
- :mod:`.clearance`: per-step signed distances and contacts (:class:`MuJoCoClearance`,
  :class:`GeometricClearance`).
- :mod:`.planner`: :func:`plan_reference` (visibility graph + smoothing, verified against the funnel),
  :class:`GuidedReference`, :class:`Guidance` (re-timing / detours for moving obstacles), :class:`SafetyEnvelope`.
- :mod:`.sink`: :class:`ObstacleLog` (RunSink; clearance per step, events, summary).
- :mod:`.display`: obstacles for figures, Foxglove scenes and the ``/usv/obstacles`` topic.
- :mod:`.hooks`: :func:`make_plan`, :class:`ObstacleHook` (assembled into a run by :func:`usv_mj.build`).

Names are imported lazily, so that importing the package does not pull in
MuJoCo, dm_control, shapely or networkx.
"""

from __future__ import annotations

from usv_mj.lazy_names import lazy_names

__getattr__, __dir__, _ = lazy_names(__name__, {
    "GeometricClearance": ".clearance", "MuJoCoClearance": ".clearance", "make_clearance_monitor": ".clearance",
    "HULL_RADIUS": ".compose", "ContactParams": ".compose", "HarbourPlant": ".compose", "compose_scene": ".compose",
    "export_scene": ".compose", "hull_footprint": ".compose", "place_moving_obstacles": ".compose",
    "Guidance": ".planner", "GuidedReference": ".guided", "Plan": ".planner", "PlanningError": ".planner",
    "SafetyEnvelope": ".planner", "plan_reference": ".planner",
    "ObstacleHook": ".hooks", "make_plan": ".hooks",
    "ObstacleLog": ".sink",
    "draw_obstacles": ".display", "scene_entities": ".display", "obstacles_message": ".display",
})
__all__ = sorted(_)
