"""The harbour model, composed with ``dm_control.mjcf``: scene + hull + obstacles.

:func:`compose_scene` parses ``models/scene.xml`` (which includes ``models/usv.xml``) with
``dm_control.mjcf`` and adds, in Python and never by pasting XML text,

- collision geoms on the body "hull" that follow its shape (:data:`HULL_COLLISION_GEOMS`, read from
  ``usv.xml`` by :func:`hull_collision_geoms`, never restated): the box
  of the midship/stern section and the ellipsoid of the bow of ``usv.xml``'s visual hull, slightly
  taller; they have no mass (the plant sets the inertia from :mod:`usv_mj.physics.ship`);
- one geom per obstacle: a vertical cylinder ("circle") or box ("box") from z = -1 m to
  z = +1 m (the hull is at the waterline z = 0); static obstacles are geoms of the world body,
  moving ones are mocap bodies (``mocap_pos`` is set by :meth:`HarbourPlant.move_obstacles`);
- optionally, visual-only translucent discs/rounded rectangles showing each obstacle's inflated
  safety boundary (see :mod:`usv_mj.references.planner`);
- optionally, a fan of MuJoCo ``rangefinder`` sensors on the hull (``rangefinders``: body-frame
  ray angles [rad], 0 = bow, counter-clockwise): sites ``range_i`` at the hull origin,
  :data:`RANGEFINDER_HEIGHT` above the waterline, rays horizontal (the harbor task's sensors);
- ``<option><flag contact="enable" constraint="enable"/>``: ``usv.xml`` disables both (open water
  needs neither); here the hull must be stopped by a contact force;
- ``<flag sleep="enable"/>`` and ``<body name="hull" sleep="never">``: MuJoCo's sleeping with the
  hull never asleep. The hull's dynamics do not change (its tree is always awake; tested bit for
  bit), but MuJoCo then skips static bodies in ``mj_kinematics`` (google-deepmind/mujoco#3540,
  fixed by #3541), so the poses of the standing obstacles (geoms of the world body) are computed
  once instead of in each of the four RK4 stages of every step: at 1000 standing circles
  ``mj_kinematics`` measured 4.9 -> 0.3 us and ``mj_step`` about 31 -> 10 us (README obstacle table).

Collision filtering: hull geoms have contype = 1, conaffinity = 2; obstacles contype = 2,
conaffinity = 1, so the hull collides with obstacles and obstacles never with each other (a
crossing boat passes through a buoy); the visual geoms of usv.xml and the water have 0/0.

Contact parameters (:class:`ContactParams`, on both sides of every hull/obstacle pair): friction,
``solref`` (time constant [s], damping ratio) and ``solimp`` (MuJoCo's impedance curve). The
defaults are a firm, well-damped fendered pier: a few centimetres of penetration under the full
thrust of the PPC law, no bounce that looks like rubber.
"""

from __future__ import annotations

import warnings

import math
import os
import tempfile
from dataclasses import dataclass

import mujoco
import numpy as np
with warnings.catch_warnings():
    # dm_control probes GLFW at import when MUJOCO_GL is unset and warns that there is no DISPLAY;
    # mjcf needs no GL at all (rendering picks its own backend: usv_mj.outputs.render.gl_backend)
    warnings.simplefilter("ignore")
    from dm_control import mjcf

from usv_mj.scenario.obstacles import OBSTACLE_COLORS, OBSTACLE_HALF_HEIGHT, ObstacleSpec
from usv_mj.scene.hull import HULL_COLLISION_GEOMS
from usv_mj.support.assets import models_dir

SCENE_PATH = os.path.join(str(models_dir()), "scene.xml")
RANGEFINDER_HEIGHT = 0.3  # m above the waterline: rays at this height hit only the obstacles
HULL_CONTYPE, HULL_CONAFFINITY = 1, 2
OBSTACLE_CONTYPE, OBSTACLE_CONAFFINITY = 2, 1


