"""The stable-baselines3 view of the batch: :class:`USVSB3VecEnv`, a ``VecEnv`` stepping N episodes in one call.

::

    from stable_baselines3 import PPO
    from usv_mj.envs.sb3_vec import USVSB3VecEnv
    venv = USVSB3VecEnv("track", num_envs=64, seed=0, plant="analytic")
    model = PPO("MlpPolicy", venv).learn(1_000_000)

It is :class:`usv_mj.envs.gymnasium_vector.USVVectorEnv` in stable-baselines3's convention: an episode
that ends is reset in the same step (``AutoresetMode.SAME_STEP``), ``dones`` = terminated or
truncated, and that episode's ``info`` has ``terminal_observation`` (its last observation) and
``TimeLimit.truncated`` (the time limit ended it, not the task), plus ``kind`` and ``reason``.
``seed(s)`` seeds episode i with ``s + i`` at the next ``reset()``. The observation and the action are
the Gymnasium view's (float32, scaled; normalized in [-1, 1]).
"""

from __future__ import annotations

import numpy as np

try:
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv
except ImportError:  # pragma: no cover - optional dependency
    from usv_mj.core.errors import missing_extra

    raise missing_extra("stable-baselines3", "usv_mj's stable-baselines3 VecEnv view") from None

from gymnasium.vector import AutoresetMode

from usv_mj.envs.gymnasium_vector import USVVectorEnv


class USVSB3VecEnv(VecEnv):
    """``num_envs`` episodes of a track task for stable-baselines3 (module docstring); options as
    :class:`USVVectorEnv`'s (``plant``, ``n_threads``, ``duration``, ...)."""

    def __init__(self, task: str = "track", num_envs: int = 1, seed=None, **options):
        self.venv = USVVectorEnv(task, num_envs, seed, autoreset_mode=AutoresetMode.SAME_STEP, **options)
        super().__init__(self.venv.num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self._actions = None
        self._seed = seed

    def reset(self):
        seeds = self._seeds if any(s is not None for s in self._seeds) else None
        obs, _ = self.venv.reset(seed=seeds)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions) -> None:
        self._actions = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, 2)

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        infos = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones).tolist():
            infos[i] = {"terminal_observation": info["final_obs"][i], "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
                        "kind": info["kind"][i], "reason": info["reason"][i]}
        return obs, reward.astype(np.float32), dones, infos

    def seed(self, seed=None):
        """Episode i seeded ``seed + i`` at the next reset (stable-baselines3's convention)."""
        if seed is None:
            seed = int(np.random.randint(0, 2 ** 31 - 1))
        self._seeds = [int(seed) + i for i in range(self.num_envs)]
        return self._seeds

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name, indices=None):
        return [getattr(self.venv.single, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name, value, indices=None) -> None:
        raise AttributeError(f"USVSB3VecEnv: the episodes share one definition; cannot set {attr_name!r}")

    def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
        return [getattr(self.venv.single, method_name)(*method_args, **method_kwargs)
                for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False for _ in self._get_indices(indices)]

    def get_images(self):
        raise NotImplementedError("USVSB3VecEnv: render one episode with usv_mj.envs.gym_env(..., render_mode='rgb_array')")
