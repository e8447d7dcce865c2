"""load(), the environment class, the Gymnasium view and episode records (see :mod:`usv_mj.envs`)."""


from __future__ import annotations

import inspect
import math
import warnings

import numpy as np

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # dm_control's GLFW probe (see usv_mj.obstacles.compose)
    from dm_control.rl import control

from usv_mj.plants.mujoco_plant import MuJoCoPlant
from usv_mj.scenario import Scenario, load_scenario
from usv_mj.simulation import make_environment

from . import ALL_TASKS
from .physics import HarbourEnvPlant, USVPhysics
from .tasks import DEFAULT_PREVIEW, HarbourTask, TrackTask

WAVES_SEA = {"preset": "moderate",
             # compass directions (docs/sea.md): current setting toward 060, wind from the south (180)
             "current": {"speed": 0.3, "toward_deg": 60.0, "sigma": 0.0, "time_constant": 120.0},
             "wind": {"speed": 5.0, "from_deg": 180.0, "gust_sigma": 1.0, "gust_time_constant": 2.0, "seed": 2}}
HARBOUR_FUNNEL = {"rho_xy": [3.0, 0.5], "rate": 0.2}  # as examples/scenarios/harbour_gap.toml



class USVEnvironment(control.Environment):
    """``dm_control.rl.control.Environment`` that owns its plant: :meth:`close` closes it, and a task
    with a per-episode model (harbor) gets a new physics at every :meth:`reset` after the first."""

    def __init__(self, physics, task, *, time_limit, n_sub_steps, rebuild=None):
        super().__init__(physics, task, time_limit=time_limit, n_sub_steps=n_sub_steps)
        self._rebuild = rebuild
        self._fresh = True
        self._closed = False

    def reset(self):
        if self._closed:
            raise RuntimeError("USVEnvironment: the environment is closed")
        if self._rebuild is not None and not self._fresh:
            old = self._physics
            self._physics = self._rebuild()
            self._physics.legacy_step = old.legacy_step
            old.close()
        self._fresh = False
        return super().reset()

    def step(self, action):
        if self._closed:
            raise RuntimeError("USVEnvironment: the environment is closed")
        return super().step(action)

    def close(self):
        if not self._closed:
            self._closed = True
            self._physics.close()


def _scenario(task: str, options: dict, duration: float) -> Scenario:
    scenario = options.pop("scenario", None)
    preset = options.pop("preset", "paper")
    overrides = options.pop("overrides", None) or {}
    cp = options.pop("control_period", 0.01)
    sub = options.pop("substeps", 10)
    if scenario is not None:
        if not isinstance(scenario, Scenario):
            raise TypeError(f"usv_mj.envs.load: scenario must be a usv_mj.scenario.Scenario, got {type(scenario).__name__}")
        return scenario
    base = {"control_period": cp, "plant": {"kind": "mujoco", "substeps": sub}, "duration": duration}
    if task == "track_waves":
        base["sea"] = WAVES_SEA
    if task == "harbor":
        base["funnel"] = HARBOUR_FUNNEL
        base["trajectory"] = {"kind": "waypoints", "points": [[0.0, 0.0], [40.0, 0.0]], "speed": 0.6}
        base["initial"] = {"eta": [0.0, 0.0, 0.0]}
    return load_scenario(preset=preset, overrides=_nested_merge(base, overrides))


def _nested_merge(a: dict, b: dict) -> dict:
    """``a`` with ``b`` merged in, tables recursively (``b`` wins)."""
    out = dict(a)
    for key, value in b.items():
        out[key] = _nested_merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) \
            else value
    return out


def _plant_supports_sea() -> bool:
    return "environment" in inspect.signature(MuJoCoPlant.__init__).parameters


