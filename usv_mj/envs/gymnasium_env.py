"""The Gymnasium view of the USV tasks: :class:`USVGymEnv` and the registered ids.

::

    import gymnasium
    env = gymnasium.make("usv_mj.envs:usv_mj/Track-v0") # Gymnasium imports usv_mj.envs, which registers the ids
    env = gymnasium.make("usv_mj/Track-v0")             # the same from a wheel (usv_mj.envs.gymnasium_hook), or once
                                                        # usv_mj.envs is imported; or gym_env("track")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    info["kind"], info["reason"]                        # why the episode ended (None while it runs)

Ids: one per task of :data:`usv_mj.core.registry.TASKS` (:func:`usv_mj.envs.gym_id`, registered on
``import usv_mj.envs``, and by a task registered later when it registers): ``usv_mj/Track-v0``,
``usv_mj/TrackWaves-v0``, ``usv_mj/Harbor-v0``, ``usv_mj/HarborWaves-v0`` (the tasks ``track``,
``track_waves``, ``harbor``, ``harbor_waves`` of :mod:`usv_mj.envs`), ``usv_mj/MyTask-v0`` for a
task ``my_task`` of your own. ``gymnasium.make(id, **options)`` passes the options of
:func:`usv_mj.envs.load` through (``duration``, ``quantize``, ``preset``, ...), plus ``seed`` (the
environment's seed until the first ``reset(seed=...)``), ``flat`` and ``render_size``.

Action: ``Box(-1, 1, (2,), float32)``, the normalized (tau_u, tau_r): +1 is the task's largest
forward surge force / counter-clockwise yaw moment, -1 the largest astern / clockwise one (the
bounds of the dm_env action spec, :func:`usv_mj.envs.tasks.action_bounds`), 0 is no thrust; each
side is scaled on its own (a = tau / high for tau >= 0, tau / |low| below), so asymmetric
actuator limits keep 0 at rest; a channel whose least value is 0 (KVLCC2's surge, whose propeller
does not pull astern) gives 0 for the whole negative half. Values outside [-1, 1] are clipped.

Observation (``flat=True``, the default): one float32 vector, the task's observations (in
:meth:`usv_mj.envs.tasks.TrackTask.observation_shapes` order) each divided by its scale
(:data:`SCALES`) and clipped to the space's bounds, so ``PPO("MlpPolicy", env)`` takes it with no
wrapper. ``flat=False`` gives a ``Dict`` of the same scaled Boxes. The scales put the usual values
near +-1: lengths / 10 m, angles / pi, speeds / 2 m/s, yaw rates / 1 rad/s, the funnel by its
initial width, the time by the time limit (so it runs from 0 to 1), the rangefinders by their
range. The bounds come from what ends an episode: the distance to the reference (``max_distance``),
the state limits of the scenario (``limits.max_speed``, ``limits.max_yaw_rate``), the time limit,
the rangefinders' range; an observation past them ends the episode on that very step, and is
clipped to the bound in that last observation. :meth:`USVGymEnv.decode` gives the unscaled
(physical) dict back.

``info``: ``kind`` (None while the episode runs; "diverged", "lost", "contact", "goal" or
"time_limit" at its end), ``reason`` (a sentence), ``time`` [s], ``action`` (the clipped physical
action [N, N m]), ``command`` (after the quantizer) and ``thrust`` (what the plant got: the vessel's
actuators' force). ``terminated`` is the
task's termination (discount 0), ``truncated`` the time limit.

Rendering (``render_mode="rgb_array"``): the project's renderer (:mod:`usv_mj.outputs.render`, the one
``usv-mj run`` uses, with the same OpenGL choice, :func:`usv_mj.outputs.render.gl_backend.select_backend`):
the top view of the hull on the water (the sea's waves in the wave tasks), its wake, the path
ahead, the funnel and the harbour's obstacles: the frame of
:meth:`usv_mj.envs.USVEnvironment.render_frame`, which the dm_env's ``physics.render()`` draws
too (:mod:`usv_mj.envs.rendering`). When mujoco in this process is bound to another GL platform
than the chosen one, the frames are drawn by one spawned worker process.
"""

from __future__ import annotations

import collections
import math
import warnings

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError:  # pragma: no cover - optional dependency
    from usv_mj.core.errors import missing_extra

    raise missing_extra("gymnasium", "usv_mj's Gymnasium view (usv_mj.envs.gym_env, gymnasium.make)") from None

