"""The dm_control ``Physics`` of the USV environments: a view of a MuJoCo plant, not a copy.

:class:`USVPhysics` wraps the very ``mujoco.MjModel`` / ``mujoco.MjData`` of a
:class:`usv_mj.plants.mujoco_plant.MuJoCoPlant` (``wrapper.MjData(plant.data)`` shares the native
structs), so the environment integrates exactly what ``usv-mj run --plant mujoco`` integrates:

- the passive-force callback is the plant's (installed by the plant's registry when the plant is
  made, removed when the last plant is closed; its parameters live in this mjData's ``userdata``
  behind the marker, so any number of environments coexist in one process);
- :meth:`USVPhysics.step` advances through :meth:`MuJoCoPlant.step` (zero-order hold of
  ``data.ctrl`` = (tau_u [N], tau_r [N m]) over ``plant.substeps`` RK4 steps of ``opt.timestep``),
  so the time is the plant's step count times the control period, as in :func:`usv_mj.simulation.simulate`;
- :meth:`USVPhysics.reset` goes through :meth:`MuJoCoPlant.reset`, which writes the callback's
  parameters again after ``mj_resetData`` (a bare ``mj_resetData`` would zero ``userdata`` and
  silently turn the hydrodynamics off).

:class:`HarbourEnvPlant` is the MuJoCo plant on the harbour model of
:func:`usv_mj.obstacles.compose.compose_scene` plus a fan of MuJoCo ``rangefinder`` sensors on the
hull (sites at the hull origin, 0.3 m above the waterline, rays horizontal).
"""

from __future__ import annotations

import math
import tempfile
import warnings

import mujoco
import numpy as np

with warnings.catch_warnings():
    # dm_control probes GLFW at import when MUJOCO_GL is unset and warns that there is no DISPLAY
    # (as in usv_mj.obstacles.compose); nothing here needs GL until physics.render is called
    warnings.simplefilter("ignore")
    from dm_control import mujoco as dm_mujoco
    from dm_control.mujoco import wrapper

from usv_mj.plants.mujoco_callback import HydrodynamicCallbackError
from usv_mj.plants.mujoco_plant import MuJoCoPlant

RANGEFINDER_HEIGHT = 0.3  # m above the waterline (obstacles span z in [-1, 1], the water plane is z = 0)


class USVPhysics(dm_mujoco.Physics):
    """A ``dm_control.mujoco.Physics`` over a :class:`MuJoCoPlant`'s own model and data.

    Build with :meth:`from_plant`. Attributes: ``plant`` (the plant), ``failure`` (None, or the
    message of the last :class:`HydrodynamicCallbackError` raised during :meth:`step`: the task
    ends the episode with it as the reason).
    """

    plant: MuJoCoPlant

    @classmethod
    def from_plant(cls, plant: MuJoCoPlant) -> USVPhysics:
        if plant.data.model._address != plant.model._address:  # pragma: no cover - bindings invariant
            raise RuntimeError("USVPhysics: the plant's data does not belong to its model")
        obj = cls.__new__(cls)
        obj.plant = plant
        obj.failure = None
        obj._closed = False
        dm_mujoco.Physics.__init__(obj, wrapper.MjData(plant.data))
        return obj

    # --- stepping and resetting go through the plant --------------------------------------------

    def step(self, nstep: int = 1) -> None:
        """Advance ``nstep`` MuJoCo steps (a whole number of control periods of the plant) with the
        thrust in ``data.ctrl`` held (MuJoCoPlant.step). A callback failure or a NaN reset is caught
        and kept in :attr:`failure` (the state is then what MuJoCo left)."""
        sub = self.plant.substeps
        if nstep % sub != 0:
            raise ValueError(f"USVPhysics.step: nstep = {nstep} is not a multiple of the plant's substeps ({sub})")
        if self.failure is not None:
            return
        ctrl = self.plant.data.ctrl
        tau_u, tau_r = float(ctrl[0]), float(ctrl[1])
        try:
            for _ in range(nstep // sub):
                self.plant.step(tau_u, tau_r)
        except HydrodynamicCallbackError as exc:
            self.failure = str(exc)

    def reset(self, keyframe_id=None) -> None:
        """Back to the origin at rest at t = 0 through :meth:`MuJoCoPlant.reset` (the task then puts
        the hull at its initial pose with :meth:`set_initial_state`)."""
        if keyframe_id is not None:
            raise ValueError("USVPhysics.reset: keyframes are not supported (the task sets the initial state)")
        self.failure = None
        self.plant.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)

    def set_initial_state(self, eta0, nu0) -> None:
        """Pose (x, y, psi) [m, m, rad] and body velocity (u, v, r) at t = 0 (MuJoCoPlant.reset)."""
        self.failure = None
        self.plant.reset(eta0, nu0, 0.0)

    def copy(self, share_model=False):
        raise NotImplementedError("USVPhysics cannot be copied: it is a view of one plant (make another "
                                  "environment with usv_mj.envs.load)")

    # --- state in the plant's conventions -------------------------------------------------------

    @property
    def state(self) -> np.ndarray:
        """(x, y, psi, u, v, r): pose [m, m, rad] and body velocity [m/s, m/s, rad/s]."""
        return self.plant.state

    def time(self) -> float:
        """The plant's time [s] (step count times the control period: no summation drift)."""
        return self.plant.time

    def close(self) -> None:
        """Close the plant (unmarks the mjData; the callback is removed with the last plant)."""
        if not self._closed:
            self._closed = True
            try:
                self.free()
            finally:
                self.plant.close()


