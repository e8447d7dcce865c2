"""Frames of an environment through the project's renderer: the one place where the dm_env
(:meth:`usv_mj.envs.USVEnvironment.render_frame`), its physics (:meth:`USVPhysics.render`, what
dm_control tools and shimmy's ``DmControlCompatibilityV0`` call) and the Gymnasium view
(``USVGymEnv.render``) draw a picture.

A frame is the last row of a :class:`~usv_mj.record.run_record.RunRecord` of the episode so far
(:func:`usv_mj.envs.episode_record`: its metadata carry the episode's scenario, so the frame has the
sea and the harbour), planned by :func:`usv_mj.outputs.render.planner.plan_frames` and drawn by a
:class:`usv_mj.outputs.render.replay.FrameRenderer`, the renderer of ``usv-mj run``, with the same OpenGL
choice (:func:`usv_mj.outputs.render.gl_backend.select_backend`: ``MUJOCO_GL`` if set, else EGL, else
OSMesa). mujoco binds its GL platform when it is first imported, and dm_control imports it before
anyone chose: when the platform it was bound to is not the chosen one (``MUJOCO_GL`` was unset,
say), the frames are drawn by one spawned worker process that imports mujoco with the right one.
"""

from __future__ import annotations

import weakref

import numpy as np

#: Rows of an episode an environment keeps for its frames (the wake trail is the last 10 s or so).
HISTORY_ROWS = 3000


class _Drawer:
    """One :class:`usv_mj.outputs.render.replay.FrameRenderer`, here or in one spawned worker (module docstring)."""

    def __init__(self, width: int, height: int, camera: str, hull=None):
        from usv_mj.outputs.render.gl_backend import in_process_backend, select_backend
        from usv_mj.outputs.render.video import check_camera

        self.backend = select_backend()
        check_camera(camera)          # a bad name is one ValueError here, not a failed worker
        self.key = (int(width), int(height), camera, hull)
        # hull: the vessel's (L, B, T) [m], the model file's hull scaled to it as the run's video does
        self.kwargs = dict(width=int(width), height=int(height), camera=camera, model_path=None, hull=hull)
        here = in_process_backend()
        self.local = self.pool = None
        if here is None or here == self.backend:
            from usv_mj.outputs.render.replay import FrameRenderer

            self.local = FrameRenderer(**self.kwargs)
        else:
            from usv_mj.outputs.render.gl_backend import backend_environment
            from usv_mj.outputs.render.video import worker_init

            from usv_mj.support.spawning import spawn_context

            self.pool = spawn_context().Pool(
                1, initializer=worker_init, initargs=(backend_environment(self.backend), self.kwargs))
            # an environment dropped without close() still stops its worker
            weakref.finalize(self, self.pool.terminate)

    def frame(self, spec) -> np.ndarray:
        if self.local is not None:
            return np.array(self.local.render(spec), dtype=np.uint8)
        from usv_mj.outputs.render.video import worker_render

        return np.array(self.pool.apply(worker_render, (spec,)), dtype=np.uint8)

    def close(self) -> None:
        if self.local is not None:
            self.local.close()
        if self.pool is not None:
            from usv_mj.outputs.render.video import worker_close

            try:
                self.pool.apply(worker_close)     # the worker frees its GL context before it is stopped
            except Exception:  # noqa: BLE001 - a worker that is gone has nothing to free
                pass
            self.pool.terminate()
            self.pool.join()
        self.local = self.pool = None


class FrameSource:
    """Draws the last row of a record at a size and camera; keeps its renderer (and worker) while
    they stay the same, and starts another when they change. :meth:`close` stops it."""

    def __init__(self):
        self._drawer = None

    def frame(self, record, *, width: int, height: int, camera: str = "top", hull="record") -> np.ndarray:
        """The (height, width, 3) uint8 frame of the last row of ``record``. ``hull``: the drawn
        hull's (L, B, T) [m]; "record" (default): the record's vessel's, as ``usv-mj run``'s video
        draws it (:func:`usv_mj.outputs.render.world.hull_dimensions`); None: the model file's (the paper's)."""
        from usv_mj.outputs.render.planner import plan_frames
        from usv_mj.outputs.render.world import hull_dimensions

        for name, v in (("width", width), ("height", height)):
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or not 16 <= v <= 8192:
                raise ValueError(f"render: {name} = {v!r} must be a whole number of pixels in [16, 8192]")
        if isinstance(hull, str) and hull == "record":
            hull = hull_dimensions(record)
        key = (int(width), int(height), camera, None if hull is None else tuple(float(v) for v in hull))
        if self._drawer is None or self._drawer.key != key:
            self.close()
            self._drawer = _Drawer(*key)
        spec = plan_frames(record, width=key[0], height=key[1], camera=camera, rows=[len(record) - 1]).frames[0]
        return self._drawer.frame(spec)

    def close(self) -> None:
        if self._drawer is not None:
            self._drawer.close()
            self._drawer = None


def pose_record(state, t: float = 0.0):
    """A one-row record of a pose (x, y, psi, u, v, r) at t [s], with no reference and no scenario
    (calm water): what a physics that belongs to no environment can draw (its hull: the plant's
    dimensions, given to :meth:`FrameSource.frame` as ``hull``)."""
    from usv_mj.record.run_record import RunRecord

    x = np.asarray(state, dtype=float)
    cols = {"t": np.array([float(t)])}
    for j, name in enumerate(("x", "y", "psi", "u", "v", "r")):
        cols[name] = x[j:j + 1].copy()
    return RunRecord.from_arrays(cols, metadata={"plant": "mujoco", "controller": "env"})


def hull_tuple(dimensions):
    """(L, B, T) [m] of a :class:`usv_mj.vessels.Dimensions` as the renderer takes it, None for the
    model file's own hull (the paper's): :func:`usv_mj.outputs.render.world.hull_dimensions`'s rule."""
    from types import SimpleNamespace

    from usv_mj.outputs.render.world import hull_dimensions

    return hull_dimensions(SimpleNamespace(vessel=SimpleNamespace(model=SimpleNamespace(dimensions=dimensions))))