from usv_mj.envs.environment import load

LENGTH_SCALE = 10.0      # m
SPEED_SCALE = 2.0        # m/s
YAW_RATE_SCALE = 1.0     # rad/s
PREVIEW_SPEED = 10.0     # m/s: bound of the reference's speed in the preview bound (clipped beyond)
#: name -> scale of each element (the funnel, time and rangefinder scales depend on the task)
SCALES = {"position_error": LENGTH_SCALE, "heading_error": math.pi, "heading": 1.0,
          "velocity": (SPEED_SCALE, SPEED_SCALE, YAW_RATE_SCALE),
          "velocity_error": (SPEED_SCALE, SPEED_SCALE, YAW_RATE_SCALE), "reference_preview": LENGTH_SCALE,
          "funnel": "rho(0)", "time": "time limit", "goal": (LENGTH_SCALE, LENGTH_SCALE, math.pi),
          "rangefinder": "max_range"}


class USVGymEnv(gymnasium.Env):
    """A :func:`usv_mj.envs.load` environment as a ``gymnasium.Env`` (see the module docstring).

    ``dm_env`` is the underlying :class:`usv_mj.envs.USVEnvironment` (its ``task`` and ``physics``).
    """

    RENDER_MODES = ("rgb_array",)

    # The metadata is an instance property: gymnasium.make then hands render_mode to __init__ as
    # asked, so an unsupported mode ("human") is refused in one line instead of being wrapped in
    # gymnasium's HumanRendering (a pygame window this headless renderer never fills).
    @property
    def metadata(self) -> dict:
        return self._metadata

    @metadata.setter
    def metadata(self, value: dict) -> None:
        self._metadata = value

    def __init__(self, task: str = "track", seed=None, render_mode=None, flat: bool = True,
                 render_size=(640, 360), **options):
        self._metadata = {"render_modes": list(self.RENDER_MODES), "render_fps": 30}
        if render_mode is not None and render_mode not in self.RENDER_MODES:
            raise ValueError(f"USVGymEnv: render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.task_name = task
        self.render_mode = render_mode
        self.render_size = tuple(int(v) for v in render_size)
        self.flat = bool(flat)
        self.dm_env = load(task, seed=seed, **options)
        self.metadata = dict(self.metadata, render_fps=round(1.0 / self.dm_env.control_timestep()))
        t = self.dm_env.task
        spec = self.dm_env.action_spec()
        self._low, self._high = np.asarray(spec.minimum, float), np.asarray(spec.maximum, float)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._scale, self._bounds = {}, {}
        for name, shape in t.observation_shapes():
            scale, lo, hi = self._scaling(name, shape)
            self._scale[name], self._bounds[name] = scale, (lo, hi)
        boxes = collections.OrderedDict(
            (n, spaces.Box(lo.astype(np.float32), hi.astype(np.float32), lo.shape, np.float32))
            for n, (lo, hi) in self._bounds.items())
        if self.flat:
            lo = np.concatenate([b.low.ravel() for b in boxes.values()])
            hi = np.concatenate([b.high.ravel() for b in boxes.values()])
            self.observation_space = spaces.Box(lo, hi, lo.shape, np.float32)
        else:
            self.observation_space = spaces.Dict(boxes)

    # --- scaling ---------------------------------------------------------------------------------

    def _scaling(self, name, shape):
        t = self.dm_env.task
        lim = t.scenario.limits
        if name == "funnel":
            scale = np.array([t.funnel_xy.rho_0, t.funnel_psi.rho_0])
        elif name == "time":
            scale = np.array([t.time_limit])
        elif name == "rangefinder":
            scale = np.full(shape, t.max_range)
        else:
            scale = np.broadcast_to(np.asarray(SCALES[name], float), shape).copy()
        big_ex = t.max_distance
        physical = {
            "position_error": np.full(shape, big_ex),
            "heading_error": np.full(shape, math.pi),
            "heading": np.ones(shape),
            "velocity": np.array([lim.max_speed, lim.max_speed, lim.max_yaw_rate]),
            "velocity_error": np.array([lim.max_speed + PREVIEW_SPEED, lim.max_speed + PREVIEW_SPEED,
                                        lim.max_yaw_rate + PREVIEW_SPEED]),
            "reference_preview": np.full(shape, big_ex + float(np.max(t.preview_times)) * PREVIEW_SPEED),
            "goal": np.array([big_ex + 2.0 * getattr(t, "goal_distance", 0.0)] * 2 + [math.pi]),
        }
        if name in physical:
            hi = physical[name].reshape(shape) / scale
            return scale, -hi, hi
        lo, hi = t.observation_bounds()[name]
        return scale, np.broadcast_to(lo, shape) / scale, np.broadcast_to(hi, shape) / scale

    def _observe(self, obs: dict):
        out = collections.OrderedDict()
        for name, value in obs.items():
            lo, hi = self._bounds[name]
            out[name] = np.clip(np.asarray(value) / self._scale[name], lo, hi).astype(np.float32)
        if not self.flat:
            return out
        return np.concatenate([v.ravel() for v in out.values()])

    def decode(self, observation) -> dict:
        """The physical observation dict (the dm_env's units) of a Gymnasium observation."""
        if isinstance(observation, dict):
            items = observation.items()
        else:
            v = np.asarray(observation, dtype=np.float64)
            items, i = [], 0
            for name, (lo, _) in self._bounds.items():
                n = lo.size
                items.append((name, v[i:i + n].reshape(lo.shape)))
                i += n
        return collections.OrderedDict((k, np.asarray(x, np.float64) * self._scale[k]) for k, x in items)

    def physical_action(self, action) -> np.ndarray:
        """The thrust (tau_u [N], tau_r [N m]) of a normalized action (clipped to [-1, 1])."""
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(2), -1.0, 1.0)
        return np.where(a >= 0.0, a * self._high, -a * self._low)

    def normalized_action(self, thrust) -> np.ndarray:
        """The normalized action of a thrust [N, N m] (the inverse of :meth:`physical_action`, clipped)."""
        f = np.asarray(thrust, dtype=np.float64).reshape(2)
        # a channel whose least value is 0 (KVLCC2's surge: the propeller does not pull astern)
        # takes a negative force as 0
        below = np.divide(-f, self._low, out=np.zeros(2), where=self._low < 0.0)
        a = np.where(f >= 0.0, f / self._high, below)
        return np.clip(a, -1.0, 1.0).astype(np.float32)

    # --- gymnasium.Env ---------------------------------------------------------------------------

    def _info(self) -> dict:
        info = self.dm_env.task.info
        info["time"] = float(self.dm_env.physics.time())
        return info

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self.dm_env.reseed(int(seed))
        ts = self.dm_env.reset()
        self._episode_over = False
        return self._observe(ts.observation), self._info()

    def step(self, action):
        """One control step. After the step that ended the episode (terminated or truncated), or
        before the first reset, raises ``gymnasium.error.ResetNeeded``: call reset() first (the
        dm_control environment underneath would start a new episode without saying so)."""
        if getattr(self, "_episode_over", True):
            from gymnasium.error import ResetNeeded

            raise ResetNeeded("USVGymEnv.step: the episode has ended (the last step returned terminated or "
                              "truncated) or was never started; call reset() before step()")
        ts = self.dm_env.step(self.physical_action(action))
        terminated = bool(ts.last() and ts.discount == 0.0)
        truncated = bool(ts.last() and not terminated)
        self._episode_over = terminated or truncated
        return self._observe(ts.observation), float(ts.reward), terminated, truncated, self._info()

    def render(self):
        if self.render_mode is None:
            warnings.warn("USVGymEnv.render: no render_mode was given (use render_mode='rgb_array')",
                          UserWarning, stacklevel=2)
            return None
        if not self.dm_env.history():
            raise RuntimeError("USVGymEnv.render: call reset() first")
        w, h = self.render_size
        return self.dm_env.render_frame(width=w, height=h, camera="top", metadata={"task": self.task_name})

    def close(self):
        if self.dm_env is not None:
            self.dm_env.close()
        super().close()


def gym_env(task: str, seed=None, render_mode=None, **options):
    """A Gymnasium view of :func:`load`: :class:`usv_mj.envs.gymnasium_env.USVGymEnv` (a flat,
    scaled float32 observation and a normalized Box(-1, 1) action by default; see that module).
    The same environments are registered as ``usv_mj/Track-v0`` ... for ``gymnasium.make``
    (:func:`usv_mj.envs.gym_id` of each task). Raises ImportError if gymnasium is not installed."""
    return USVGymEnv(task, seed=seed, render_mode=render_mode, **options)
