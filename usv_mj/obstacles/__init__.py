"""Obstacles with real contact physics and guidance that keeps clear.

- the ``[[obstacles]]`` / ``[guidance]`` tables are the scenario's (:mod:`usv_mj.scenario.obstacles`).
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

from usv_mj.core.lazy_names import lazy_names

__getattr__, __dir__, _ = lazy_names(__name__, {
    "GeometricClearance": ".clearance", "MuJoCoClearance": ".clearance", "make_clearance_monitor": ".clearance",
    "HULL_RADIUS": "usv_mj.scene.compose", "ContactParams": "usv_mj.scene.compose", "HarbourPlant": "usv_mj.scene.compose", "compose_scene": "usv_mj.scene.compose",
    "export_scene": "usv_mj.scene.compose", "hull_footprint": "usv_mj.scene.compose", "place_moving_obstacles": "usv_mj.scene.compose",
    "Guidance": "usv_mj.references.planner", "GuidedReference": "usv_mj.references.guided", "Plan": "usv_mj.references.planner", "PlanningError": "usv_mj.references.planner",
    "SafetyEnvelope": "usv_mj.references.planner", "plan_reference": "usv_mj.references.planner",
    "ObstacleHook": ".hooks", "make_plan": ".hooks",
    "ObstacleLog": ".sink",
    "draw_obstacles": "usv_mj.scene.display", "scene_entities": "usv_mj.scene.display", "obstacles_message": "usv_mj.scene.display",
})
__all__ = sorted(_)
