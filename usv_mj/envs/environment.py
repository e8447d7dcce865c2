"""load(), the environment class, the Gymnasium view and episode records (see :mod:`usv_mj.envs`)."""


from __future__ import annotations

import collections
import copy
import dataclasses
import math
import warnings
import weakref

import dm_env
import numpy as np

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # dm_control's GLFW probe (see usv_mj.scene.compose)
    from dm_control.rl import control
from dm_env import specs

from usv_mj.builder import channels_of
from usv_mj.core import arguments
from usv_mj.core.errors import UnknownKindError, expected
from usv_mj.core.registry import TASKS
from usv_mj.scenario.spec import Scenario, ScenarioError, load_scenario, merge_tables

from usv_mj.envs.tasks import DEFAULT_PREVIEW

#: keys of ``environment_kwargs`` (as ``dm_control.suite.load``'s): control.Environment's own options
ENVIRONMENT_KWARGS = ("time_limit", "flat_observation", "legacy_step")


class USVEnvironment(control.Environment):
    """``dm_control.rl.control.Environment`` that owns its plant: :meth:`close` closes it, and a task
    with a per-episode model (harbor) gets a new physics at every :meth:`reset` after the first (and
    at the first after :meth:`reseed`).

    With ``flat_observation=True`` the observation is one float64 vector ``observations``: the
    task's observations flattened and concatenated in :meth:`TrackTask.observation_shapes` order
    (:meth:`observation_layout` gives each one's slice and shape).

    It keeps the last :data:`usv_mj.envs.rendering.HISTORY_ROWS` steps of the episode (time, state,
    reference, action, thrust: :meth:`history`) for its pictures: :meth:`render_frame`, which its
    physics' ``render()`` and the Gymnasium view's ``render()`` draw through."""

    def __init__(self, physics, task, *, time_limit, n_sub_steps, rebuild=None, flat_observation=False,
                 legacy_step=True):
        from usv_mj.envs.rendering import HISTORY_ROWS

        super().__init__(physics, task, time_limit=time_limit, n_sub_steps=n_sub_steps,
                         flat_observation=flat_observation, legacy_step=legacy_step)
        self._rebuild = rebuild
        self._fresh = True
        self._closed = False
        self._history = collections.deque(maxlen=HISTORY_ROWS)
        self._frames = None
        physics.owner = weakref.ref(self)
        self._fusable = hasattr(task, "fused_kernels") and hasattr(task, "observation_dict")

    @property
    def flat_observation(self) -> bool:
        return bool(self._flat_observation)

    def observation_layout(self) -> dict:
        """name -> (slice, shape) of each observation in the flat vector."""
        return {name: (part, shape) for name, part, shape, _ in self._task.observation_views()}

    def unflatten(self, observation) -> dict:
        """The observation as a dict of arrays (a flat ``observations`` vector is split by
        :meth:`observation_layout`; a dict is returned as is)."""
        if "observations" not in observation:
            return observation
        v = np.asarray(observation["observations"])
        return collections.OrderedDict((k, v[sl].reshape(shape)) for k, (sl, shape) in self.observation_layout().items())

    def observation_spec(self):
        spec = self._task.observation_spec(self._physics)
        if not self._flat_observation:
            return spec
        n = sum(int(np.prod(s.shape)) for s in spec.values())
        return collections.OrderedDict(observations=specs.Array((n,), np.float64, name="observations"))

    def reseed(self, seed) -> None:
        """A new random state for the task (an int, a RandomState or None); the next :meth:`reset`
        draws its episode (start, harbour layout) from it, the first one included."""
        self._task._random = seed if isinstance(seed, np.random.RandomState) else np.random.RandomState(seed)
        self._fresh = False

    def reset(self):
        if self._closed:
            raise RuntimeError("USVEnvironment: the environment is closed")
        if self._rebuild is not None and not self._fresh:
            old = self._physics
            self._physics = self._rebuild()
            self._physics.legacy_step = old.legacy_step
            self._physics.owner = weakref.ref(self)
            old.close()
        self._fresh = False
        ts = super().reset()
        self._history.clear()
        self._remember()
        return ts

    def step(self, action):
        """``dm_control.rl.control.Environment.step``; when the task can do its part (before_step,
        the physics step, after_step, the reward and the observation vector) in one call
        (:meth:`_fused_step`), that call and dm_control's bookkeeping after it (step
        limit, discount, TimeStep) instead. Then the step is kept for :meth:`render_frame` and the
        time limit noted in the task's :attr:`~TrackTask.info`."""
        if self._closed:
            raise RuntimeError("USVEnvironment: the environment is closed")
        task, physics = self._task, self._physics
        fused = None
        if self._fusable and not self._reset_next_step:
            fused = self._fused_step(action)
        if fused is None:
            ts = super().step(action)
            if ts.first():   # it reset (after a last step): reset() kept the step
                return ts
        else:
            reward, vector = fused
            observation = collections.OrderedDict([(control.FLAT_OBSERVATION_KEY, vector)]) \
                if self._flat_observation else task.observation_dict(vector)
            self._step_count += 1
            discount = 1.0 if self._step_count >= self._step_limit else task.get_termination(physics)
            if discount is None:
                ts = dm_env.TimeStep(dm_env.StepType.MID, reward, 1.0, observation)
            else:
                self._reset_next_step = True
                ts = dm_env.TimeStep(dm_env.StepType.LAST, reward, discount, observation)
        self._remember()
        if ts.last() and ts.discount == 1.0:
            task.mark_time_limit(physics.time())
        return ts

    def _fused_step(self, action):
        """before_step, physics.step, after_step, get_reward and the observation vector in one native
        call: the task gives the parts (:meth:`TrackTask.fused_kernels`), the physics steps
        (:meth:`USVPhysics.step_native`); (reward, observation vector), or None with nothing done
        when the task cannot fuse this step."""
        task, physics = self._task, self._physics
        f = task.fused_kernels(physics, self._n_sub_steps)
        if f is None:
            return None
        a0, a1 = task.fused_action(action, physics)
        ev, t = physics.step_native(f.plant_kernel, task.fused_native, f, a0, a1, physics)
        return task.fused_result(ev, t, physics)

    def _remember(self) -> None:
        self._history.append(step_row(self))

    def history(self) -> list:
        """The episode's last steps: (t [s], state (6), reference (7), action (2), thrust (2),
        command (2), saturated (2)) rows, oldest first, as :func:`episode_record` takes them (empty
        before the first :meth:`reset`): the thrust is the actuators' force the plant got, the
        command the quantizer's output they were given."""
        return list(self._history)

    def render_frame(self, *, width: int = 320, height: int = 240, camera: str = "top",
                     metadata=None) -> np.ndarray:
        """The picture of the current step, (height, width, 3) uint8, by the project's renderer
        (:mod:`usv_mj.envs.rendering`): the hull on the episode's sea, its wake, the path ahead, the
        funnel and the harbour's obstacles, with the heads-up overlay. ``camera``: "top" (follows the
        hull from above, north up) or a camera of models/scene.xml ("chase", "overview", "chart").
        Before the first :meth:`reset` it shows the hull where the physics has it. ``metadata``:
        extra record metadata (e.g. ``{"task": name}``)."""
        from usv_mj.envs.rendering import FrameSource

        if self._closed:
            raise RuntimeError("USVEnvironment: the environment is closed")
        rows = self.history()
        if not rows:
            ph = self._physics
            rows = [(ph.time(), ph.state.copy(), np.full(7, np.nan), np.zeros(2), np.zeros(2))]
        if self._frames is None:
            self._frames = FrameSource()
        record = episode_record(self, rows, metadata)
        return self._frames.frame(record, width=width, height=height, camera=camera)

    def scene_xml(self) -> str:
        """The MJCF text of the scene this environment's physics runs (the composed harbour with its
        obstacles and rangefinders, or the hull alone): the file the plant loaded is a temporary
        copy that :meth:`close` removes, so keep this text to keep the scene. MuJoCo alone sees no
        water in it: :func:`usv_mj.attach_hydrodynamics` attaches the hull forces."""
        if self._closed:
            raise RuntimeError("USVEnvironment: the environment is closed")
        return self._physics.plant.scene_xml()

    def close(self):
        if not self._closed:
            self._closed = True
            try:
                if self._frames is not None:
                    self._frames.close()
                    self._frames = None
            finally:
                self._physics.close()


