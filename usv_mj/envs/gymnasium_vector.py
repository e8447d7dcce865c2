"""The vector environments: ``gymnasium.make_vec("usv_mj/Track-v0", num_envs=N)`` steps N episodes in one call.

::

    import gymnasium
    import usv_mj.envs                                             # registers the ids
    envs = gymnasium.make_vec("usv_mj/Track-v0", num_envs=64)      # USVVectorEnv (the MuJoCo plant)
    envs = gymnasium.make_vec("usv_mj/Track-v0", num_envs=4096, plant="analytic")
    obs, info = envs.reset(seed=0)                                 # env i seeded 0 + i
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())

:class:`USVVectorEnv` is a ``gymnasium.vector.VectorEnv`` over :class:`usv_mj.envs.batch.TrackBatch`:
the actions (normalized, as :class:`usv_mj.envs.gymnasium_env.USVGymEnv`'s), the control step, the
plant, the observation (scaled and clipped, float32), the reward and the termination of every
episode are computed in one native call, with no Python per episode; Python runs only for the
episodes that end (their ``info`` and their reset). Each episode equals a :class:`USVGymEnv` of the
same options reset with seed ``seed + i`` (``reset(seed=seed)``), step for step: observations,
rewards, terminations and truncations (tests/test_vector_env.py).

Autoreset (``metadata["autoreset_mode"]``, Gymnasium 1.x): ``autoreset_mode`` = ``NEXT_STEP`` (the
default, as SyncVectorEnv: the step after an episode's last one resets it, returning its first
observation with reward 0 and neither flag, its action unused), ``SAME_STEP`` (an episode that ends
is reset in the same step: the observation returned is the new episode's, the last one in
``info["final_obs"]`` with ``info["final_info"]``) or ``DISABLED`` (``reset(options={"reset_mask":
mask})`` resets the episodes in ``mask``). ``info`` holds, for the episodes that ended at this step,
``kind`` ("diverged", "lost" or "time_limit") and ``reason`` (object arrays with the masks ``_kind``,
``_reason``), as the single environment's ``info``; the actions, commands and thrusts of the last step
are the env's :attr:`~USVVectorEnv.last_action`, ``last_command`` and ``last_thrust`` (N, 2).

Options: those of :func:`usv_mj.envs.load` (``duration``, ``quantize``, ``vessel``, ...), ``plant``
("mujoco", the tasks' own, or "analytic": RK4 of the same hull in native code), ``n_threads`` (numba
threads; None: numba's setting). The harbour tasks are not batched natively (a new model per layout,
obstacles moved in Python): :func:`make_vector_env` gives a ``SyncVectorEnv`` of :class:`USVGymEnv`
for them.
"""

from __future__ import annotations

import numpy as np

try:
    import gymnasium
    from gymnasium.vector import AutoresetMode, VectorEnv
    from gymnasium.vector.utils import batch_space
except ImportError:  # pragma: no cover - optional dependency
    from usv_mj.core.errors import missing_extra

    raise missing_extra("gymnasium", "usv_mj's vector environments (gymnasium.make_vec)") from None

from usv_mj.envs.batch import NotBatched, TrackBatch
from usv_mj.envs.environment import task_entry
from usv_mj.envs.gymnasium_env import USVGymEnv


def _mode(value) -> AutoresetMode:
    if isinstance(value, AutoresetMode):
        return value
    try:
        return AutoresetMode(value)
    except ValueError:
        names = {m.name.lower(): m for m in AutoresetMode}
        if isinstance(value, str) and value.lower() in names:
            return names[value.lower()]
        raise ValueError(f"USVVectorEnv: autoreset_mode must be one of {[m.value for m in AutoresetMode]}, "
                         f"got {value!r}") from None