def load(task: str, seed=None, **options) -> USVEnvironment:
    """A new environment for ``task`` (one of :data:`ALL_TASKS`) seeded with ``seed`` (an int, a
    ``numpy.random.RandomState`` or None for fresh entropy); options: see the module docstring.

    Raises ValueError for an unknown task or option, NotImplementedError for ``track_waves`` when
    the MuJoCo plant does not take a sea state.
    """
    if task not in ALL_TASKS:
        raise ValueError(f"usv_mj.envs.load: unknown task {task!r}; tasks: {', '.join(ALL_TASKS)}")
    options = dict(options)
    default_duration = 90.0 if task == "harbor" else 30.0
    duration = float(options.pop("duration", default_duration))
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"usv_mj.envs.load: duration must be a finite number > 0 s, got {duration!r}")
    preview = tuple(options.get("preview_times", DEFAULT_PREVIEW))
    scenario = _scenario(task, options, duration + max(preview) + 1.0)
    if scenario.plant.kind != "mujoco":
        scenario = scenario.with_overrides({"plant": {"kind": "mujoco"}})
    task_kw = {k: options.pop(k) for k in ("quantize", "max_surge_force", "max_yaw_moment", "preview_times",
                                           "start_offset", "max_distance") if k in options}
    cp, sub = scenario.control_period, scenario.plant.substeps
    environment = None
    if not scenario.sea.calm:
        if not _plant_supports_sea():
            raise NotImplementedError(f"usv_mj.envs.load({task!r}): the MuJoCo plant does not take a sea state yet "
                                      "(MuJoCoPlant has no 'environment' argument)")
        environment = make_environment(scenario, duration + max(preview) + 1.0)
    n_steps = round(duration / cp)
    time_limit = n_steps * cp
    if task in ("track", "track_waves"):
        if options:
            raise ValueError(f"usv_mj.envs.load({task!r}): unknown options {sorted(options)}")
        kwargs = {} if environment is None else {"environment": environment}
        plant = MuJoCoPlant(scenario.ship, scenario.disturbance, cp, sub, **kwargs)
        tsk = TrackTask(scenario, random=seed, **task_kw)
        return USVEnvironment(USVPhysics.from_plant(plant), tsk, time_limit=time_limit, n_sub_steps=sub)
    # harbor
    harbour_kw = {k: options.pop(k) for k in ("n_rays", "max_range", "goal_radius") if k in options}
    goal_distance = float(options.pop("goal_distance", 40.0))
    if options:
        raise ValueError(f"usv_mj.envs.load('harbor'): unknown options {sorted(options)}")
    tsk = HarbourTask(scenario, margin_m=scenario.guidance.margin_m, random=seed, **harbour_kw, **task_kw)

    def build():
        from usv_mj.obstacles.clearance import MuJoCoClearance

        from .layout import harbour_layout

        layout = harbour_layout(tsk.random, scenario, scenario.guidance, duration, goal_distance)
        kwargs = {} if environment is None else {"environment": environment}
        plant = HarbourEnvPlant(scenario.ship, scenario.disturbance, layout.obstacles, cp, sub,
                                ray_angles=tsk.ray_angles, **kwargs)
        tsk.attach_layout(layout, MuJoCoClearance(plant))
        return USVPhysics.from_plant(plant)

    return USVEnvironment(build(), tsk, time_limit=time_limit, n_sub_steps=sub, rebuild=build)


def gym_env(task: str, seed=None, render_mode=None, **options):
    """A Gymnasium view of :func:`load` through shimmy's ``DmControlCompatibilityV0`` (observations a
    dict of arrays, action the thrust box). Raises ImportError if shimmy is not installed."""
    try:
        from shimmy.dm_control_compatibility import DmControlCompatibilityV0
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError("usv_mj.envs.gym_env needs shimmy[dm-control] (pip install 'shimmy[dm-control]')") from exc
    return DmControlCompatibilityV0(load(task, seed=seed, **options), render_mode=render_mode)


def episode_record(env, steps, metadata=None):
    """A :class:`usv_mj.record.RunRecord` of an episode for the renderer (``usv_mj.render.render_run``).

    ``steps``: a list of (t, state (6), reference (7), action (2), thrust (2)) rows, as collected by
    :func:`usv_mj.envs.cli.rollout`. The diagnostics the HUD shows are filled from the task: e1, e2 =
    x - x_d, y - y_d [m] (the hull origin, not the controller's offset point), e3 = wrap(psi - psi_d),
    rho1 = rho2 = rho_xy(t), rho3 = rho_psi(t) and z_i = e_i / rho_i; the controller's own adaptive
    states are not known here (NaN).
    """
    from usv_mj.ship import wrap_angle as wrap
    from usv_mj.record import COLUMNS, RunRecord

    n = len(steps)
    cols = {name: np.full(n, np.nan) for name in COLUMNS}
    for i, (t, x, ref, a, q) in enumerate(steps):
        cols["t"][i] = t
        for j, name in enumerate(("x", "y", "psi", "u", "v", "r")):
            cols[name][i] = x[j]
        for j, name in enumerate(("x_d", "y_d", "psi_d", "x_d_dot", "y_d_dot", "r_d", "u_d")):
            cols[name][i] = ref[j]
        cols["tau_u"][i], cols["tau_r"][i] = a
        cols["q_tau_u"][i], cols["q_tau_r"][i] = q
        rxy, rpsi = float(env.task.funnel_xy(t)), float(env.task.funnel_psi(t))
        e = (x[0] - ref[0], x[1] - ref[1], wrap(x[2] - ref[2]))
        for j, rho in enumerate((rxy, rxy, rpsi)):
            cols[f"e{j + 1}"][i] = e[j]
            cols[f"rho{j + 1}"][i] = rho
            cols[f"z{j + 1}"][i] = e[j] / rho
    meta = {"plant": "mujoco", "controller": "env", "control_period_s": env.control_timestep()}
    meta.update(metadata or {})
    return RunRecord.from_arrays(cols, metadata=meta)