#: the options of :func:`load` every task takes (the scenario's), beside the task's own typed options
SCENARIO_OPTIONS = ("scenario", "preset", "overrides", "vessel", "control_period", "substeps")
DEFAULT_DURATION = 30.0  # s: the episode of a task whose options have no ``duration``


def _scenario(task: str, entry, options: dict, duration: float) -> Scenario:
    """The episode's scenario (:mod:`usv_mj.envs.suite`: the factory's contract): ``scenario`` as
    is, else the preset, the task's tables (``entry.scenario``) and the user's overrides."""
    from usv_mj.scenario.overrides import with_vessel

    scenario = options.pop("scenario", None)
    preset = options.pop("preset", "paper")
    overrides = options.pop("overrides", None) or {}
    vessel = options.pop("vessel", None)
    cp = options.pop("control_period", 0.01)
    sub = options.pop("substeps", 10)
    if vessel is not None and not isinstance(vessel, str):
        raise ValueError(f"usv_mj.envs.load({task!r}): vessel must be a vessel kind (a string: "
                         f"`usv-mj kinds vessel`, a data file or 'module:Name'), got {vessel!r}")
    if scenario is not None:
        if not isinstance(scenario, Scenario):
            raise TypeError(f"usv_mj.envs.load: scenario must be a usv_mj.scenario.spec.Scenario, got {type(scenario).__name__}")
        if vessel is not None:
            raise ValueError(f"usv_mj.envs.load({task!r}): vessel={vessel!r} with a ready scenario: give the "
                             f"vessel in the scenario ([vessel] kind) or drop scenario")
        return scenario
    if not isinstance(overrides, dict):
        raise ValueError(f"usv_mj.envs.load({task!r}): overrides must be a dict of scenario tables, got {overrides!r}")
    overrides = with_vessel(vessel, overrides)  # --vessel's own shorthand: [vessel] kind, its options kept
    base = {"control_period": cp, "plant": {"kind": "mujoco", "substeps": sub}, "duration": duration}
    base = merge_tables(base, copy.deepcopy(entry.scenario))  # the task's own tables (its sea, its harbour)
    try:
        return load_scenario(preset=preset, overrides=merge_tables(base, overrides))
    except ScenarioError as exc:
        if "waves" in entry.tags and "[sea]" in str(exc):   # the task's own sea: a user cannot remove it
            calm = [k for k in TASKS.kinds() if k not in TASKS.tagged("waves")]
            raise type(exc)(f"{exc}; the task {task!r} is in a sea: the calm tasks are {', '.join(calm)}") from None
        raise