class USVVectorEnv(VectorEnv):
    """``num_envs`` episodes of a track task as one ``gymnasium.vector.VectorEnv`` (module docstring)."""

    def __init__(self, task: str = "track", num_envs: int = 1, seed=None, *, plant: str = "mujoco",
                 autoreset_mode=AutoresetMode.NEXT_STEP, n_threads: int | None = None, parallel: bool | None = None,
                 render_mode=None, flat: bool = True, **options):
        if render_mode is not None:
            raise ValueError("USVVectorEnv: render_mode must be None (render one episode with "
                             "usv_mj.envs.gym_env(..., render_mode='rgb_array'))")
        if not flat:
            raise ValueError("USVVectorEnv: only the flat observation is batched (flat=True)")
        self.autoreset_mode = _mode(autoreset_mode)
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": []}
        self.render_mode = None
        self.single = USVGymEnv(task, **options)   # the task's definition and the spaces of one episode
        scale, lo, hi = (np.concatenate([np.broadcast_to(v, self.single._bounds[n][0].shape).ravel()
                                         for n, v in items]) for items in (
            self.single._scale.items(), ((n, b[0]) for n, b in self.single._bounds.items()),
            ((n, b[1]) for n, b in self.single._bounds.items())))
        try:
            self.batch = TrackBatch(task, num_envs, seed, plant=plant, single=self.single.dm_env, n_threads=n_threads,
                                    parallel=parallel, scaled=(scale, lo, hi))
        except BaseException:
            self.single.close()
            raise
        self.num_envs = self.batch.num_envs
        self.single_observation_space = self.single.observation_space
        self.single_action_space = self.single.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._autoreset = np.zeros(self.num_envs, np.bool_)
        self._started = False
        self.last_action, self.last_command = self.batch.last_action, self.batch.last_command
        self.last_thrust, self.last_saturated = self.batch.last_thrust, self.batch.last_saturated

    # --- gymnasium.vector.VectorEnv ------------------------------------------------------------------------

    def reset(self, *, seed=None, options=None):
        """Every episode (or, ``options={"reset_mask": mask}``, those in ``mask``) starts again;
        ``seed``: an int (episode i seeded seed + i), a list of N seeds or None (each episode's
        random state goes on)."""
        b = self.batch
        if seed is not None:
            seeds = list(seed) if isinstance(seed, (list, tuple, np.ndarray)) else [int(seed) + i for i in range(b.num_envs)]
            if len(seeds) != b.num_envs:
                raise ValueError(f"USVVectorEnv.reset: {len(seeds)} seeds for {b.num_envs} environments")
            for i, s in enumerate(seeds):
                if s is not None:
                    b.rngs[i] = np.random.RandomState(int(s))
        mask = None if options is None else options.get("reset_mask")
        if mask is not None:
            mask = np.asarray(mask, dtype=np.bool_)
            if mask.shape != (b.num_envs,):
                raise ValueError(f"USVVectorEnv.reset: reset_mask must have shape ({b.num_envs},), got {mask.shape}")
            idx = np.flatnonzero(mask)
        else:
            idx = np.arange(b.num_envs)
        b.reset_envs(idx)
        self._autoreset[idx] = False
        self._started = True
        return b.OBS32.copy(), {}

    def step(self, actions):
        if not self._started:
            from gymnasium.error import ResetNeeded

            raise ResetNeeded("USVVectorEnv.step: call reset() before step()")
        b = self.batch
        mode = self.autoreset_mode
        pending = self._autoreset
        if mode == AutoresetMode.DISABLED and pending.any():
            raise RuntimeError(f"USVVectorEnv.step (autoreset DISABLED): envs {np.flatnonzero(pending).tolist()} "
                               f"ended; reset them first (reset(options={{'reset_mask': mask}}))")
        active = ~pending if mode == AutoresetMode.NEXT_STEP else None
        b.advance(actions, True, active)
        terminated, truncated = b.ends()
        reward = b.REW.copy()
        infos = {}
        ended = np.flatnonzero(terminated | truncated)
        if mode == AutoresetMode.NEXT_STEP:
            again = np.flatnonzero(pending)
            ended = ended[~pending[ended]]
            self._add_end_info(infos, ended, truncated)
            if again.size:
                b.reset_envs(again)
                reward[again] = 0.0
                terminated[again] = False
                truncated[again] = False
            self._autoreset = terminated | truncated
        elif mode == AutoresetMode.SAME_STEP:
            self._add_end_info(infos, ended, truncated)
            if ended.size:
                final_obs = np.empty(self.num_envs, dtype=object)
                final_info = np.empty(self.num_envs, dtype=object)
                for i in ended.tolist():
                    final_obs[i] = b.OBS32[i].copy()
                    final_info[i] = {"kind": infos["kind"][i], "reason": infos["reason"][i]}
                mask = np.zeros(self.num_envs, np.bool_)
                mask[ended] = True
                infos.update(final_obs=final_obs, _final_obs=mask, final_info=final_info, _final_info=mask.copy())
                b.reset_envs(ended)
        else:
            self._add_end_info(infos, ended, truncated)
            self._autoreset = terminated | truncated
        return b.OBS32.copy(), reward, terminated, truncated, infos

    def _add_end_info(self, infos: dict, ended, truncated) -> None:
        if not len(ended):
            return
        n = self.num_envs
        kind = np.full(n, None, dtype=object)
        reason = np.full(n, None, dtype=object)
        for i in ended.tolist():
            kind[i], reason[i] = self.batch.end_info(i, bool(truncated[i]))
        mask = np.zeros(n, np.bool_)
        mask[ended] = True
        infos.update(kind=kind, _kind=mask, reason=reason, _reason=mask.copy())

    def close_extras(self, **kwargs):
        self.batch.close()
        self.single.close()

    @property
    def physical_action(self):
        """The single view's normalized -> physical action map (USVGymEnv.physical_action)."""
        return self.single.physical_action


def make_vector_env(num_envs: int = 1, task: str = "track", autoreset_mode=AutoresetMode.NEXT_STEP, **options):
    """The vector entry point of the registered ids (``gymnasium.make_vec``): :class:`USVVectorEnv` for
    the tasks the batch steps natively (a track task with a fixed reference); the others (the harbour
    tasks: tagged "obstacles"; a task the batch cannot take) as a ``SyncVectorEnv`` of
    :class:`USVGymEnv`, env i seeded ``seed + i``."""
    options.pop("max_episode_steps", None)
    if "obstacles" not in task_entry(task).tags:
        try:
            return USVVectorEnv(task, num_envs, autoreset_mode=autoreset_mode, **options)
        except NotBatched:
            pass
    for name in ("plant", "n_threads", "parallel"):
        options.pop(name, None)
    seed = options.pop("seed", None)
    fns = [(lambda i=i: USVGymEnv(task, seed=None if seed is None else int(seed) + i, **options))
           for i in range(int(num_envs))]
    return gymnasium.vector.SyncVectorEnv(fns, autoreset_mode=_mode(autoreset_mode))
