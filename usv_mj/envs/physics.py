"""The dm_control ``Physics`` of the USV environments: a view of a MuJoCo plant, not a copy.

:class:`USVPhysics` wraps the very ``mujoco.MjModel`` / ``mujoco.MjData`` of a
:class:`usv_mj.plants.mujoco_plant.MuJoCoPlant` (``wrapper.MjData(plant.data)`` shares the native
structs), so the environment integrates exactly what ``usv-mj run --plant mujoco`` integrates:

- the passive-force callback is the plant's (installed by the plant's registry when the plant is
  made, removed when the last plant is closed; its parameters live in this mjData's ``userdata``
  behind the marker, so any number of environments coexist in one process);
- :meth:`USVPhysics.step` advances through :meth:`MuJoCoPlant.step` (zero-order hold of
  ``data.ctrl`` = (tau_u [N], tau_r [N m]) over ``plant.substeps`` RK4 steps of ``opt.timestep``),
  so the time is the plant's step count times the control period, as in :func:`usv_mj.loop.simulate.simulate`;
- :meth:`USVPhysics.reset` goes through :meth:`MuJoCoPlant.reset`, which writes the callback's
  parameters again after ``mj_resetData`` (a bare ``mj_resetData`` would zero ``userdata`` and
  silently turn the hydrodynamics off).

The plant comes from :func:`usv_mj.build.make_plant` (the one constructor of plants): in the
harbor tasks it is the composed harbour scene with the ``rangefinders`` option (a fan of MuJoCo
``rangefinder`` sensors on the hull, :func:`usv_mj.scene.compose.compose_scene`).

:meth:`USVPhysics.render` (what dm_control's tools and shimmy's ``DmControlCompatibilityV0`` call)
draws with the project's renderer, not dm_control's: the water and the sea are the renderer's
(:mod:`usv_mj.envs.rendering`), and it runs headless with the OpenGL choice of ``usv-mj run``.
"""

from __future__ import annotations

import warnings

import numpy as np

with warnings.catch_warnings():
    # dm_control probes GLFW at import when MUJOCO_GL is unset and warns that there is no DISPLAY
    # (as in usv_mj.scene.compose); nothing here needs GL until physics.render is called
    warnings.simplefilter("ignore")
    from dm_control import mujoco as dm_mujoco
    from dm_control.mujoco import wrapper

from usv_mj.plants.mujoco_callback import HydrodynamicCallbackError
from usv_mj.plants.mujoco_plant import MuJoCoPlant



