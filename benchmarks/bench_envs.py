"""Environment steps per second (usv_mj.envs) on one core, beside the bare mj_step of the same model.

For each task: ``env.step`` with a fixed action (no policy cost), with and without the hysteresis
quantizer; the PPC policy's cost per step separately; and the yardsticks measured in the same run on
the very model and data of the environment's plant: ``mujoco.mj_step`` called ``substeps`` times
(one control period, through the Python bindings) and ``MuJoCoPlant.step`` (the native stepper).
Each figure is the best of ``--rounds`` interleaved rounds (the machine is shared).

    python benchmarks/bench_envs.py [--steps 2000] [--rounds 3] [--tasks track,harbor]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np

from usv_mj import envs


def _env_steps(env, n, action, policy=None):
    ts = env.reset()
    t0 = time.perf_counter()
    done = 0
    while done < n:
        if ts.last():
            ts = env.reset()
        ts = env.step(policy(ts) if policy is not None else action)
        done += 1
    return n / (time.perf_counter() - t0)


def _policy_calls(env, n):
    policy = envs.PPCPolicy(env)
    ts = env.reset()
    t0 = time.perf_counter()
    for _ in range(n):
        policy(ts)
    return n / (time.perf_counter() - t0)


def _bare(plant, n):
    m, d = plant.model, plant.data
    sub = plant.substeps
    plant.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    d.ctrl[:] = (2.0, 0.1)
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d, sub)
    per_period = n / (time.perf_counter() - t0)
    plant.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    t0 = time.perf_counter()
    for _ in range(n):
        plant.step(2.0, 0.1)
    return per_period, n / (time.perf_counter() - t0)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--tasks", default="track,harbor")
    args = ap.parse_args(argv)
    action = np.array([2.0, 0.1])
    print(f"usv_mj.envs benchmark: {args.steps} control steps per figure, best of {args.rounds} rounds "
          f"(measured on a shared 2-core machine: figures under load)")
    for task in args.tasks.split(","):
        env_q = envs.load(task, seed=0, quantize=True)
        env_c = envs.load(task, seed=0, quantize=False)
        plant = env_c.physics.plant
        best = {k: 0.0 for k in ("quant", "cont", "ppc_env", "policy", "bare", "plant")}
        try:
            for _ in range(args.rounds):
                best["quant"] = max(best["quant"], _env_steps(env_q, args.steps, action))
                best["cont"] = max(best["cont"], _env_steps(env_c, args.steps, action))
                best["ppc_env"] = max(best["ppc_env"], _env_steps(env_q, args.steps, None, envs.PPCPolicy(env_q)))
                best["policy"] = max(best["policy"], _policy_calls(env_q, args.steps))
                env_c.reset()
                plant = env_c.physics.plant
                bare, stepper = _bare(plant, args.steps)
                best["bare"] = max(best["bare"], bare)
                best["plant"] = max(best["plant"], stepper)
        finally:
            env_q.close()
            env_c.close()
        sub = plant.substeps
        cp = plant.control_period
        print(f"\n{task}: control period {cp} s = {sub} RK4 steps of {cp / sub} s")
        print(f"  bare mujoco.mj_step x{sub} (one control period) {best['bare']:10.0f} /s "
              f"({best['bare'] * sub:.0f} mj_step/s)")
        print(f"  MuJoCoPlant.step (native stepper)          {best['plant']:10.0f} /s")
        print(f"  env.step, quantize=False                   {best['cont']:10.0f} /s "
              f"({best['bare'] / best['cont']:.1f}x the bare period)")
        print(f"  env.step, quantize=True                    {best['quant']:10.0f} /s "
              f"({best['bare'] / best['quant']:.1f}x the bare period)")
        print(f"  PPCPolicy call alone                       {best['policy']:10.0f} /s")
        print(f"  env.step + PPCPolicy (quantized)           {best['ppc_env']:10.0f} /s "
              f"({best['ppc_env'] * cp:.1f}x real time)")


if __name__ == "__main__":
    main()
