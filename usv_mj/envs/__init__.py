"""The USV as dm_control tasks, for learning and benchmarking controllers.

Public API::

    from usv_mj import envs
    env = envs.load("track", seed=0)              # a dm_control.rl.control.Environment
    policy = envs.PPCPolicy(env)                  # the paper's controller as a policy
    ts = env.reset()
    while not ts.last():
        ts = env.step(policy(ts))
    env.task.info                                  # why the episode ended
    env.close()

Tasks (:data:`ALL_TASKS`; the observation, action, reward and termination conventions are in
:mod:`usv_mj.envs.tasks`):

- ``track``: follow the paper's reference (docs/model.md §4) from a start drawn uniformly within
  +-(3 m, 3 m, 0.5 rad) of its pose at t = 0, at rest; 30 s episodes, control period 0.01 s
  (10 RK4 steps of 1 ms), the paper preset's ship, disturbance, funnel and quantizer.
- ``track_waves``: the same in the ``moderate`` sea (docs/sea.md §3: JONSWAP Hs 0.2 m, Tp 2 s, from
  the west) with a 0.3 m/s current (setting toward compass 060, 30 deg counter-clockwise from +x) and a
  5 m/s wind (from the south, blowing toward +y; gusts sigma 1 m/s).
- ``harbor``: from the origin to a goal 40 m ahead through a randomised harbour (two piers with a
  gap, a buoy field; a new layout every episode) without contact; the observed reference is the
  guidance plan; 16 rangefinders fan around the hull; 90 s episodes.

Options of :func:`load` (keyword arguments): ``scenario`` (a :class:`usv_mj.scenario.Scenario`
used as is), else ``preset`` ("paper") and ``overrides`` (a nested dict as in scenario files);
``control_period`` [s] (0.01), ``substeps`` (10), ``duration`` [s] (30 / 90), ``quantize`` (True),
``max_surge_force`` [N] (1000), ``max_yaw_moment`` [N m] (1000), ``preview_times`` [s],
``start_offset`` (track), ``max_distance`` [m] (50), harbor: ``n_rays`` (16), ``max_range`` [m] (20),
``goal_radius`` [m] (1.5), ``goal_distance`` [m] (40).

The physics is the MuJoCo plant itself (:class:`usv_mj.envs.physics.USVPhysics` is a
``dm_control.mujoco.Physics`` over the plant's own mjModel/mjData), so a policy sees exactly what
``usv-mj run --plant mujoco`` integrates, with the same hydrodynamic callback. Close environments
with ``env.close()`` (the plant unmarks its mjData; the global callback goes with the last plant).

A Gymnasium view: :func:`gym_env` (shimmy's ``DmControlCompatibilityV0``).
"""

from __future__ import annotations

import importlib

ALL_TASKS = ("track", "track_waves", "harbor")

_WHERE = {
    "load": "environment", "gym_env": "environment", "episode_record": "environment",
    "USVEnvironment": "environment", "PPCPolicy": "policies", "RandomPolicy": "policies",
    "TrackTask": "tasks", "HarbourTask": "tasks", "USVPhysics": "physics", "HarbourEnvPlant": "physics",
}

__all__ = ["ALL_TASKS", "HarbourEnvPlant", "HarbourTask", "PPCPolicy", "RandomPolicy", "TrackTask", "USVEnvironment",
           "USVPhysics", "episode_record", "gym_env", "load"]


def __getattr__(name: str):
    """Names are imported on first use, so ``usv-mj --help`` does not import dm_control."""
    if name not in _WHERE:
        raise AttributeError(f"module 'usv_mj.envs' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
