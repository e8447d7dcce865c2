"""The hull's shape as MuJoCo sees it: collision geoms read from ``models/usv.xml``, scaled to a vessel.

The one source of the hull's shape is the model file's visual geoms "hull_mid" (box) and "hull_bow"
(ellipsoid); the collision geoms copy them, slightly taller (:data:`HULL_COLLISION_GEOMS`), and a
vessel of other main dimensions gets them scaled by :func:`scale_hull` (the rule the MuJoCo plant
applies to its model at load). What the clearance monitors and the planner see of the hull (its
radius, its footprint) is made from the same geoms, so it is what MuJoCo collides.
"""

from __future__ import annotations

import math
import os
import warnings

import mujoco
import numpy as np
with warnings.catch_warnings():
    # dm_control probes GLFW at import when MUJOCO_GL is unset and warns that there is no DISPLAY;
    # mjcf needs no GL at all (rendering picks its own backend: usv_mj.outputs.render.gl_backend)
    warnings.simplefilter("ignore")
    from dm_control import mjcf

from usv_mj.support.assets import models_dir
from usv_mj.vessels import PAPER_DIMENSIONS

HULL_PATH = os.path.join(str(models_dir()), "usv.xml")

# the collision geoms copy these visual geoms of usv.xml (the one source of the hull's shape): same
# type, water-plane half-sizes and position; only the half-height is raised to COLLISION_HALF_HEIGHT
HULL_SHAPE_GEOMS = (("hull_collision_mid", "hull_mid"), ("hull_collision_bow", "hull_bow"))
COLLISION_HALF_HEIGHT = 0.15  # m: slightly taller than the visual hull (0.13 m)


def hull_collision_geoms(model_path: str = HULL_PATH) -> tuple:
    """(name, type, size (MuJoCo half-sizes), pos) in the hull's body frame for each collision geom,
    read from the visual geoms "hull_mid" (box) and "hull_bow" (ellipsoid) of the model file."""
    root = mjcf.from_path(model_path)
    out = []
    for name, visual in HULL_SHAPE_GEOMS:
        g = root.find("geom", visual)
        if g is None:
            raise ValueError(f"hull_collision_geoms: no geom {visual!r} in {model_path}")
        size = tuple(float(v) for v in g.size)
        out.append((name, g.type, (size[0], size[1], COLLISION_HALF_HEIGHT), tuple(float(v) for v in g.pos)))
    return tuple(out)


HULL_COLLISION_GEOMS = hull_collision_geoms()


def hull_radius(geoms=None) -> float:
    """Radius [m] of the smallest disc about the body origin that holds the hull's collision geoms
    (``geoms``: default :data:`HULL_COLLISION_GEOMS`) in the water plane (the paper hull's: the
    box's far corners, sqrt(0.98^2 + 0.38^2) = 1.0511 m; the ellipsoid reaches x = 1.0 m)."""
    r = 0.0
    for _, kind, size, pos in (HULL_COLLISION_GEOMS if geoms is None else geoms):
        if kind == "box":
            for sx in (-1, 1):
                for sy in (-1, 1):
                    r = max(r, math.hypot(pos[0] + sx * size[0], pos[1] + sy * size[1]))
        else:  # ellipsoid: max over the boundary (x0 + a cos t, y0 + b sin t), sampled finely
            t = np.linspace(0.0, 2.0 * math.pi, 3601)
            r = max(r, float(np.max(np.hypot(pos[0] + size[0] * np.cos(t), pos[1] + size[1] * np.sin(t)))))
    return r


HULL_RADIUS = hull_radius()


def _is_paper(dimensions) -> bool:
    ref = PAPER_DIMENSIONS
    return dimensions is None or (dimensions.L, dimensions.B, dimensions.T) == (ref.L, ref.B, ref.T)


