"""Replaying a finished run in MuJoCo's renderer: one frame = set qpos, ``mj_forward``, draw.

No plant and no simulation: the hull's joints ``x``, ``y``, ``yaw`` of ``models/scene.xml`` are set
from the recorded (x, y, psi) [m, m, rad] columns of a :class:`~usv_mj.record.run_record.RunRecord`, and the
picture is completed with

- a *ghost hull* at the reference pose (x_d, y_d, psi_d): a semi-transparent copy of the hull's
  geoms on a mocap body ``ghost`` that is added to the model at load time with :class:`mujoco.MjSpec`
  (``models/`` is not edited);
- the *wake trail*: line segments through the hull's recent positions, fading with age;
- the *reference path ahead*: line segments through the upcoming (x_d, y_d);
- the *prescribed-performance funnel* (docs/model.md §3 step 4, Eq. 9): the rectangle |e1| < rho1, |e2| < rho2
  around the reference point, drawn as a translucent slab with an outline, green while both errors
  are inside and red when one is not. The funnel is centred on the Do & Pan point
  x_bar_d = x_d + eps cos psi_d, y_bar_d = y_d + eps sin psi_d when eps = m23/m22 is known from the
  record's metadata, else on (x_d, y_d) (eps = 0.03 m for the paper's ship: under a pixel).

These extra shapes are user geoms appended to ``renderer.scene`` after ``update_scene``
(``mjv_initGeom`` + ``mjv_connector``, ``mjGEOM_LINE``), so they cost no physics and no model change.

Cameras: ``"top"`` is a free camera looking straight down (image right = world +x, image up = world
+y) whose look-at point and distance follow a :class:`TopView` (centre [m], half-height of the visible
water [m]) computed per frame by the planner to keep ship, reference and funnel in view; any other
name is a camera of the model (``"chase"`` rides behind the hull, ``"overview"`` is fixed, ``"chart"``
is fixed straight down over the origin, image right = east, image up = north).

Speed (docs/model.md §1: shadows and multisampling dominate on Mesa's software rasteriser): shadows and
reflections are off and multisampling is reduced unless asked for.

This module imports mujoco: import it only in a process whose ``MUJOCO_GL`` is already chosen
(:mod:`usv_mj.outputs.render.gl_backend`).
"""

from __future__ import annotations

import atexit
import math
import os
import weakref
from pathlib import Path

import numpy as np

import mujoco

from usv_mj.outputs.render.planner import (FUNNEL_BAD_RGBA, FUNNEL_FILL_ALPHA, FUNNEL_OK_RGBA, GHOST_RGBA, LAYERS, PATH_RGBA,
                      SAFETY_LINE_RGBA, TRAIL_RGBA, FrameSpec, TopView)
from usv_mj.support.assets import models_dir

REPO_MODELS = models_dir()
DEFAULT_SCENE = REPO_MODELS / "scene.xml"

#: A small stand-in scene with the same contract as models/scene.xml (hull on joints x, y, yaw;
#: cameras chase, top and chart; a textured water plane at z = 0). Used only when no scene file is found.
STANDIN_SCENE_XML = """
<mujoco model="usv stand-in scene">
  <compiler angle="radian"/>
  <option gravity="0 0 0"/>
  <visual><global offwidth="1280" offheight="720"/><quality shadowsize="1024"/></visual>
  <asset>
    <texture type="skybox" builtin="gradient" rgb1="0.55 0.72 0.90" rgb2="0.12 0.25 0.45" width="64" height="384"/>
    <texture name="water" type="2d" builtin="checker" rgb1="0.08 0.28 0.46" rgb2="0.11 0.34 0.54"
             mark="edge" markrgb="0.35 0.55 0.72" width="512" height="512"/>
    <material name="water" texture="water" texrepeat="1 1" texuniform="true"/>
  </asset>
  <worldbody>
    <light directional="true" pos="0 0 50" dir="-0.3 0.2 -1"/>
    <geom name="water" type="plane" size="500 500 0.5" material="water" contype="0" conaffinity="0"/>
    <body name="hull">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="yaw" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="141.85" diaginertia="5 12 15.6"/>
      <geom name="hull_mid" type="box" size="0.70 0.38 0.13" pos="-0.28 0 0.03" rgba="0.93 0.93 0.9 1"
            contype="0" conaffinity="0" group="1"/>
      <geom name="hull_bow" type="ellipsoid" size="0.58 0.38 0.13" pos="0.42 0 0.03" rgba="0.93 0.93 0.9 1"
            contype="0" conaffinity="0" group="1"/>
      <geom name="cabin" type="box" size="0.26 0.24 0.11" pos="-0.20 0 0.28" rgba="0.8 0.2 0.1 1"
            contype="0" conaffinity="0" group="1"/>
      <camera name="chase" pos="-5.0 0 2.2" xyaxes="0 -1 0 0.40 0 0.92" fovy="50"/>
      <camera name="top" mode="trackcom" pos="0 0 25" xyaxes="1 0 0 0 1 0" fovy="45"/>
    </body>
    <camera name="chart" pos="0 0 40" xyaxes="1 0 0 0 1 0" fovy="45"/>
  </worldbody>
</mujoco>
"""


