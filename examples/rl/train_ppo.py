"""Train a stock stable-baselines3 PPO policy on ``usv_mj/Track-v0`` for the benchmark's leaderboard.

    python examples/rl/train_ppo.py --steps 780000 --out renders/ppo_track.zip      # the issue's run
    python examples/rl/train_ppo.py --steps 4096 --out /tmp/ppo_smoke.zip          # a smoke test

Stock PPO (``MlpPolicy``, stable-baselines3's default hyper-parameters), no wrapper, on the
Gymnasium view of the track task (the flat scaled observation, the normalized action; 30 s episodes
at a 0.01 s control period, a random start offset; :mod:`usv_mj.envs`). The script prints the
steps, the wall time and the steps per second at the end.

Score it beside the controllers with a suite that names it (relative paths: to the suite's folder)::

    controllers = ["ppc", "pi", "los", { name = "ppo", policy = "renders/ppo_track.zip" }]

A policy runs each benchmark episode through the same environment (the MuJoCo plant) at the task's
own control period and length, from the task's start pose (:mod:`usv_mj.bench.policy`); the track
observation has no view of obstacles, so a policy's harbour episodes are recorded as failed.
"""

from __future__ import annotations

import argparse
import time


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=780_000, help="environment steps (default 780000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="renders/ppo_track.zip", help="the model file (.zip)")
    args = parser.parse_args()
    import gymnasium
    from stable_baselines3 import PPO

    import usv_mj.envs  # noqa: F401  (registers usv_mj/Track-v0)

    env = gymnasium.make("usv_mj/Track-v0")
    model = PPO("MlpPolicy", env, seed=args.seed, verbose=0, device="cpu")
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.steps)
    wall = time.perf_counter() - t0
    model.save(args.out)
    print(f"PPO on usv_mj/Track-v0: {args.steps} steps in {wall:.0f} s ({args.steps / wall:.0f} steps/s); "
          f"saved {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
