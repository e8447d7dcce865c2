"""Train a stock stable-baselines3 PPO policy on ``usv_mj/Track-v0`` for the benchmark's leaderboard.

    python examples/rl/train_ppo.py --steps 5000000 --checkpoint 500000 --out /tmp/ppo/ppo_track.zip
    python examples/rl/train_ppo.py --steps 4096 --out /tmp/ppo_smoke.zip           # a smoke test

The shipped policy, ``usv_mj/jobs/bench/suites/ppo_track.zip`` (the default suite's ``ppo``), is the
first command's checkpoint at 3,000,320 steps (``ppo_track-3000320.zip``; the run was stopped
there, after 43.8 min at 1141 steps/s on a shared 2-core machine; README, Benchmark).

Stock PPO (``MlpPolicy``, stable-baselines3's default hyper-parameters: a rollout of 2048 steps,
minibatches of 64, 10 epochs, lr 3e-4, gamma 0.99, GAE 0.95, clip 0.2), no wrapper, on the
Gymnasium view of the track task (the flat scaled observation, the normalized action; 30 s episodes
at a 0.01 s control period, a random start offset; :mod:`usv_mj.envs`). The rollout is collected
from ``--n-envs`` copies of the environment stepped in one process (stable-baselines3's
``DummyVecEnv``, 8 by default) with ``n_steps = 2048 // n_envs`` each, so one update still sees
2048 steps, as the default: vectorising only batches the policy's forward pass.

What makes it fast (docs/metrics.md, "The PPO row"):

- **One torch thread** (``torch.set_num_threads(1)``). torch's default is one intra-op thread per
  core; on a 2-core machine that others share, its threads spin against each other and against the
  environment for every 64x22 forward pass: 18 steps/s was measured that way under load, 343 steps/s
  on the idle machine, 1728 steps/s with one thread (one environment).
- **A vectorised environment**: one batched forward pass for 8 environment steps instead of 8
  (2980 steps/s on the idle machine). An environment step is ~130 us (the fused native step of
  :mod:`usv_mj.envs.native`: 10 RK4 steps of 1 ms and the observation in one compiled call).
- **Threads that sleep between steps**: the script sets ``OMP_WAIT_POLICY=passive`` (unless set)
  before numba loads OpenMP; with the default, the batch's idle threads spin through PPO's update
  (65 against 494 steps/s, measured on the shared machine).
- **The episodes stepped together** (``--vec native``, the default since issue 36): the
  ``--n-envs`` episodes advance in one compiled call (:class:`usv_mj.envs.sb3_vec.USVSB3VecEnv`:
  the action, the plant, the observation and the reward of every episode, no Python per episode),
  the same episodes as ``--vec dummy``'s (env i seeded ``seed + i``, the MuJoCo plant); ``--plant
  analytic`` trains on the native RK4 of the same hull instead.

The script prints a progress line per 2048-step update (steps, wall time, steps/s, mean return of
the last 20 episodes), saves a checkpoint every ``--checkpoint`` steps beside ``--out``
(``<out>-<steps>.zip``), and at the end prints the steps, the wall time and the steps per second.

Score it beside the controllers with a suite that names it (relative paths: to the suite's folder)::

    controllers = ["ppc", "pi", "los", { name = "ppo", policy = "ppo_track.zip" }]

A policy runs each benchmark episode through the same environment (the MuJoCo plant) at its training
control period (0.01 s, zero-order hold), from the task's start pose (:mod:`usv_mj.jobs.bench.policy`);
the track observation has no view of obstacles, so a policy is not scored on the harbour task.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

# numba's worker threads (the native batch's prange on the OpenMP layer) spin after every parallel env
# step by default (libgomp's OMP_WAIT_POLICY), and PPO's update, which runs between the steps, finds
# both cores taken: 65 steps/s against 494 with "passive" (6144 steps, --vec native, MuJoCo plant,
# shared 2-core machine at load 8). Read once, when libgomp loads: set before numba or torch is
# imported; a setting of the user's own is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3_000_000, help="environment steps (default 3000000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-envs", type=int, default=8, help="environments stepped together (default 8; "
                        "must divide 2048)")
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads (default 1)")
    parser.add_argument("--vec", choices=("native", "dummy"), default="native",
                        help="native: the episodes stepped in one compiled call (usv_mj.envs.sb3_vec.USVSB3VecEnv, "
                             "the default); dummy: stable-baselines3's DummyVecEnv of single environments (before)")
    parser.add_argument("--plant", choices=("mujoco", "analytic"), default="mujoco",
                        help="the task's plant (native only; default mujoco, the benchmark's)")
    parser.add_argument("--env-threads", type=int, default=None,
                        help="numba threads stepping the native batch (default: numba's setting)")
    parser.add_argument("--checkpoint", type=int, default=500_000, help="save every N steps (0: never)")
    parser.add_argument("--out", default="renders/ppo_track.zip", help="the model file (.zip)")
    args = parser.parse_args()
    if args.n_envs < 1 or 2048 % args.n_envs:
        parser.error(f"--n-envs must divide 2048, got {args.n_envs}")
    import numpy as np
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env

    import usv_mj.envs  # noqa: F401  (registers usv_mj/Track-v0)

    torch.set_num_threads(args.threads)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if args.vec == "native":   # the same episodes (env i seeded seed + i), stepped together natively
        from stable_baselines3.common.vec_env import VecMonitor

        from usv_mj.envs.sb3_vec import USVSB3VecEnv

        env = VecMonitor(USVSB3VecEnv("track", num_envs=args.n_envs, seed=args.seed, plant=args.plant,
                                      n_threads=args.env_threads))
    else:
        if args.plant != "mujoco":
            parser.error("--plant analytic needs --vec native")
        env = make_vec_env("usv_mj/Track-v0", n_envs=args.n_envs, seed=args.seed)
    model = PPO("MlpPolicy", env, n_steps=2048 // args.n_envs, seed=args.seed, verbose=0, device="cpu")
    t0 = time.perf_counter()

    class Progress(BaseCallback):
        saved = 0

        def _on_step(self) -> bool:
            return True

        def _on_rollout_end(self) -> None:
            n = self.num_timesteps
            wall = time.perf_counter() - t0
            ret = [e["r"] for e in self.model.ep_info_buffer]
            mean = f"{np.mean(ret):.1f}" if ret else "-"
            print(f"steps {n} wall {wall:.0f} s {n / wall:.0f} steps/s mean return (last {len(ret)} episodes) "
                  f"{mean}", flush=True)

        def _on_rollout_start(self) -> None:   # the update of the last rollout is done: n steps learnt
            n = self.num_timesteps
            if args.checkpoint and n // args.checkpoint > self.saved:
                self.saved = n // args.checkpoint
                self.model.save(out.with_name(f"{out.stem}-{n}.zip"))

    model.learn(total_timesteps=args.steps, callback=Progress())
    wall = time.perf_counter() - t0
    model.save(out)
    print(f"PPO on usv_mj/Track-v0: {model.num_timesteps} steps in {wall:.0f} s "
          f"({model.num_timesteps / wall:.0f} steps/s, {args.n_envs} envs ({args.vec}, {args.plant}), "
          f"{args.threads} torch thread(s)); "
          f"saved {out}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