class USVPhysics(dm_mujoco.Physics):
    """A ``dm_control.mujoco.Physics`` over a :class:`MuJoCoPlant`'s own model and data.

    Build with :meth:`from_plant`. Attributes: ``plant`` (the plant), ``failure`` (None, or the
    message of the last :class:`HydrodynamicCallbackError` raised during :meth:`step`: the task
    ends the episode with it as the reason), ``owner`` (None, or a weak reference to the
    :class:`usv_mj.envs.USVEnvironment` that steps it, set by the environment: :meth:`render`
    draws its episode).
    """

    plant: MuJoCoPlant
    owner = None

    @classmethod
    def from_plant(cls, plant: MuJoCoPlant) -> USVPhysics:
        if plant.data.model._address != plant.model._address:  # pragma: no cover - bindings invariant
            raise RuntimeError("USVPhysics: the plant's data does not belong to its model")
        obj = cls.__new__(cls)
        obj.plant = plant
        obj.failure = None
        obj._closed = False
        obj.owner = None
        obj._frames = None
        obj._ctrl = plant.data.ctrl  # a view of the mjData's ctrl (read at every step)
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
        ctrl = self._ctrl
        tau_u, tau_r = float(ctrl[0]), float(ctrl[1])
        plant = self.plant
        try:
            for _ in range(nstep // sub):
                plant.step(tau_u, tau_r)
        except HydrodynamicCallbackError as exc:
            self.failure = str(exc)

    def step_native(self, plant_kernel, step, *args):
        """One control period through a native function that steps the plant's kernel itself
        (the fused step of :meth:`usv_mj.envs.USVEnvironment.step`): ``step(k, t, *args)`` with k the
        plant's step count and t [s] the time after the step returns the evaluation at the new
        state (``.x``, and ``.failed`` when the plant's step failed); the plant is brought to that
        state (``plant_kernel.sync``) and a failure kept in :attr:`failure`, as :meth:`step` keeps it.
        Returns (evaluation, t)."""
        plant = self.plant
        k = plant.step_count
        t = plant.time_at(k + 1)
        ev = step(k, t, *args)
        plant_kernel.sync(k + 1, ev.x)
        if ev.failed:  # as step(): the plant's error is the physics' failure
            try:
                plant_kernel.fail(k)
            except HydrodynamicCallbackError as exc:
                self.failure = str(exc)
        return ev, t

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

    # --- pictures -------------------------------------------------------------------------------

    def render(self, height=240, width=320, camera_id=-1, overlays=(), depth=False, segmentation=False,
               scene_option=None, render_flag_overrides=None, scene_callback=None) -> np.ndarray:
        """A camera view as a (height, width, 3) uint8 RGB array, with ``dm_control.mujoco.Physics.render``'s
        signature, drawn by the project's renderer (the one of ``usv-mj run``, :mod:`usv_mj.envs.rendering`)
        rather than dm_control's: the hull on the water (the sea's waves when the episode has a sea), its
        wake, the path ahead, the funnel, the harbour's obstacles and the heads-up overlay. It works
        headless with the OpenGL choice of ``usv-mj run`` (``MUJOCO_GL`` if set, else EGL, else OSMesa),
        whatever GL platform dm_control picked when it was imported.

        What it draws: the episode of the environment that owns this physics
        (:meth:`usv_mj.envs.USVEnvironment.render_frame`; the same frame as the Gymnasium view's
        ``render()``); a physics that belongs to no environment draws its hull on calm water.

        ``camera_id``: -1 (dm_control's free camera) is the renderer's ``"top"`` view (straight down,
        north up, following the hull); a camera index of this model or a camera name (``"chase"``,
        ``"overview"``, ``"chart"``, ``"top"``) is that camera of models/scene.xml.

        Not supported (each raises ValueError naming the argument, so that nothing is silently
        ignored): ``depth``, ``segmentation``, ``overlays``, ``scene_option``, ``render_flag_overrides``
        and ``scene_callback``. dm_control's own renderer is still there for them, as
        ``dm_control.mujoco.Physics.render(physics, ...)``: it draws this model (the hull without the
        water) and needs ``MUJOCO_GL`` set before dm_control is imported.
        """
        for name, value, asked in (("depth", depth, bool(depth)), ("segmentation", segmentation, bool(segmentation)),
                                   ("overlays", overlays, bool(overlays)),
                                   ("scene_option", scene_option, scene_option is not None),
                                   ("render_flag_overrides", render_flag_overrides, bool(render_flag_overrides)),
                                   ("scene_callback", scene_callback, scene_callback is not None)):
            if asked:
                raise ValueError(f"USVPhysics.render: {name}={value!r} is not supported: the project's renderer "
                                 "draws RGB frames of its own scene (call dm_control.mujoco.Physics.render("
                                 "physics, ...) for dm_control's renderer, with MUJOCO_GL set)")
        camera = self._camera_name(camera_id)
        env = self.owner() if self.owner is not None else None
        if env is not None and env.physics is self:
            return env.render_frame(width=width, height=height, camera=camera)
        from usv_mj.envs.rendering import FrameSource, hull_tuple, pose_record

        if self._closed:
            raise RuntimeError("USVPhysics.render: the physics is closed")
        if self._frames is None:
            self._frames = FrameSource()
        d = getattr(self.plant, "dimensions", None)  # the hull the plant simulates (None: the model file's)
        hull = None if d is None else hull_tuple(d)
        return self._frames.frame(pose_record(self.state, self.time()), width=width, height=height, camera=camera,
                                  hull=hull)

    def _camera_name(self, camera_id) -> str:
        if isinstance(camera_id, str):
            return camera_id
        try:
            i = int(camera_id)
        except (TypeError, ValueError):
            raise ValueError(f"USVPhysics.render: camera_id must be a camera name or index, got {camera_id!r}") from None
        if i == -1:
            return "top"
        n = int(self.model.ncam)
        if not 0 <= i < n:
            raise ValueError(f"USVPhysics.render: camera_id = {i}: this model has {n} cameras "
                             f"(0..{n - 1}); -1 is the free top view")
        return self.model.id2name(i, "camera")

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
                if self._frames is not None:
                    self._frames.close()
                    self._frames = None
                self.free()
            finally:
                self.plant.close()