def task_entry(task: str):
    """The registry entry of ``task`` (:data:`usv_mj.core.registry.TASKS`); ValueError naming the tasks."""
    if not isinstance(task, str) or task not in TASKS:
        raise ValueError(f"usv_mj.envs.load: unknown task {task!r}; tasks: {', '.join(TASKS.kinds())}"
                         + (" (or 'package.module:factory')" if isinstance(task, str) and ":" not in task else ""))
    try:
        return TASKS.get(task, "usv_mj.envs.load")
    except UnknownKindError as exc:   # an entry point or module:Name that cannot be imported
        raise ValueError(str(exc)) from None


def load(task: str, seed=None, *, task_kwargs=None, environment_kwargs=None, flat_observation: bool = False,
         **options) -> USVEnvironment:
    """A new environment for ``task`` (a kind of :data:`usv_mj.core.registry.TASKS`: "track",
    "track_waves", "harbor", "harbor_waves", a task registered by its own module, or
    "package.module:factory") seeded with ``seed`` (an int, a ``numpy.random.RandomState`` or None
    for fresh entropy); options: see the module docstring of :mod:`usv_mj.envs` (the task's own are
    its options dataclass's fields: ``usv-mj kinds task``).

    As ``dm_control.suite.load``: ``task_kwargs`` (a dict, merged into the options),
    ``environment_kwargs`` (``time_limit`` [s] = the episode length, ``flat_observation``,
    ``legacy_step``) and ``flat_observation`` (one concatenated ``observations`` vector).

    Raises ValueError for an unknown task, option or vessel.
    """
    if not isinstance(task, str):
        raise expected("usv_mj.envs.load", "task", f"a task name ({', '.join(TASKS.kinds())})", task)
    entry = task_entry(task)
    if seed is not None and not isinstance(seed, np.random.RandomState):
        arguments.integer("usv_mj.envs.load", "seed", seed, 0, "an integer >= 0, a numpy.random.RandomState or None")
    arguments.mapping_or_none("usv_mj.envs.load", "task_kwargs", task_kwargs, "a dict of task options or None")
    arguments.mapping_or_none("usv_mj.envs.load", "environment_kwargs", environment_kwargs,
                              "a dict (time_limit, flat_observation, legacy_step) or None")
    options = {**(task_kwargs or {}), **options}
    env_kw = dict(environment_kwargs or {})
    unknown = sorted(set(env_kw) - set(ENVIRONMENT_KWARGS))
    if unknown:
        raise ValueError(f"usv_mj.envs.load({task!r}): unknown environment_kwargs {unknown}; "
                         f"known: {', '.join(ENVIRONMENT_KWARGS)}")
    flat = bool(env_kw.pop("flat_observation", flat_observation))
    legacy_step = bool(env_kw.pop("legacy_step", True))
    if "time_limit" in env_kw:
        options.setdefault("duration", env_kw.pop("time_limit"))
    option_class = entry.options_class
    fields = {f.name for f in dataclasses.fields(option_class)} if option_class is not None else set()
    unknown = sorted(set(options) - fields - set(SCENARIO_OPTIONS) - {"duration"})
    if unknown:
        raise ValueError(f"usv_mj.envs.load({task!r}): unknown options {unknown}; the task's: "
                         f"{', '.join(sorted(fields)) or 'none'}; every task's: {', '.join(SCENARIO_OPTIONS)}")
    if "duration" in options and not arguments.is_real(options["duration"]):
        raise expected("usv_mj.envs.load", "duration", "a number of seconds > 0", options["duration"])
    own = {k: options.pop(k) for k in list(options) if k in fields}
    try:
        typed = option_class(**own) if option_class is not None else None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"usv_mj.envs.load({task!r}): {exc}") from None
    duration = getattr(typed, "duration", options.pop("duration", DEFAULT_DURATION))
    if not arguments.is_real(duration):
        raise expected("usv_mj.envs.load", "duration", "a number of seconds > 0", duration)
    duration = float(duration)
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"usv_mj.envs.load: duration must be a finite number > 0 s, got {duration!r}")
    preview = tuple(getattr(typed, "preview_times", DEFAULT_PREVIEW))
    scenario = _scenario(task, entry, options, duration + max(preview) + 1.0)
    if scenario.plant.kind != "mujoco":
        scenario = scenario.with_overrides({"plant": {"kind": "mujoco"}})
    cp, sub = scenario.control_period, scenario.plant.substeps
    time_limit = round(duration / cp) * cp
    env_kw = {"time_limit": time_limit, "n_sub_steps": sub, "flat_observation": flat, "legacy_step": legacy_step}
    return entry.make(typed, scenario, random=seed, environment_kwargs=env_kw)