@dataclass(frozen=True)
class ContactParams:
    """Hull/obstacle contact: ``friction`` (sliding, torsional, rolling), ``solref`` = (time
    constant [s], damping ratio), ``solimp`` = (d0, d_width, width [m], midpoint, power), ``condim``.

    ``solref[0]`` must be at least twice the MuJoCo time step (MuJoCo's own rule for stability)."""

    friction: tuple[float, float, float] = (0.4, 0.005, 0.0001)
    solref: tuple[float, float] = (0.02, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.01, 0.5, 2.0)
    condim: int = 3

    def __post_init__(self) -> None:
        if not all(math.isfinite(f) and f >= 0 for f in self.friction) or len(self.friction) != 3:
            raise ValueError(f"ContactParams.friction must be 3 finite numbers >= 0, got {self.friction!r}")
        if len(self.solref) != 2 or not all(math.isfinite(v) and v > 0 for v in self.solref):
            raise ValueError(f"ContactParams.solref must be 2 finite numbers > 0, got {self.solref!r}")
        if len(self.solimp) != 5 or not (0 < self.solimp[0] < 1 and 0 < self.solimp[1] < 1 and self.solimp[2] > 0):
            raise ValueError(f"ContactParams.solimp must be (d0, d_width in (0, 1), width > 0, midpoint, power), "
                             f"got {self.solimp!r}")
        if self.condim not in (1, 3, 4, 6):
            raise ValueError(f"ContactParams.condim must be 1, 3, 4 or 6, got {self.condim!r}")


SAFETY_COLOR = (0.22, 0.47, 0.60, 1.0)  # opaque tint just above the water: overlapping pieces do not show


def obstacle_geom_name(obstacle: ObstacleSpec) -> str:
    return f"obstacle_{obstacle.name}" if not obstacle.name.startswith("obstacle_") else obstacle.name


def compose_scene(obstacles=(), contact: ContactParams = ContactParams(), safety_radii=None,
                  scene_path: str = SCENE_PATH, rangefinders=()) -> mjcf.RootElement:
    """The composed MJCF model (see the module docstring).

    ``safety_radii``: optional inflation [m] per obstacle (e.g. :meth:`Plan.inflation`): adds a
    visual-only translucent boundary at that distance around each static obstacle.
    ``rangefinders``: body-frame angles [rad] of horizontal rangefinder rays from the hull origin
    (sites and sensors ``range_i``; MuJoCo's rangefinder excludes the site's own body, so the hull
    never sees itself).
    """
    root = mjcf.from_path(scene_path)
    root.model = "usv harbour"
    root.option.flag.contact = "enable"
    root.option.flag.constraint = "enable"
    hull = root.find("body", "hull")
    if hull is None:
        raise ValueError(f"compose_scene: no body 'hull' in {scene_path}")
    # MuJoCo's sleeping, with the hull's tree never asleep: the dynamics are those without it (bit
    # for bit), but mj_kinematics skips the static bodies, so the standing obstacles' poses are
    # computed once, not in each of RK4's four stages of every step (STANDING_POSES_ONCE)
    root.option.flag.sleep = "enable"
    hull.sleep = "never"
    common = dict(friction=list(contact.friction), solref=list(contact.solref), solimp=list(contact.solimp),
                  condim=contact.condim)
    for name, kind, size, pos in HULL_COLLISION_GEOMS:
        hull.add("geom", name=name, type=kind, size=list(size), pos=list(pos), contype=HULL_CONTYPE,
                 conaffinity=HULL_CONAFFINITY, group=3, mass=0, density=0, rgba=[1, 0.2, 0.2, 0.35], **common)
    # a wider view of the harbour for the fixed camera
    for i, obstacle in enumerate(obstacles):
        name = obstacle_geom_name(obstacle)
        if obstacle.kind == "circle":
            shape = dict(type="cylinder", size=[obstacle.radius, OBSTACLE_HALF_HEIGHT])
        else:
            shape = dict(type="box", size=[0.5 * obstacle.size[0], 0.5 * obstacle.size[1], OBSTACLE_HALF_HEIGHT])
        color = OBSTACLE_COLORS["moving" if obstacle.moving else obstacle.kind]
        quat = [math.cos(obstacle.yaw / 2), 0.0, 0.0, math.sin(obstacle.yaw / 2)]
        geom = dict(name=name, contype=OBSTACLE_CONTYPE, conaffinity=OBSTACLE_CONAFFINITY, rgba=list(color),
                    group=0, **shape, **common)
        if obstacle.moving:
            body = root.worldbody.add("body", name=f"{name}_body", mocap=True,
                                      pos=[obstacle.center[0], obstacle.center[1], 0.0], quat=quat)
            body.add("geom", **geom)
        else:
            root.worldbody.add("geom", pos=[obstacle.center[0], obstacle.center[1], 0.0], quat=quat, **geom)
            if safety_radii is not None and safety_radii[i] > 0:
                _add_safety_boundary(root.worldbody, obstacle, float(safety_radii[i]), name)
    for i, a in enumerate(np.asarray(rangefinders, dtype=float).reshape(-1)):
        site = hull.add("site", name=f"range_{i}", pos=[0.0, 0.0, RANGEFINDER_HEIGHT],
                        zaxis=[math.cos(a), math.sin(a), 0.0], size=[0.02], group=4)
        root.sensor.add("rangefinder", name=f"range_{i}", site=site)
    return root


