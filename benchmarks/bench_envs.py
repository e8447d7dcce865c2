"""env.step of the dm_control tasks (usv_mj.envs) on one core, beside the bare control period of the same model.

The yardstick (issue 16's): the bare ``mujoco.mj_step`` of one control period on the very model and
data of the environment's plant, at the environment's own state, called natively
``mujoco.mj_step(m, d, nstep=substeps)`` (one binding call, MuJoCo's own loop; the hydrodynamic
callback runs in it, as in every step of the plant: its cost is physics). Harbor's model has the
obstacles, the contacts and the 16 rangefinder sensors, so its period is its own. For reference
also: ``mj_step`` called ``substeps`` times from Python, and ``MuJoCoPlant.step`` (the native
stepper).

Per task: ``env.step`` with a fixed action (no policy cost), quantizer on and off; with the PPC
policy (its call alone too); and, in the same run, the step of a trivial dm_control task (no
physics, one observation) = ``dm_control.rl.control.Environment.step``'s own overhead. Each figure
is the best over ``--rounds`` rounds of ``--steps`` steps, all figures interleaved within a round
(the machine is shared: best-of-interleaved is the load-robust estimate); us per step, and the
ratio to the bare period.

    python benchmarks/bench_envs.py [--steps 200] [--rounds 15] [--tasks track,harbor]
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import warnings

import mujoco
import numpy as np

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # dm_control's GLFW probe (no display needed here)
    from dm_control.rl import control
    from dm_control.suite import base

from usv_mj import envs


class _TrivialPhysics:
    """Just what control.Environment calls on a physics."""

    legacy_step = True

    def step(self, n_sub_steps=1):
        pass

    def reset_context(self):
        return contextlib.nullcontext()

    def timestep(self):
        return 0.001


class _TrivialTask(base.Task):
    """One (2,) observation, reward 0, never ends: control.Environment.step and nothing else."""

    def __init__(self):
        super().__init__(random=0)
        self._obs = np.zeros(2)

    def initialize_episode(self, physics):
        pass

    def before_step(self, action, physics):
        pass

    def after_step(self, physics):
        pass

    def get_observation(self, physics):
        return collections.OrderedDict(x=self._obs)

    def get_reward(self, physics):
        return 0.0


def _env_block(env, n, action, policy=None):
    """Seconds per env.step over n steps (a reset when an episode ends is not timed)."""
    ts = env._last_ts if hasattr(env, "_last_ts") else env.reset()
    total = 0.0
    done = 0
    while done < n:
        if ts.last():
            ts = env.reset()
        k = 0
        t0 = time.perf_counter()
        while k < n - done and not ts.last():
            ts = env.step(policy(ts) if policy is not None else action)
            k += 1
        total += time.perf_counter() - t0
        done += k
    env._last_ts = ts
    return total / n


def _bare_block(plant, n, native=True):
    """Seconds per bare control period on the plant's model and data from its current state
    (restored afterwards, so the environment's episode goes on where it was)."""
    m, d = plant.model, plant.data
    sub = plant.substeps
    saved = (d.qpos.copy(), d.qvel.copy(), d.ctrl.copy(), d.time)
    d.ctrl[:] = (2.0, 0.1)
    t0 = time.perf_counter()
    if native:
        for _ in range(n):
            mujoco.mj_step(m, d, sub)
    else:
        for _ in range(n):
            for _ in range(sub):
                mujoco.mj_step(m, d)
    dt = (time.perf_counter() - t0) / n
    d.qpos[:], d.qvel[:], d.ctrl[:], d.time = saved
    return dt


def _plant_block(plant, n):
    """Seconds per MuJoCoPlant.step (its step count restored afterwards)."""
    saved = (plant.data.qpos.copy(), plant.data.qvel.copy(), plant._k, plant._x)
    t0 = time.perf_counter()
    for _ in range(n):
        plant.step(2.0, 0.1)
    dt = (time.perf_counter() - t0) / n
    plant.data.qpos[:], plant.data.qvel[:] = saved[0], saved[1]
    plant._k, plant._x = saved[2], saved[3]
    return dt


def _policy_block(policy, ts, n):
    t0 = time.perf_counter()
    for _ in range(n):
        policy(ts)
    return (time.perf_counter() - t0) / n


def measure(task: str, steps: int, rounds: int) -> dict:
    env_q = envs.load(task, seed=0, quantize=True)
    env_c = envs.load(task, seed=0, quantize=False)
    env_p = envs.load(task, seed=0, quantize=True)
    trivial = control.Environment(_TrivialPhysics(), _TrivialTask())
    action = np.array([2.0, 0.1])
    best = collections.defaultdict(lambda: float("inf"))
    try:
        ppc = envs.PPCPolicy(env_p)
        for env in (env_q, env_c, env_p):
            env._last_ts = env.reset()
        trivial.reset()
        _env_block(env_q, 20, action)  # compile / warm the caches
        _env_block(env_p, 20, None, ppc)
        for _ in range(rounds):
            best["bare"] = min(best["bare"], _bare_block(env_q.physics.plant, steps))
            best["quant"] = min(best["quant"], _env_block(env_q, steps, action))
            best["bare_py"] = min(best["bare_py"], _bare_block(env_q.physics.plant, steps, native=False))
            best["cont"] = min(best["cont"], _env_block(env_c, steps, action))
            best["plant"] = min(best["plant"], _plant_block(env_q.physics.plant, steps))
            best["ppc_env"] = min(best["ppc_env"], _env_block(env_p, steps, None, ppc))
            best["policy"] = min(best["policy"], _policy_block(ppc, env_p._last_ts, steps))
            best["trivial"] = min(best["trivial"], _env_block(trivial, steps, action))
        plant = env_q.physics.plant
        out = {k: v * 1e6 for k, v in best.items()}
        out.update(substeps=plant.substeps, control_period=plant.control_period)
        return out
    finally:
        env_q.close()
        env_c.close()
        env_p.close()


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200, help="steps per figure and round")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--tasks", default="track,harbor")
    args = ap.parse_args(argv)
    print(f"usv_mj.envs benchmark: best of {args.rounds} interleaved rounds of {args.steps} steps per figure, "
          f"us per control step (shared 2-core machine: figures under load)")
    for task in args.tasks.split(","):
        r = measure(task, args.steps, args.rounds)
        sub, cp, bare = r["substeps"], r["control_period"], r["bare"]

        def line(label, us, ratio=True, extra=""):
            tail = f"  {us / bare:5.2f}x the bare period" if ratio else ""
            print(f"  {label:46s} {us:8.1f} us{tail}{extra}")

        print(f"\n{task}: control period {cp} s = {sub} RK4 steps of {cp / sub} s")
        line(f"bare mujoco.mj_step(m, d, nstep={sub})  [yardstick]", bare, extra=f"  ({cp / bare * 1e6:.0f}x real time)")
        line(f"bare mujoco.mj_step x{sub} from Python", r["bare_py"])
        line("MuJoCoPlant.step (native stepper)", r["plant"])
        line("env.step, quantize=True", r["quant"], extra=f"  (+{r['quant'] - bare:.1f} us over the physics)")
        line("env.step, quantize=False", r["cont"], extra=f"  (+{r['cont'] - bare:.1f} us)")
        line("env.step + PPCPolicy (quantized)", r["ppc_env"], extra=f"  ({cp / r['ppc_env'] * 1e6:.0f}x real time)")
        line("PPCPolicy call alone", r["policy"], ratio=False)
        line("trivial dm_control task's env.step", r["trivial"], ratio=False,
             extra="  (control.Environment.step's own overhead)")


if __name__ == "__main__":
    main()