class HarbourEnvPlant(MuJoCoPlant):
    """:class:`MuJoCoPlant` on the composed harbour model with ``n_rays`` rangefinders on the hull.

    Same composition as :class:`usv_mj.obstacles.compose.HarbourPlant` (collision geoms, contact
    parameters, filtering), plus sites ``range_i`` on body "hull" at z = :data:`RANGEFINDER_HEIGHT`
    whose z axes point at the body-frame angles ``ray_angles`` [rad] (0 = bow, counter-clockwise),
    and one ``rangefinder`` sensor per site. MuJoCo's rangefinder excludes the site's own body, so
    the hull never sees itself; the rays are parallel to the water plane and hit only obstacles.
    Readings are the distance [m] from the hull origin along the ray, -1 when nothing is hit.

    Attributes as ``HarbourPlant``: ``obstacles``, ``hull_geoms``, ``obstacle_geoms``,
    ``obstacle_mocap``, ``model_xml_path``; plus ``ray_angles``, :meth:`rangefinders` and
    ``render_model_path`` (the same harbour without the rangefinder sites, for ``usv_mj.render``).
    """

    def __init__(self, ship, disturbance, obstacles=(), control_period: float = 1e-3, substeps: int = 1,
                 contact=None, ray_angles=(), environment=None):
        from usv_mj.obstacles.compose import (
            HULL_COLLISION_GEOMS,
            ContactParams,
            compose_scene,
            export_scene,
            obstacle_geom_name,
        )

        contact = contact or ContactParams()
        self.obstacles = tuple(obstacles)
        self.contact = contact
        if contact.solref[0] < 2.0 * control_period / substeps:
            raise ValueError(f"HarbourEnvPlant: contact.solref[0] = {contact.solref[0]} s is under twice the MuJoCo "
                             f"time step ({control_period / substeps} s)")
        self.ray_angles = np.asarray(ray_angles, dtype=float).reshape(-1)
        root = compose_scene(self.obstacles, contact)
        hull = root.find("body", "hull")
        for i, a in enumerate(self.ray_angles):
            site = hull.add("site", name=f"range_{i}", pos=[0.0, 0.0, RANGEFINDER_HEIGHT],
                            zaxis=[math.cos(a), math.sin(a), 0.0], size=[0.02], group=4)
            root.sensor.add("rangefinder", name=f"range_{i}", site=site)
        self._tmp = tempfile.TemporaryDirectory(prefix="usv_mj_env_harbour_")
        self.model_xml_path = export_scene(root, self._tmp.name)
        # the same harbour without the rangefinders, for the renderer (MuJoCo draws rangefinder rays)
        self.render_model_path = export_scene(compose_scene(self.obstacles, contact),
                                              tempfile.mkdtemp(dir=self._tmp.name))
        kwargs = {} if environment is None else {"environment": environment}
        super().__init__(ship, disturbance, control_period, substeps, model_path=self.model_xml_path, **kwargs)
        m = self.model
        gid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n)
        self.hull_geoms = np.array([gid(n) for n, *_ in HULL_COLLISION_GEOMS], dtype=np.int64)
        self.obstacle_geoms = np.array([gid(obstacle_geom_name(o)) for o in self.obstacles], dtype=np.int64)
        self.obstacle_mocap = np.full(len(self.obstacles), -1, dtype=np.int64)
        for i, o in enumerate(self.obstacles):
            if o.moving:
                self.obstacle_mocap[i] = m.body_mocapid[m.geom_bodyid[self.obstacle_geoms[i]]]
        self._sensor_adr = np.array([m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, f"range_{i}")]
                                     for i in range(len(self.ray_angles))], dtype=np.int64)

    def move_obstacles(self, t: float) -> None:
        """Put every moving obstacle at center + velocity t (held during the next step)."""
        for i, o in enumerate(self.obstacles):
            j = self.obstacle_mocap[i]
            if j >= 0:
                cx, cy = o.center_at(t)
                self.data.mocap_pos[j, 0] = cx
                self.data.mocap_pos[j, 1] = cy

    def rangefinders(self) -> np.ndarray:
        """Readings [m] (-1: no hit) at the current state: kinematics, then MuJoCo's position-stage
        sensors (after ``mj_step`` the sensor data are those of the last step's start)."""
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_sensorPos(self.model, self.data)
        return self.data.sensordata[self._sensor_adr].copy()

    def close(self) -> None:
        super().close()
        self._tmp.cleanup()
