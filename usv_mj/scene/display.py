"""What the figures, the video and the MCAP log need to show obstacles, as plain data.

- :func:`draw_obstacles`: matplotlib patches for the trajectory figure: each obstacle filled, its
  inflated safety boundary (obstacle grown by the plan's inflation) dashed.
- :func:`scene_entities`: ``foxglove.SceneEntity`` dicts (the layout of
  :func:`usv_mj.outputs.log.messages._scene`): a cube per box, a cylinder per circle, a LINE_LOOP per
  inflated boundary, in frame "map" (REP-105: the run log's world frame), for a
  ``foxglove.SceneUpdate`` on ``P/scene/obstacles``.
- :func:`obstacles_message`: everything about the obstacles at one logged row as plain data
  (:meth:`usv_mj.obstacles.sink.ObstacleLog.frame`). The ``/usv/obstacles`` MCAP topic itself is
  laid out in bulk by :mod:`usv_mj.outputs.log.extra_topics` (t; per obstacle name, clearance_m,
  normal_force_N, center {x, y}; the fixed shapes go in the run's metadata).

The MuJoCo video needs nothing from here: the composed model (:func:`usv_mj.scene.compose.compose_scene`)
already contains the obstacle geoms (group 0), moving ones as mocap bodies (place them per frame
with :func:`usv_mj.scene.compose.place_moving_obstacles`), and the inflated boundaries as flat
visual geoms (group 2) when ``safety_radii`` is given.
"""

from __future__ import annotations

import math

import numpy as np

from usv_mj.scenario.obstacles import OBSTACLE_COLORS, OBSTACLE_HALF_HEIGHT


def inflation_of(inflation, i: int) -> float:
    """The safety-boundary distance [m] of obstacle i from a per-obstacle list (None, NaN or a missing
    entry: 0, nothing drawn; e.g. moving obstacles, whose boundary the static plan does not give)."""
    if inflation is None or i >= len(inflation) or inflation[i] is None:
        return 0.0
    v = float(inflation[i])
    return v if math.isfinite(v) else 0.0


def boundary_points(obstacle, inflation: float, t: float = 0.0, n: int = 64) -> np.ndarray:
    """Closed outline [m] of the obstacle grown by ``inflation`` at time t, shape (k, 2)."""
    grown = obstacle.shape(t).buffer(inflation, quad_segs=max(n // 4, 2))
    return np.asarray(grown.exterior.coords)


def draw_obstacles(ax, obstacles, inflation=None, t: float = 0.0, label: bool = True):
    """Draw the obstacles at time t on a matplotlib axis (x east, y north, equal aspect)."""
    from matplotlib.patches import Polygon as PolygonPatch

    for i, o in enumerate(obstacles):
        color = OBSTACLE_COLORS["moving" if o.moving else o.kind]
        outline = np.asarray(o.shape(t).exterior.coords)
        ax.add_patch(PolygonPatch(outline, closed=True, facecolor=color[:3], edgecolor="k", linewidth=0.6,
                                  alpha=0.85, zorder=3))
        grow = inflation_of(inflation, i)
        if grow > 0:
            b = boundary_points(o, grow, t)
            ax.plot(b[:, 0], b[:, 1], "--", color=(0.85, 0.65, 0.0), linewidth=0.8, zorder=2,
                    label="inflated boundary" if label and i == 0 else None)
        if label:
            cx, cy = o.center_at(t)
            ax.annotate(o.name, (cx, cy), fontsize=6, ha="center", va="center", zorder=4)


def _pose(x, y, yaw):
    return {"position": {"x": float(x), "y": float(y), "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}}


def _color(rgba):
    return {"r": rgba[0], "g": rgba[1], "b": rgba[2], "a": rgba[3]}


def scene_entities(obstacles, t: float, stamp: dict, inflation=None) -> list[dict]:
    """``foxglove.SceneEntity`` dicts for the obstacles at time t (``stamp`` = {"sec", "nsec"})."""
    out = []
    for i, o in enumerate(obstacles):
        cx, cy = o.center_at(t)
        color = _color(OBSTACLE_COLORS["moving" if o.moving else o.kind])
        cubes, cylinders, lines = [], [], []
        if o.kind == "box":
            cubes.append({"pose": _pose(cx, cy, o.yaw), "size": {"x": o.size[0], "y": o.size[1],
                                                                  "z": 2 * OBSTACLE_HALF_HEIGHT}, "color": color})
        else:
            d = 2 * o.radius
            cylinders.append({"pose": _pose(cx, cy, 0.0), "size": {"x": d, "y": d, "z": 2 * OBSTACLE_HALF_HEIGHT},
                              "bottom_scale": 1.0, "top_scale": 1.0, "color": color})
        grow = inflation_of(inflation, i)
        if grow > 0:
            pts = boundary_points(o, grow, t)[:-1]
            lines.append({"type": 1, "pose": _pose(0.0, 0.0, 0.0), "thickness": 0.05, "scale_invariant": False,
                          "points": [{"x": float(px), "y": float(py), "z": 0.02} for px, py in pts],
                          "color": _color((1.0, 0.8, 0.1, 0.9)), "colors": [], "indices": []})
        out.append({"timestamp": stamp, "frame_id": "map", "id": f"obstacle/{o.name}",
                    "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
                    "metadata": [{"key": "kind", "value": o.kind}, {"key": "moving", "value": str(o.moving).lower()}],
                    "arrows": [], "cubes": cubes, "spheres": [], "cylinders": cylinders, "lines": lines,
                    "triangles": [], "texts": [], "models": []})
    return out


def obstacles_message(log, k: int) -> dict:
    """The ``/usv/obstacles`` message of row k: {"t", "obstacles": [{name, kind, center, radius, size,
    yaw, moving, inflation_m, clearance_m, normal_force_N}, ...]} (JSON-ready)."""
    return log.frame(k)