def _add_safety_boundary(parent, obstacle: ObstacleSpec, inflation: float, name: str) -> None:
    """Visual-only flat geoms at z = 0.01 m: the obstacle grown by ``inflation`` (Minkowski sum with
    a disc: a disc, or a rounded rectangle made of two boxes and four corner discs)."""
    vis = dict(contype=0, conaffinity=0, group=2, rgba=list(SAFETY_COLOR), mass=0)
    cx, cy = obstacle.center
    h = 0.005
    if obstacle.kind == "circle":
        parent.add("geom", name=f"{name}_safety", type="cylinder", size=[obstacle.radius + inflation, h],
                   pos=[cx, cy, 0.01], **vis)
        return
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    quat = [math.cos(obstacle.yaw / 2), 0.0, 0.0, math.sin(obstacle.yaw / 2)]
    hl, hw = 0.5 * obstacle.size[0], 0.5 * obstacle.size[1]
    parent.add("geom", name=f"{name}_safety_x", type="box", size=[hl + inflation, hw, h], pos=[cx, cy, 0.01],
               quat=quat, **vis)
    parent.add("geom", name=f"{name}_safety_y", type="box", size=[hl, hw + inflation, h], pos=[cx, cy, 0.01],
               quat=quat, **vis)
    for k, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        px, py = sx * hl, sy * hw
        parent.add("geom", name=f"{name}_safety_c{k}", type="cylinder", size=[inflation, h],
                   pos=[cx + c * px - s * py, cy + s * px + c * py, 0.01], **vis)


def place_moving_obstacles(model: mujoco.MjModel, data: mujoco.MjData, obstacles, t: float) -> None:
    """Set the mocap pose of every moving obstacle of a model made by :func:`compose_scene` (or any
    model holding its bodies, e.g. a renderer's copy) to its position at time t [s]."""
    for o in obstacles:
        if not o.moving:
            continue
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{obstacle_geom_name(o)}_body")
        if body < 0 or model.body_mocapid[body] < 0:
            raise ValueError(f"place_moving_obstacles: no mocap body for the moving obstacle {o.name!r} in the model")
        cx, cy = o.center_at(t)
        data.mocap_pos[model.body_mocapid[body], :2] = (cx, cy)


def export_scene(root: mjcf.RootElement, directory: str | None = None) -> str:
    """Write the composed model (and any assets) to ``directory`` (a new temporary one by default);
    return the XML file's path."""
    directory = directory or tempfile.mkdtemp(prefix="usv_mj_harbour_")
    mjcf.export_with_assets(root, directory, "harbour.xml")
    return os.path.join(directory, "harbour.xml")
