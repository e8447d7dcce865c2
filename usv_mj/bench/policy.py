"""A learned policy as a benchmark controller: an episode of the task's scenario in the Gymnasium view.

A suite names a policy as ``{ name = "ppo", policy = "ppo_track.zip" }`` (a stable-baselines3
model: PPO, SAC, TD3 or A2C, loaded with ``.load`` and run with ``predict(obs, deterministic=True)``)
or ``policy = "package.module:callable"`` (any ``callable(observation) -> action`` on the Gymnasium
observation of :class:`usv_mj.envs.gymnasium_env.USVGymEnv`: the flat, scaled float32 vector; the
action a normalized (2,) array in [-1, 1]). A callable that is a class is made once per episode with
the environment: ``Class(env)`` (as :class:`usv_mj.envs.PPCPolicy`).

:func:`policy_episode` runs one episode of the task's scenario through ``usv_mj/Track-v0``'s
environment (the MuJoCo plant, the scenario's control period, sea and actuators), starting from the
scenario's initial pose (not the task's random offset), for the scenario's duration, and returns
its :class:`usv_mj.record.RunRecord` (:func:`usv_mj.envs.environment.episode_record`). The Track
observation has no view of obstacles: a task with obstacles is refused (the row says so). The
episode is judged by the default :class:`usv_mj.criteria.PoseTolerance` (a policy declares no
criterion of its own).
"""

from __future__ import annotations

import numpy as np

from ..errors import ScenarioError

SB3_ALGORITHMS = ("PPO", "SAC", "TD3", "A2C")


def load_policy(spec: str, env):
    """``observation -> action`` of ``spec`` (module docstring) for the Gymnasium env ``env``."""
    if spec.endswith(".zip"):
        try:
            import stable_baselines3 as sb3
        except ImportError:
            raise ScenarioError(f"policy {spec!r}: stable-baselines3 is not installed (pip install stable-baselines3)") \
                from None
        problems = []
        for name in SB3_ALGORITHMS:
            try:
                model = getattr(sb3, name).load(spec, device="cpu")
                break
            except FileNotFoundError:
                raise ScenarioError(f"policy {spec!r}: no such file") from None
            except Exception as exc:  # another algorithm's file
                problems.append(f"{name}: {type(exc).__name__}")
        else:
            raise ScenarioError(f"policy {spec!r}: not a stable-baselines3 model of {', '.join(SB3_ALGORITHMS)} "
                                f"({'; '.join(problems)})")
        return lambda obs: model.predict(obs, deterministic=True)[0]
    if ":" not in spec:
        raise ScenarioError(f"policy {spec!r}: give a stable-baselines3 .zip or package.module:callable")
    from ..sweep.runner import resolve

    try:
        obj = resolve(spec)
    except (ImportError, AttributeError) as exc:
        raise ScenarioError(f"policy {spec!r}: cannot import it ({type(exc).__name__}: {exc})") from None
    if isinstance(obj, type):
        obj = obj(env)
    if not callable(obj):
        raise ScenarioError(f"policy {spec!r} is not callable")
    return obj


def policy_episode(scenario, options: dict):
    """The record of one episode of ``scenario`` driven by ``options["policy"]`` (module docstring)."""
    from ..criteria import PoseTolerance
    from ..envs.environment import episode_record
    from ..envs.gymnasium_env import USVGymEnv

    spec = options["policy"]
    if scenario.obstacles:
        raise ScenarioError(f"policy {spec!r}: the Gymnasium Track observation has no view of the obstacles of "
                            f"this task; a policy is scored on open-water tasks")
    genv = USVGymEnv("track", seed=0, scenario=scenario, duration=scenario.duration, start_offset=(0.0, 0.0, 0.0))
    env = genv.dm_env
    task = env.task
    eta0 = np.asarray(scenario.initial.eta, float)
    nu0 = np.asarray(scenario.initial.nu, float)
    task.start_pose = lambda: (eta0.copy(), nu0.copy())   # the suite's start pose, not the task's offset
    policy = load_policy(spec, genv)
    rows = []

    def row():
        t = env.physics.time()
        rows.append((t, env.physics.state.copy(), task.reference.evaluate(t).copy(), task.last_action.copy(),
                     task.last_thrust.copy()))

    try:
        obs, _ = genv.reset(seed=0)
        row()
        while True:
            obs, _, terminated, truncated, _ = genv.step(np.asarray(policy(obs), np.float32))
            row()
            if terminated or truncated:
                break
        stop = task.termination_reason
        record = episode_record(env, rows, {"controller": f"policy {spec}",
                                            "criterion": PoseTolerance().to_dict(), "preset": scenario.preset})
    finally:
        genv.close()
    if stop and rows[-1][0] < scenario.duration - 1e-9:
        record.status, record.stop_reason = "diverged", f"the episode ended early: {stop}"
    return record