#: Renderers still open; closed at exit, because an EGL context freed during interpreter shutdown
#: (by the Renderer's __del__, after mujoco.egl's own atexit eglTerminate) prints EGLError
#: tracebacks. The handler is registered after the first context exists, so it runs before
#: eglTerminate (atexit runs last-registered first).
_OPEN: "weakref.WeakSet[FrameRenderer]" = weakref.WeakSet()
_atexit_registered = False


def _close_open_renderers() -> None:
    """At exit: free every renderer still open, each in its own GL context. Nothing may escape:
    an error here would be printed as "Exception ignored in atexit callback" (issue 28), and a
    context that cannot be freed any more costs nothing in a process that is ending (a worker
    terminated by its pool while it exits, say)."""
    for r in list(_OPEN):
        try:
            r.close()
        except BaseException:  # noqa: BLE001 - see the docstring
            pass


def load_scene_spec(model_path: str | os.PathLike | None = None) -> tuple[mujoco.MjSpec, str]:
    """The scene as an MjSpec, and a label saying where it came from.

    ``model_path`` None means ``models/scene.xml`` of this repository, or the built-in stand-in when
    that file is absent (an installed package without the models directory).
    """
    if model_path is None:
        if DEFAULT_SCENE.is_file():
            return mujoco.MjSpec.from_file(str(DEFAULT_SCENE)), str(DEFAULT_SCENE)
        return mujoco.MjSpec.from_string(STANDIN_SCENE_XML), "built-in stand-in scene"
    path = Path(model_path)
    if not path.is_file():
        raise FileNotFoundError(f"render model {str(path)!r} does not exist")
    return mujoco.MjSpec.from_file(str(path)), str(path)


GHOST_MAX_GEOMS = 6


def _hull_geoms_in_hull_frame(model: mujoco.MjModel, hull_id: int) -> list[dict]:
    """Every visible geom of the hull's subtree, with its pose relative to the hull body frame."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    r_hull = data.xmat[hull_id].reshape(3, 3)
    p_hull = data.xpos[hull_id]
    subtree = {hull_id}
    for b in range(model.nbody):
        if model.body_parentid[b] in subtree and b != 0:
            subtree.add(b)
    out = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] not in subtree or model.geom_group[g] > 2 or model.geom_rgba[g, 3] == 0:
            continue
        r_g = data.geom_xmat[g].reshape(3, 3)
        rel_r = r_hull.T @ r_g
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rel_r.ravel())
        out.append({
            "type": int(model.geom_type[g]), "size": model.geom_size[g].copy(),
            "pos": r_hull.T @ (data.geom_xpos[g] - p_hull), "quat": quat,
            "mesh": model.mesh(model.geom_dataid[g]).name if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH else "",
            "rbound": float(model.geom_rbound[g]),
        })
    return out


SEA_HFIELD, SEA_GEOM = "usv_mj_sea", "usv_mj_sea_surface"
SEA_RGBA = (0.16, 0.42, 0.62, 1.0)     # the wave surface (lit: crests and troughs show by their shading)
SEA_MAX_HALF = 320.0                  # m: compiled half-size of the hfield (bounds for MuJoCo's queries)


def _names_of(m) -> list:
    """"top" first, then the model's cameras, each once (the model has a camera named "top" too)."""
    return list(dict.fromkeys(["top"] + [m.camera(i).name for i in range(m.ncam)]))


