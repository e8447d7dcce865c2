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

Tasks: the kinds of the registry :data:`usv_mj.core.registry.TASKS` (``ALL_TASKS`` reads it), each
registered by a decorator on its factory with its typed options and its tags, as dm_control's suite
registers its own (:mod:`usv_mj.envs.suite`; a task of your own registers the same way and is then
a task of :func:`load`, of ``gymnasium.make`` and of ``usv-mj env``). The observation, action,
reward and termination conventions are in :mod:`usv_mj.envs.tasks`. The built-in ones:

- ``track``: follow the paper's reference (docs/model.md §4) from a start drawn uniformly within
  +-(3 m, 3 m, 0.5 rad) of its pose at t = 0, at rest; 30 s episodes, control period 0.01 s
  (10 RK4 steps of 1 ms), the paper preset's ship (or ``vessel``), disturbance, funnel and quantizer.
- ``track_waves``: the same in the ``moderate`` sea (docs/sea.md §3: JONSWAP Hs 0.2 m, Tp 2 s, from
  the west) with a 0.3 m/s current (setting toward compass 060, 30 deg counter-clockwise from +x) and a
  5 m/s wind (from the south, blowing toward +y; gusts sigma 1 m/s).
- ``harbor``: from the origin to a goal 40 m ahead through a randomised harbour (two piers with a
  gap, a buoy field; a new layout every episode) without contact; the observed reference is the
  guidance plan; 16 rangefinders fan around the hull; 90 s episodes.
- ``harbor_waves``: the harbour in the sea of ``track_waves``.

Options of :func:`load` (keyword arguments): ``scenario`` (a :class:`usv_mj.scenario.spec.Scenario`
used as is), else ``preset`` ("paper") and ``overrides`` (a nested dict as in scenario files);
``vessel`` (a vessel kind of :data:`usv_mj.core.registry.VESSELS`: "paper", "cybership2", "otter",
"clarke83", a vessel data file or "module:Name"; what ``usv-mj run --vessel`` gives, its options
in ``overrides={"vessel": {...}}``): the task runs that hull, its rigid body and hydrodynamics in
the plant, its actuators between the action and the plant (the action bounds are their limits),
its nominal model in :class:`PPCPolicy` and its hull in the pictures; the reference is the
scenario's, as in a run; on a ruddered vessel ("kvlcc2": its channels are n_P and the rudder angle) the action
is allocated to the propeller and the rudder (usv_mj.physics.mmg.mmg_allocate), as a force controller's in a run;
``control_period`` [s] (0.01), ``substeps`` (10), ``duration`` [s] (30 / 90), ``quantize`` (True),
``max_surge_force`` [N] and ``max_yaw_moment`` [N m] (1000: the action bounds of channels whose
actuators are unlimited; ``scenario.actuators`` limits win where finite), ``preview_times`` [s],
``start_offset`` (track), ``max_distance`` [m] (50), harbor: ``n_rays`` (16), ``max_range`` [m] (20),
``goal_radius`` [m] (1.5), ``goal_distance`` [m] (40, in [30, 500]: a ValueError outside). As ``dm_control.suite.load``:
``task_kwargs``, ``environment_kwargs`` (``time_limit``, ``flat_observation``, ``legacy_step``) and
``flat_observation=True`` (one ``observations`` vector; ``env.unflatten(obs)`` splits it).