def step_row(env) -> tuple:
    """The row of the environment's present step, as :func:`episode_record` takes it: (t [s], state
    (6), reference (7), action (2), thrust (2), command (2), saturated (2)), copies."""
    task, ph = env.task, env.physics
    t = ph.time()
    return (t, ph.state.copy(), task.reference_at(t).copy(), task.last_action.copy(), task.last_thrust.copy(),
            task.last_command.copy(), task.last_saturated.copy())


def episode_record(env, steps, metadata=None):
    """A :class:`usv_mj.record.run_record.RunRecord` of an episode for the renderer (``usv_mj.outputs.render.render_run``).

    ``steps``: a list of (t, state (6), reference (7), action (2), thrust (2)[, command (2),
    saturated (2)]) rows, as collected by :func:`usv_mj.cli.env.rollout` (without the last two,
    the command is taken to be the thrust and nothing saturated: the paper's unlimited actuators).
    The record declares the funnel block (:data:`usv_mj.controllers.base.FUNNEL_FIELDS`), filled
    from the task: e1, e2 = x - x_d, y - y_d [m] (the hull origin, not the controller's offset
    point), e3 = wrap(psi - psi_d), rho1 = rho2 = rho_xy(t), rho3 = rho_psi(t) and z_i = e_i /
    rho_i. ``tau`` is the clipped action, ``q_tau`` the quantized command, ``f`` the actuators'
    force the plant got and ``sat`` their saturation flags. The metadata carry the episode's
    scenario (its sea and, in the harbor, the layout's obstacles, and its vessel), so the video
    shows the water, the harbour and the vessel's hull.
    """
    from usv_mj.core.layouts import FUNNEL_FIELDS
    from usv_mj.record.run_record import CORE_COLUMNS, RunRecord
    from usv_mj.physics.ship import wrap_angle as wrap

    task = env.task
    n = len(steps)
    cols = {name: np.full(n, np.nan) for name in CORE_COLUMNS + FUNNEL_FIELDS}
    for i, (t, x, ref, a, f, *more) in enumerate(steps):
        q, sat = (more[0], more[1]) if len(more) >= 2 else (f, (0.0, 0.0))
        cols["t"][i] = t
        for j, name in enumerate(("x", "y", "psi", "u", "v", "r")):
            cols[name][i] = x[j]
        for j, name in enumerate(("x_d", "y_d", "psi_d", "x_d_dot", "y_d_dot", "r_d", "u_d")):
            cols[name][i] = ref[j]
        cols["tau_u"][i], cols["tau_r"][i] = a
        cols["q_tau_u"][i], cols["q_tau_r"][i] = q
        cols["f_u"][i], cols["f_r"][i] = f
        cols["sat_u"][i], cols["sat_r"][i] = sat
        rxy, rpsi = float(task.funnel_xy(t)), float(task.funnel_psi(t))
        e = (x[0] - ref[0], x[1] - ref[1], wrap(x[2] - ref[2]))
        for j, rho in enumerate((rxy, rxy, rpsi)):
            cols[f"e{j + 1}"][i] = e[j]
            cols[f"rho{j + 1}"][i] = rho
            cols[f"z{j + 1}"][i] = e[j] / rho
    scenario = getattr(task, "episode_scenario", None) or task.scenario
    meta = {"plant": "mujoco", "controller": "env", "control_period_s": env.control_timestep(),
            "duration_s": float(steps[-1][0]) if steps else 0.0, "scenario": scenario.to_dict(),
            "diagnostic_fields": list(FUNNEL_FIELDS), "channels": channels_of(scenario).to_metadata()}
    meta.update(metadata or {})
    return RunRecord.from_arrays(cols, metadata=meta, diagnostic_fields=FUNNEL_FIELDS)