def camera_names(model_path=None) -> list:
    """The cameras a video can use with this render model: "top" (the free camera) and the model's."""
    m, _ = build_replay_model(model_path, width=64, height=64, ghost=True)
    return _names_of(m)


def build_replay_model(model_path=None, *, width: int = 1280, height: int = 720, ghost: bool = True,
                       samples: int = 0, sea: bool = True, hull=None) -> tuple[mujoco.MjModel, str]:
    """Compile the scene with a mocap ``ghost`` hull added and an off-screen buffer of width x height.

    ``samples``: multisampling of the off-screen buffer (0: none; 2 or MuJoCo's default 4 cost about
    2.5x the CPU time of a frame on Mesa's llvmpipe, measured 110 vs 40 ms at 1280x720).
    ``sea``: add the wave surface of docs/sea.md §6, a hidden hfield geom (``SEA_GEOM``, contype =
    conaffinity = 0) of SEA_NODES x SEA_NODES nodes that :meth:`FrameRenderer.update_sea` shows,
    re-centres, fills and uploads per frame when the run had a sea.
    ``hull``: the vessel's (L, B, T) [m] (:func:`usv_mj.outputs.render.world.hull_dimensions`): the model file's hull scaled to it
    by the MuJoCo plant's own :func:`usv_mj.scene.hull.scale_hull` (what the plant
    simulates is what is drawn); None: the file's hull (the paper's).
    """
    spec, label = load_scene_spec(model_path)
    if hull is not None:
        from usv_mj.scene.hull import scale_hull
        from usv_mj.vessels import Dimensions

        scale_hull(spec, Dimensions(*hull))
    base = spec.compile()
    for jname in ("x", "y", "yaw"):
        if mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_JOINT, jname) < 0:
            raise ValueError(f"render model {label}: joint {jname!r} of the hull is missing "
                             "(expected joints 'x', 'y', 'yaw')")
    hull_id = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_BODY, "hull")
    if hull_id < 0:
        raise ValueError(f"render model {label}: body 'hull' is missing")
    if ghost:
        # the ghost is a silhouette: the largest geoms only (each draw costs ~0.2 ms on llvmpipe)
        geoms = sorted(_hull_geoms_in_hull_frame(base, hull_id), key=lambda g: -g["rbound"])[:GHOST_MAX_GEOMS]
        body = spec.worldbody.add_body(name="ghost", mocap=True, pos=[0, 0, 0])
        for i, g in enumerate(geoms):
            kw = dict(name=f"ghost_{i}", type=mujoco.mjtGeom(g["type"]), size=g["size"], pos=g["pos"],
                      quat=g["quat"], rgba=list(GHOST_RGBA), contype=0, conaffinity=0, group=1, mass=0)
            if g["mesh"]:
                kw["meshname"] = g["mesh"]
            body.add_geom(**kw)
    if sea:
        from usv_mj.outputs.render.world import SEA_NODES

        hf = spec.add_hfield(name=SEA_HFIELD, size=[SEA_MAX_HALF, SEA_MAX_HALF, 1.0, 0.05], nrow=SEA_NODES,
                             ncol=SEA_NODES)
        hf.userdata = [0.5] * (SEA_NODES * SEA_NODES)
        spec.worldbody.add_geom(name=SEA_GEOM, type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=SEA_HFIELD,
                                contype=0, conaffinity=0, group=0, rgba=[*SEA_RGBA[:3], 0.0], mass=0)
    spec.visual.global_.offwidth = max(int(width), int(spec.visual.global_.offwidth))
    spec.visual.global_.offheight = max(int(height), int(spec.visual.global_.offheight))
    spec.visual.quality.offsamples = int(samples)
    return spec.compile(), label