def vessel_collision_geoms(dimensions=None) -> tuple:
    """:data:`HULL_COLLISION_GEOMS` of a vessel of main ``dimensions`` (usv_mj.vessels.Dimensions):
    scaled by :func:`scale_hull` (the one rule: the MuJoCo plant scales these geoms so at load), so what the analytic plant's clearance and the
    planner see is what MuJoCo collides. None or the paper's: the constant itself."""
    if _is_paper(dimensions):
        return HULL_COLLISION_GEOMS
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="hull")
    types = {"box": mujoco.mjtGeom.mjGEOM_BOX, "ellipsoid": mujoco.mjtGeom.mjGEOM_ELLIPSOID}
    for name, kind, size, pos in HULL_COLLISION_GEOMS:
        body.add_geom(name=name, type=types[kind], size=list(size), pos=list(pos))
    scale_hull(spec, dimensions)
    return tuple((name, kind, tuple(float(v) for v in g.size), tuple(float(v) for v in g.pos))
                 for (name, kind, _, _), g in zip(HULL_COLLISION_GEOMS, body.geoms))


def vessel_hull_radius(dimensions=None) -> float:
    """:func:`hull_radius` of the vessel's collision geoms (:func:`vessel_collision_geoms`);
    :data:`HULL_RADIUS` itself for the paper hull."""
    return HULL_RADIUS if _is_paper(dimensions) else hull_radius(vessel_collision_geoms(dimensions))


def hull_footprint(resolution: int = 32, geoms=None):
    """The hull's collision geoms (``geoms``: default :data:`HULL_COLLISION_GEOMS`; a vessel's:
    :func:`vessel_collision_geoms`) as one shapely polygon in the body frame (water-plane section).

    The ellipsoid is a polygon inscribed with ``4*resolution`` vertices (so distances computed
    with it can be larger than MuJoCo's by at most a(1 - cos(pi/(4 resolution))): 0.7 mm at 16)."""
    import shapely

    parts = []
    for _, kind, size, pos in (HULL_COLLISION_GEOMS if geoms is None else geoms):
        if kind == "box":
            parts.append(shapely.box(pos[0] - size[0], pos[1] - size[1], pos[0] + size[0], pos[1] + size[1]))
        else:
            t = np.linspace(0.0, 2.0 * math.pi, 4 * resolution, endpoint=False)
            parts.append(shapely.Polygon(np.c_[pos[0] + size[0] * np.cos(t), pos[1] + size[1] * np.sin(t)]))
    return shapely.union_all(parts)


def scale_hull(spec, dimensions) -> None:
    """Scale body "hull" of ``spec`` (its geoms, sites and cameras, children included) from the
    model file's hull (:data:`usv_mj.vessels.PAPER_DIMENSIONS`: L, B, T) to ``dimensions``: positions
    and box/ellipsoid half-sizes by (L, B, T) ratios, radii by the smaller ratio of their section,
    cameras uniformly by the length ratio. The geoms have no mass (the inertial is set from the
    vessel), so only what is drawn and what collides changes. None or the file's own: unchanged."""
    ref = PAPER_DIMENSIONS
    if dimensions is None or (dimensions.L, dimensions.B, dimensions.T) == (ref.L, ref.B, ref.T):
        return
    k = np.array([dimensions.L / ref.L, dimensions.B / ref.B, dimensions.T / ref.T])
    hull = spec.body("hull")
    if hull is None:
        return
    stack = [hull]
    while stack:
        body = stack.pop()
        stack.extend(body.bodies)
        for g in body.geoms:
            g.pos = np.asarray(g.pos) * k
            if not math.isnan(g.fromto[0]):
                g.fromto = np.asarray(g.fromto) * np.r_[k, k]
            size = np.array(g.size, dtype=float)
            if g.type in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
                size = size * k
            elif g.type in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
                size[0] *= min(k[0], k[1], k[2])
                size[1] *= k[2]
            elif g.type == mujoco.mjtGeom.mjGEOM_SPHERE:
                size[0] *= min(k)
            g.size = size
        for site in body.sites:
            site.pos = np.asarray(site.pos) * k
        for cam in body.cameras:
            cam.pos = np.asarray(cam.pos) * k[0]
