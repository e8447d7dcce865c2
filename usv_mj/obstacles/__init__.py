"""Obstacles: what a run measures of them and logs, step by step.

- :mod:`.clearance`: per-step signed distances and contacts (:class:`MuJoCoClearance` on the MuJoCo
  plant, :class:`GeometricClearance` from the footprint); :mod:`.broad_phase`, :mod:`.footprint_kernels`;
- :mod:`.sink`: :class:`ObstacleLog` (a run sink: clearance per step, events, summary);
- :mod:`.hooks`: :func:`make_plan`, :class:`ObstacleHook` (assembled into a run by :func:`usv_mj.build`);
  :mod:`.native_step`: the hook's step as a kernel of the compiled loop.

Elsewhere: the ``[[obstacles]]`` / ``[guidance]`` tables are the scenario's
(:mod:`usv_mj.scenario.obstacles`); the harbour's MJCF is the scene's (:mod:`usv_mj.scene.compose`,
the hull's shape :mod:`usv_mj.scene.hull`, the display data :mod:`usv_mj.scene.display`); the plant
on it is :class:`usv_mj.plants.harbour.HarbourPlant`; the guidance around obstacles is a reference
(:mod:`usv_mj.references.planner`, :mod:`usv_mj.references.guided`).

Names are imported lazily, so that importing the package does not pull in MuJoCo, dm_control,
shapely or networkx.
"""

from __future__ import annotations

from usv_mj.core.lazy_names import lazy_names

__getattr__, __dir__, _ = lazy_names(__name__, {
    "GeometricClearance": ".clearance", "MuJoCoClearance": ".clearance", "make_clearance_monitor": ".clearance",
    "ObstacleHook": ".hooks", "make_plan": ".hooks",
    "ObstacleLog": ".sink",
})
__all__ = sorted(_)