def water_level(model: mujoco.MjModel) -> float:
    """z [m] of the highest plane geom (the water surface), 0 when the model has none."""
    planes = [model.geom_pos[g, 2] for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE
              and model.geom_bodyid[g] == 0]
    return float(max(planes)) if planes else 0.0


def yaw_quat(psi: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation by psi [rad] about world z."""
    return np.array([math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)])


class FrameRenderer:
    """Owns one GL context and MuJoCo Renderer; draws :class:`FrameSpec` s to (height, width, 3) uint8.

    Parameters
    ----------
    camera: "top" (adaptive free camera from ``FrameSpec.view``) or a camera name of the model.
    layers: which of :data:`LAYERS` to draw ("hud" and "legend" are the 2-D overlay).
    shadows, reflections: MuJoCo's shadow and reflection passes (off: about 2-3x faster on Mesa).
    samples: multisampling (0 fastest, MuJoCo's default 4).
    hull: the vessel's (L, B, T) [m] or None (the model file's hull): :func:`build_replay_model`.
    """

    def __init__(self, width: int, height: int, camera: str = "top", *, model_path=None,
                 layers=LAYERS, shadows: bool = False, reflections: bool = False, samples: int = 0, hull=None):
        self.width, self.height = int(width), int(height)
        self.layers = frozenset(layers)
        unknown = self.layers - set(LAYERS)
        if unknown:
            raise ValueError(f"unknown render layers {sorted(unknown)}; known: {', '.join(LAYERS)}")
        self.model, self.model_label = build_replay_model(model_path, width=self.width, height=self.height,
                                                          ghost=True, samples=samples, hull=hull)
        m = self.model
        if not shadows:
            m.vis.quality.shadowsize = 0
        self.data = mujoco.MjData(m)
        self.qadr = [int(m.jnt_qposadr[m.joint(n).id]) for n in ("x", "y", "yaw")]
        hull = m.body("hull")
        self.hull_offset = m.body_pos[hull.id].copy()
        self.ghost_mocap = int(m.body_mocapid[m.body("ghost").id])
        self.z_water = water_level(m)
        self.shadows, self.reflections = shadows, reflections
        self.camera_name = camera
        if camera == "top":
            self.camera = mujoco.MjvCamera()
            self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
            self.camera.azimuth = 90.0
            self.camera.elevation = -90.0
            self.fovy = float(m.vis.global_.fovy)
        else:
            cid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera)
            if cid < 0:
                names = _names_of(m)
                raise ValueError(f"camera {camera!r} is not in the render model; choose one of {', '.join(names)}")
            self.camera = cid
            self.fovy = float(m.cam_fovy[cid])
        self.renderer = mujoco.Renderer(m, self.height, self.width, max_geom=4000)
        self._cheapen_texture_filtering()
        # sea and obstacles of the run being drawn (usv_mj.outputs.render.world), set per frame from FrameSpec.world
        self.sea_geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, SEA_GEOM)
        self.sea_hfield = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_HFIELD, SEA_HFIELD)
        self._planes = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE
                        and m.geom_bodyid[g] == 0]
        self._plane_z = m.geom_pos[self._planes, 2].copy()
        self._plane_alpha = m.geom_rgba[self._planes, 3].copy()
        self.world = None            # ResolvedWorld or None
        self._world_key = None
        self._sea_dirty = False
        self._boundaries: dict = {}  # obstacle index -> outline (static obstacles, cached)
        self._in_model: dict = {}    # obstacle index -> the model has its geom
        self.decor_z = self.z_water
        _OPEN.add(self)
        global _atexit_registered
        if not _atexit_registered:
            atexit.register(_close_open_renderers)
            _atexit_registered = True

    def _cheapen_texture_filtering(self) -> None:
        """The nearest texel of the nearest mipmap level (GL_NEAREST_MIPMAP_NEAREST) for 2-D textures.

        MuJoCo uploads textures with trilinear filtering; on llvmpipe the water's texture lookups
        are then a third of a frame's cost (measured 28 vs 35-39 ms of CPU a 1280x720 frame), and
        bilinear lookups within one level still 2.5 ms of 24 more than the nearest texel. The mipmap
        level is the one whose texels are about a pixel, so the picture barely changes (a mean
        difference of 0.5 of 255 in the top view of the paper run, 11 at most).
        """
        try:
            from OpenGL import GL

            ctx = self.renderer._mjr_context
            for i in range(self.model.ntex):
                if self.model.tex_type[i] == mujoco.mjtTexture.mjTEXTURE_2D:
                    GL.glBindTexture(GL.GL_TEXTURE_2D, int(ctx.texture[i]))
                    GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST_MIPMAP_NEAREST)
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        except Exception:  # pragma: no cover - keep MuJoCo's filtering if PyOpenGL cannot do it
            pass

    # --- one frame ---------------------------------------------------------------------------

    def top_camera_distance(self, view: TopView) -> float:
        """Distance [m] from the water at which the free camera sees +-view.half_height vertically."""
        return view.half_height / math.tan(math.radians(self.fovy) / 2.0)

    # --- sea and obstacles ------------------------------------------------------------------

    def use_world(self, world) -> None:
        """Switch to the sea and obstacles of ``world`` (a RenderWorld, or None: calm, none)."""
        if world == self._world_key:
            return
        from usv_mj.outputs.render.world import ResolvedWorld

        self._world_key = world
        self.world = ResolvedWorld(world) if world is not None else None
        self._boundaries.clear()
        self._in_model.clear()
        m = self.model
        env = self.world.environment if self.world is not None else None
        if env is not None and self.sea_geom >= 0:
            a = float(env.amplitude_bound)
            m.hfield_size[self.sea_hfield, 2] = 2.0 * a          # docs/sea.md §6: size (r_x, r_y, 2A, base)
            m.geom_pos[self.sea_geom, 2] = self.z_water - a      # geom z = -A
            m.geom_rgba[self.sea_geom, 3] = 1.0
            m.geom_pos[self._planes, 2] = self._plane_z - a - 0.02   # the flat sea beyond, under the troughs
            if self.camera_name == "top":   # the hfield fills the top view: drawing the plane too costs a fill
                m.geom_rgba[self._planes, 3] = 0.0
            self.decor_z = self.z_water + a                      # lines and funnel above the crests
        else:
            if self.sea_geom >= 0:
                m.geom_rgba[self.sea_geom, 3] = 0.0
            m.geom_pos[self._planes, 2] = self._plane_z
            m.geom_rgba[self._planes, 3] = self._plane_alpha
            self.decor_z = self.z_water

    def update_sea(self, spec: FrameSpec) -> None:
        """docs/sea.md §6: re-centre the hfield in whole cells (``geom_pos``; on the top view's centre, which
        always holds the hull, else on the hull), size it to the view and fill ``hfield_data`` with the
        elevation at the simulated time ``spec.t`` of the drawn state. Whole cells: the nodes sit on
        the fixed world lattice of the cell size, so the waves do not swim as the camera moves. The
        upload to the GL context happens in :meth:`render_scene`."""
        from usv_mj.outputs.render.world import SEA_BASE_EXTENT, SEA_NODES, sea_extent

        env = self.world.environment
        m = self.model
        x, y = spec.pose[0], spec.pose[1]
        if self.camera_name == "top":
            view = spec.view or TopView(x, y, 12.0)
            extent = sea_extent(view.half_height * self.width / self.height, view.half_height)
            x, y = view.cx, view.cy
        else:
            extent = 8.0 * SEA_BASE_EXTENT
        half = extent / 2.0
        cell = extent / (SEA_NODES - 1)
        cx, cy = round(x / cell) * cell, round(y / cell) * cell
        nodes = np.linspace(-half, half, SEA_NODES)
        heights = env.hfield_heights(nodes, nodes, float(spec.t), origin=(cx, cy))
        h = self.sea_hfield
        m.hfield_size[h, 0] = m.hfield_size[h, 1] = half
        m.geom_pos[self.sea_geom, 0] = cx
        m.geom_pos[self.sea_geom, 1] = cy
        adr = int(m.hfield_adr[h])
        m.hfield_data[adr:adr + SEA_NODES * SEA_NODES] = heights.ravel()
        self._sea_dirty = True

    def sea_node_under_hull(self) -> tuple[float, float, float]:
        """(x, y, z) [m] of the hfield node nearest the hull as drawn (after a frame): the geometry
        MuJoCo holds (geom_pos + node offset, geom z + data x 2A)."""
        from usv_mj.outputs.render.world import SEA_NODES

        m, h, g = self.model, self.sea_hfield, self.sea_geom
        half = float(m.hfield_size[h, 0])
        cell = 2.0 * half / (SEA_NODES - 1)
        hx = self.data.qpos[self.qadr[0]] + self.hull_offset[0]
        hy = self.data.qpos[self.qadr[1]] + self.hull_offset[1]
        c = int(round((hx - m.geom_pos[g, 0] + half) / cell))
        r = int(round((hy - m.geom_pos[g, 1] + half) / cell))
        z = m.geom_pos[g, 2] + m.hfield_data[int(m.hfield_adr[h]) + r * SEA_NODES + c] * m.hfield_size[h, 2]
        return (float(m.geom_pos[g, 0] - half + c * cell), float(m.geom_pos[g, 1] - half + r * cell), float(z))

    def _place_obstacles(self, t: float) -> None:
        from usv_mj.scene.compose import place_moving_obstacles

        try:
            place_moving_obstacles(self.model, self.data, self.world.obstacles, t)
        except ValueError:   # the render model was not composed with these obstacles: drawn as outlines
            pass

    def _obstacle_in_model(self, i: int) -> bool:
        if i not in self._in_model:
            from usv_mj.scene.compose import obstacle_geom_name

            self._in_model[i] = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM,
                                                  obstacle_geom_name(self.world.obstacles[i])) >= 0
        return self._in_model[i]

    def set_state(self, spec: FrameSpec) -> None:
        d = self.data
        self.use_world(getattr(spec, "world", None))
        if self.world is not None:
            if self.world.environment is not None and self.sea_geom >= 0:
                self.update_sea(spec)
            if self.world.any_moving:
                self._place_obstacles(float(spec.t))
        x, y, psi = spec.pose
        d.qpos[self.qadr[0]] = x - self.hull_offset[0]
        d.qpos[self.qadr[1]] = y - self.hull_offset[1]
        d.qpos[self.qadr[2]] = psi
        xd, yd, psid = spec.ref_pose
        if "ghost" in self.layers and math.isfinite(xd) and math.isfinite(yd) and math.isfinite(psid):
            d.mocap_pos[self.ghost_mocap] = (xd, yd, self.hull_offset[2])
            d.mocap_quat[self.ghost_mocap] = yaw_quat(psid)
        else:
            d.mocap_pos[self.ghost_mocap] = (0.0, 0.0, -1e4)   # hidden far below the sea
        mujoco.mj_forward(self.model, d)
        # geoms of the world body keep the positions of mj_makeData (mj_kinematics does not move them):
        # the re-centred sea and the lowered plane are placed here
        for g in ([self.sea_geom] if self.sea_geom >= 0 else []) + self._planes:
            d.geom_xpos[g] = self.model.geom_pos[g]

    def render_scene(self, spec: FrameSpec) -> np.ndarray:
        """The 3-D picture of one frame, before the 2-D overlay."""
        self.set_state(spec)
        if self.camera_name == "top":
            view = spec.view or TopView(spec.pose[0], spec.pose[1], 12.0)
            self.camera.lookat[:] = (view.cx, view.cy, self.z_water)
            self.camera.distance = self.top_camera_distance(view)
        r = self.renderer
        if self._sea_dirty:
            r._gl_context.make_current()
            mujoco.mjr_uploadHField(self.model, r._mjr_context, self.sea_hfield)
            self._sea_dirty = False
        r.update_scene(self.data, camera=self.camera)
        scn = r.scene
        scn.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.shadows
        scn.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = self.reflections
        if self.camera_name == "top":   # the sky is never in a top-down view; drawing it costs a full-screen fill
            scn.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False
        self._add_decor(spec)
        return r.render()

    def render(self, spec: FrameSpec) -> np.ndarray:
        """The finished frame: 3-D scene plus the heads-up overlay, (height, width, 3) uint8."""
        frame = self.render_scene(spec)
        if "hud" in self.layers or "legend" in self.layers:
            from usv_mj.outputs.render.overlay import draw_hud

            frame = draw_hud(frame, spec.hud, hud="hud" in self.layers, legend="legend" in self.layers)
        if getattr(spec, "others", ()) and self.camera_name == "top" and spec.view is not None:
            from usv_mj.outputs.render.overlay import draw_labels

            draw_labels(frame, self._vessel_labels(spec))
        env = self.world.environment if self.world is not None else None
        if env is not None and "hud" in self.layers:
            from usv_mj.outputs.render.overlay import draw_sea_arrows

            current = env.current(float(spec.t))[0]
            speed, direction = env.wind(float(spec.t))
            draw_sea_arrows(frame, (float(current[0]), float(current[1])), speed, direction,
                            top_down=self.camera_name == "top")
        return frame

    def _vessel_labels(self, spec: FrameSpec) -> list:
        """(text, pixel x, pixel y, rgb) of each vessel's name beside its hull, in the top camera's picture."""
        view, h, w = spec.view, self.height, self.width
        scale = (h / 2.0) / view.half_height     # pixels per metre
        out = [(spec.own_name or "own", spec.pose[0], spec.pose[1], (235, 235, 230))]
        out += [(name, pose[0], pose[1], tuple(int(255 * c) for c in rgba[:3])) for name, pose, _, rgba, _ in spec.others]
        return [(text, w / 2.0 + (x - view.cx) * scale + 12, h / 2.0 - (y - view.cy) * scale - 12, rgb)
                for text, x, y, rgb in out if math.isfinite(x) and math.isfinite(y)]

    # --- user geoms --------------------------------------------------------------------------

    def _new_geom(self, gtype, rgba):
        scn = self.renderer.scene
        if scn.ngeom >= scn.maxgeom:
            return None
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(g, gtype, np.zeros(3), np.zeros(3), np.eye(3).ravel(), np.asarray(rgba, float))
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        scn.ngeom += 1
        return g

    def _polyline(self, pts, z, width_px, rgba, fade=False):
        """Line geoms (``mjGEOM_LINE``, ``width_px`` pixels wide) through ``pts`` (k, 2) at height z.

        Lines cost almost nothing on Mesa's rasteriser; capsules cost about 0.3 ms each.
        """
        n = len(pts)
        if n < 2:
            return
        rgba = np.asarray(rgba, float)
        p0, p1 = np.empty(3), np.empty(3)
        p0[2] = p1[2] = z
        for i in range(n - 1):
            c = rgba
            if fade:
                c = rgba.copy()
                c[3] *= 0.15 + 0.85 * (i + 1) / (n - 1)
            g = self._new_geom(mujoco.mjtGeom.mjGEOM_LINE, c)
            if g is None:
                return
            p0[:2], p1[:2] = pts[i], pts[i + 1]
            mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_LINE, width_px, p0, p1)

    def _add_obstacle_outlines(self, spec: FrameSpec, z: float, w: float) -> None:
        """The inflated safety boundary of every obstacle (dashed in the figures; a line loop here), and
        the outline of any obstacle the render model does not contain (e.g. ``usv-mj render`` of a log)."""
        from usv_mj.scenario.obstacles import OBSTACLE_COLORS
        from usv_mj.scene.display import boundary_points

        world = self.world
        t = float(spec.t)
        for i, o in enumerate(world.obstacles):
            infl = world.inflation[i] if world.inflation is not None and i < len(world.inflation) else math.nan
            if math.isfinite(infl) and infl > 0:
                pts = self._boundaries.get(i) if not o.moving else None
                if pts is None:
                    pts = boundary_points(o, float(infl), t, n=48)
                    if not o.moving:
                        self._boundaries[i] = pts
                self._polyline(pts, z + 0.008, w, SAFETY_LINE_RGBA)
            if not self._obstacle_in_model(i):
                outline = np.asarray(o.shape(t).exterior.coords)
                self._polyline(outline, z + 0.008, 1.5 * w, OBSTACLE_COLORS["moving" if o.moving else o.kind])

    def _add_decor(self, spec: FrameSpec) -> None:
        z = self.decor_z + 0.01
        w = max(1.0, 3.0 * self.height / 720.0)
        if "path" in self.layers:
            self._polyline(spec.path, z + 0.002, w, PATH_RGBA)
        if "trail" in self.layers:
            self._polyline(spec.trail, z + 0.004, w, TRAIL_RGBA, fade=True)
        if "funnel" in self.layers:
            cx, cy = spec.funnel_center
            hx, hy = spec.funnel_half
            if all(math.isfinite(v) for v in (cx, cy, hx, hy)) and hx > 0 and hy > 0:
                rgba = FUNNEL_OK_RGBA if spec.funnel_ok else FUNNEL_BAD_RGBA
                corners = [(cx - hx, cy - hy), (cx + hx, cy - hy), (cx + hx, cy + hy), (cx - hx, cy + hy),
                           (cx - hx, cy - hy)]
                self._polyline(corners, z + 0.006, 1.2 * w, rgba)
                fill = self._new_geom(mujoco.mjtGeom.mjGEOM_BOX, (*rgba[:3], FUNNEL_FILL_ALPHA))
                if fill is not None:
                    fill.size[:] = (hx, hy, 0.002)
                    fill.pos[:] = (cx, cy, z)
        if self.world is not None and self.world.obstacles:
            self._add_obstacle_outlines(spec, z, w)
        if getattr(spec, "others", ()):
            self._add_vessels(spec, z, w)

    def _add_vessels(self, spec: FrameSpec, z: float, w: float) -> None:
        """The other vessels of a fleet (planner.add_fleet): each hull as a box and a bow ellipsoid of
        its length and beam (the model's hull shape, in its colour) at its pose, its wake trail, and
        the own ship's safety domain as a circle about the own hull."""
        for name, (x, y, psi), trail, rgba, (length, beam) in spec.others:
            if "trail" in self.layers:
                self._polyline(trail, z + 0.004, w, (*rgba[:3], 0.7), fade=True)
            if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(psi)):
                continue
            c, s = math.cos(psi), math.sin(psi)
            rot = np.array([c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0])
            half_l, half_b = 0.5 * length, 0.5 * beam
            for gtype, size, ahead in ((mujoco.mjtGeom.mjGEOM_BOX, (0.7 * half_l, half_b, 0.15 * half_b), -0.28 * half_l),
                                       (mujoco.mjtGeom.mjGEOM_ELLIPSOID, (0.58 * half_l, half_b, 0.15 * half_b),
                                        0.42 * half_l)):
                g = self._new_geom(gtype, rgba)
                if g is None:
                    return
                g.size[:] = size
                g.pos[:] = (x + c * ahead, y + s * ahead, self.z_water + 0.05)
                g.mat[:] = rot.reshape(3, 3)
        if getattr(spec, "domain", 0.0) > 0:
            x, y = spec.pose[0], spec.pose[1]
            a = np.linspace(0.0, 2.0 * math.pi, 73)
            self._polyline(np.c_[x + spec.domain * np.cos(a), y + spec.domain * np.sin(a)], z + 0.008, w,
                           (1.0, 0.25, 0.2, 0.8))

    def close(self) -> None:
        """Free the GL resources, with this renderer's own context current (freeing one while
        another renderer's context is current frees the wrong objects)."""
        renderer, self.renderer = self.renderer, None
        if renderer is not None:
            gl = getattr(renderer, "_gl_context", None)
            if gl is not None:
                gl.make_current()
            renderer.close()
        _OPEN.discard(self)