The plant is made by :func:`usv_mj.build.make_plant`, the one constructor of plants (the harbour's
rangefinders are an option of the composed scene), so a policy sees exactly what ``usv-mj run
--plant mujoco`` integrates, with the same hydrodynamic callback and sea;
:class:`usv_mj.envs.physics.USVPhysics` is a ``dm_control.mujoco.Physics`` over the plant's own
mjModel/mjData. Close environments with ``env.close()`` (the plant unmarks its mjData; the global
callback goes with the last plant). Pictures: ``env.physics.render()`` (dm_control's signature,
what shimmy's ``DmControlCompatibilityV0`` calls), ``env.render_frame()`` and the Gymnasium view's
``render()`` all draw through the project's renderer (:mod:`usv_mj.envs.rendering`), headless, with
the water.

A Gymnasium view: :func:`gym_env`, and an id per task (:func:`gym_id`; ``GYM_IDS`` maps them
back: ``usv_mj/Track-v0``, ``usv_mj/TrackWaves-v0``, ``usv_mj/Harbor-v0``,
``usv_mj/HarborWaves-v0``, and ``usv_mj/MyTask-v0`` for a task ``my_task``), registered when this
package is imported (a task registered later: when it registers) (if gymnasium is installed), for ``gymnasium.make`` (an installed wheel imports it
when gymnasium is imported: :mod:`usv_mj.envs.gymnasium_hook`); flat scaled observations
and normalized actions: :mod:`usv_mj.envs.gymnasium_env`.

Traffic (issue 35): ``usv_mj/Encounter-v0`` (:data:`ENV_IDS`, registered beside them;
:class:`EncounterEnv`, :mod:`usv_mj.envs.encounter_env`) is the own ship among other vessels (an
Imazu case or a scenario with ``[[vessels]]``), and :func:`traffic_parallel_env`
(:class:`TrafficParallelEnv`, :mod:`usv_mj.envs.traffic_parallel`) the PettingZoo ``ParallelEnv``
in which every vessel is an agent; both on :mod:`usv_mj.envs.traffic`.

Many episodes in one call: ``gymnasium.make_vec("usv_mj/Track-v0", num_envs=N)`` (the vector view,
:mod:`usv_mj.envs.gymnasium_vector`; ``plant="analytic"`` for the native RK4 of the same hull),
:func:`load_batch` for dm_env users (arrays of TimeStep fields, :mod:`usv_mj.envs.batch`) and
:class:`usv_mj.envs.sb3_vec.USVSB3VecEnv` for stable-baselines3: the same batch, stepped natively.
"""

from __future__ import annotations

import re

from usv_mj.core.lazy_names import lazy_names
from usv_mj.core.registry import TASKS

#: Gymnasium id -> entry point of the environments that are their own ``gymnasium.Env``, not a task's
#: view (a task of :data:`TASKS` is a dm_control environment of one hull on the MuJoCo plant; these run
#: a fleet on either plant): ``usv_mj/Encounter-v0``, the own ship among other vessels
#: (:mod:`usv_mj.envs.encounter_env`)
ENV_IDS = {"usv_mj/Encounter-v0": "usv_mj.envs.encounter_env:EncounterEnv"}

_WHERE = {
    "load": "environment", "gym_env": "gymnasium_env", "episode_record": "environment",
    "USVEnvironment": "environment", "PPCPolicy": "policies", "RandomPolicy": "policies",
    "TrackTask": "tasks", "HarbourTask": "tasks", "USVPhysics": "physics", "USVGymEnv": "gymnasium_env",
    "EncounterEnv": "encounter_env", "TrafficParallelEnv": "traffic_parallel", "traffic_parallel_env": "traffic_parallel",
    "load_batch": "batch", "TrackBatch": "batch", "USVVectorEnv": "gymnasium_vector", "USVSB3VecEnv": "sb3_vec",
}

__all__ = ["ALL_TASKS", "ENV_IDS", "EncounterEnv", "GYM_IDS", "HarbourTask", "PPCPolicy", "RandomPolicy", "TASKS",
           "TrackBatch", "TrackTask", "TrafficParallelEnv", "USVEnvironment", "USVGymEnv", "USVPhysics", "USVVectorEnv",
           "episode_record", "gym_env", "gym_id", "load", "load_batch", "traffic_parallel_env"]

_GYM_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9]*(?:[_-][A-Za-z0-9]+)*$")


def gym_id(task: str) -> str | None:
    """The Gymnasium id of ``task``: ``usv_mj/`` + its words capitalised + ``-v0`` ("track_waves" ->
    "usv_mj/TrackWaves-v0"); None for a kind that is no plain name ("package.module:factory")."""
    if not _GYM_NAME.match(task):
        return None
    return "usv_mj/" + "".join(w[:1].upper() + w[1:] for w in re.split(r"[_-]", task)) + "-v0"


def gym_ids() -> dict:
    """Gymnasium id -> task, for every task of :data:`TASKS` (the built-in ones, those registered
    since and the entry points of the group ``usv_mj.tasks``)."""
    return {gym_id(k): k for k in TASKS.kinds() if gym_id(k) is not None}


def register_gymnasium(tasks=None) -> None:
    """Register the Gymnasium ids of ``tasks`` (default: every task of :data:`TASKS` and the ids of
    :data:`ENV_IDS`; a task registered later is added when it registers) with Gymnasium's registry when gymnasium is
    installed (it imports neither dm_control nor mujoco: the entry point is resolved by
    ``gymnasium.make``). Called on import of this module, which the wheel's start-up hook does once
    gymnasium is imported (:mod:`usv_mj.envs.gymnasium_hook`: Gymnasium 1.x reads no entry points)
    and ``gymnasium.make("usv_mj.envs:usv_mj/Track-v0")`` does first; also the ``gymnasium.envs``
    entry point of the package (pyproject.toml), which only Gymnasium before 1.0 loaded."""
    try:
        from gymnasium.envs.registration import register, registry
    except ImportError:  # pragma: no cover - optional dependency
        return
    for task in (TASKS.kinds() if tasks is None else tasks):
        env_id = gym_id(task)
        if env_id is not None and env_id not in registry:
            register(id=env_id, entry_point="usv_mj.envs.gymnasium_env:USVGymEnv", kwargs={"task": task},
                     vector_entry_point="usv_mj.envs.gymnasium_vector:make_vector_env")
    for env_id, entry_point in (ENV_IDS.items() if tasks is None else ()):
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point)


register_gymnasium()
TASKS.on_register(lambda entry: register_gymnasium((entry.kind,)))


# names imported on first use, so ``usv-mj --help`` does not import dm_control
_lazy_getattr, _lazy_dir, _ = lazy_names(__name__, {name: "." + module for name, module in _WHERE.items()})


def __dir__():
    return sorted(set(_lazy_dir()) | {"ALL_TASKS", "GYM_IDS"})


def __getattr__(name):
    # the registry read at every access: a task registered since is in them
    if name == "ALL_TASKS":
        return TASKS.kinds()
    if name == "GYM_IDS":
        return gym_ids()
    return _lazy_getattr(name)
