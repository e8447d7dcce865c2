"""A learned policy as a benchmark controller: an episode of the task's scenario in the Gymnasium view.

A suite names a policy as ``{ name = "ppo", policy = "ppo_track.zip" }`` (a stable-baselines3
model: PPO, SAC, TD3 or A2C, loaded with ``.load`` and run with ``predict(obs, deterministic=True)``)
or ``policy = "package.module:callable"`` (any ``callable(observation) -> action`` on the Gymnasium
observation of :class:`usv_mj.envs.gymnasium_env.USVGymEnv`: the flat, scaled float32 vector; the
action a normalized (2,) array in [-1, 1]). A callable that is a class is made once per episode with
the environment: ``Class(env)`` (as :class:`usv_mj.envs.PPCPolicy`).

:func:`policy_episode` runs one episode of the task's scenario through ``usv_mj/Track-v0``'s
environment (the MuJoCo plant, the scenario's sea and actuators), starting from the scenario's
initial pose (not the task's random offset), for the scenario's duration, and returns its
:class:`usv_mj.record.run_record.RunRecord` (:func:`usv_mj.envs.environment.episode_record`: one row per
control step).

**As it was trained.** The policy runs at its own control period (``control_period`` of the
suite's entry, default :data:`DEFAULT_CONTROL_PERIOD` = 0.01 s, Track-v0's): the suite gives its
episodes the task's scenario with ``control_period`` = that period and ``plant.substeps`` = that
period over the task's integration step (:func:`usv_mj.jobs.bench.suite.plan_suite`), so the plant
integrates the task's 1 ms RK4 steps and the policy's action (through the quantizer) is held
over its 10 of them, zero-order hold, exactly as in training. The Track observation has no view
of obstacles: a policy is not planned on a task with obstacles, and refused here if given one.

**Its criterion.** A policy declares none, so the suite gives it one that fits what it was trained
for: pose tracking of the time-parametrised reference with the track task's reward, whose terms
are 1 (full reward) while |p - p_d| <= 0.25 m and |wrap(psi - psi_d)| <= 0.1 rad
(:mod:`usv_mj.envs.tasks`). :func:`default_criterion` is that band as a
:class:`usv_mj.record.criteria.PoseTolerance` after the task's settling time (``settle_time_s``, the
metrics' own): ``PoseTolerance(settle_time_s, position_m=0.25, heading_deg=5.7296)``. A suite
entry's ``criterion`` table (``{ kind = "pose_tolerance", ... }``, any of
:data:`usv_mj.record.criteria.CRITERIA`) replaces it.
"""

from __future__ import annotations

import numpy as np

from usv_mj.core.errors import ScenarioError

SB3_ALGORITHMS = ("PPO", "SAC", "TD3", "A2C")
#: the environment task (a kind of :data:`usv_mj.core.registry.TASKS`) whose Gymnasium view a policy
#: runs in, on the suite task's own scenario: ``usv_mj/Track-v0``'s (what the policies are trained in)
POLICY_TASK = "track"
DEFAULT_CONTROL_PERIOD = 0.01
"""s: the control period of ``usv_mj/Track-v0`` (10 RK4 steps of 1 ms), the one a policy trained there learnt."""


def default_criterion(settle_time_s: float = 20.0):
    """The criterion of a policy that declares none (module docstring): the track reward's
    full-reward band as a pose tolerance after ``settle_time_s``."""
    import math

    from usv_mj.record.criteria import PoseTolerance
    from usv_mj.envs.tasks import TRACK_REWARD_HEADING_RAD, TRACK_REWARD_POSITION_M

    return PoseTolerance(settle_time_s=float(settle_time_s), position_m=TRACK_REWARD_POSITION_M,
                         heading_deg=math.degrees(TRACK_REWARD_HEADING_RAD))


def load_policy(spec: str, env):
    """``observation -> action`` of ``spec`` (module docstring) for the Gymnasium env ``env``."""
    if spec.endswith(".zip"):
        try:
            import stable_baselines3 as sb3
        except ImportError:
            raise ScenarioError(f"policy {spec!r}: stable-baselines3 is not installed (pip install stable-baselines3)") \
                from None
        import torch

        # one intra-op thread: a benchmark worker is one process per core, and torch's default (a
        # thread per core) makes the threads of a 64-wide forward pass spin against each other and
        # the other workers (examples/rl/train_ppo.py measures the same in training)
        torch.set_num_threads(1)
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
    from usv_mj.jobs.sweep.runner import resolve

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
    from usv_mj.record.criteria import criterion_from_dict
    from usv_mj.envs.environment import episode_record
    from usv_mj.envs.gymnasium_env import USVGymEnv

    from usv_mj.core.registry import TASKS

    spec = options["policy"]
    task = TASKS.get(POLICY_TASK, f"policy {spec!r}")
    if scenario.obstacles:   # the task's observation sees the obstacles of its own layout at most
        raise ScenarioError(f"policy {spec!r}: the Gymnasium {POLICY_TASK!r} observation has no view of the obstacles "
                            f"of this task; a policy is scored on open-water tasks")
    criterion = criterion_from_dict(options.get("criterion") or default_criterion().to_dict())
    genv = USVGymEnv(task.kind, seed=0, scenario=scenario, duration=scenario.duration, start_offset=(0.0, 0.0, 0.0))
    env = genv.dm_env
    task = env.task
    eta0 = np.asarray(scenario.initial.eta, float)
    nu0 = np.asarray(scenario.initial.nu, float)
    task.start_pose = lambda: (eta0.copy(), nu0.copy())   # the suite's start pose, not the task's offset
    policy = load_policy(spec, genv)
    rows = []

    from usv_mj.envs.environment import step_row

    def row():
        rows.append(step_row(env))

    try:
        obs, _ = genv.reset(seed=0)
        row()
        while True:
            obs, _, terminated, truncated, _ = genv.step(np.asarray(policy(obs), np.float32))
            row()
            if terminated or truncated:
                break
        stop = task.termination_reason
        # the record's convention (usv_mj.jobs.bench.metrics): row k's input is the one held from t_k to
        # t_{k+1}; a row above holds the action of the step that ended at t_k, so shift them by one
        # (the last row's input, never applied, repeats the last action)
        rows = [(t, x, ref, *rows[min(k + 1, len(rows) - 1)][3:]) for k, (t, x, ref, *_) in enumerate(rows)]
        record = episode_record(env, rows, {"controller": f"policy {spec}",
                                            "criterion": criterion.to_dict(), "preset": scenario.preset})
    finally:
        genv.close()
    if stop and rows[-1][0] < scenario.duration - 1e-9:
        record.status, record.stop_reason = "diverged", f"the episode ended early: {stop}"
    return record
