"""Every vessel an agent: a PettingZoo ``ParallelEnv`` of a traffic situation (issue 35, item 6).

::

    from usv_mj.envs import traffic_parallel_env
    env = traffic_parallel_env(situation=5, plant="analytic")      # agents "own", "ts1", "ts2"
    obs, infos = env.reset(seed=0)
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        obs, rewards, terminations, truncations, infos = env.step(actions)

The situation, the simulation, the observations, rewards and ends are
:mod:`usv_mj.envs.traffic`'s, with every vessel an agent: ``possible_agents`` are the vessels' names
(an Imazu case: ``own``, ``ts1``, ...; a scenario: its ``[[vessels]]`` names), each agent's
observation is :mod:`usv_mj.envs.traffic`'s of its own vessel (its goal, the others in its body
frame), its action the normalized (surge force, yaw moment) of ``usv_mj/Encounter-v0`` through its
own control step. The options are ``usv_mj/Encounter-v0``'s (one situation: the agents are fixed),
plus ``max_cycles`` (None: the time limit alone; else every agent still acting is truncated after
that many steps; PettingZoo's API test sets it).

An agent leaves ``agents`` in the step it terminates (collision, goal, diverged) or is truncated
(the time limit, ``max_cycles``), and never comes back; its vessel stays in the sea on a zero
command (a hull the others still meet). Observation and action spaces are built once: each call
returns the same object. ``reset(seed, options)``: the seed renews :attr:`np_random` (the situation
itself is deterministic); ``options`` are accepted and ignored (the situation is the
constructor's). ``state()``: every vessel's (x, y, psi, u, v, r), one row each, flattened.
"""

from __future__ import annotations

import numpy as np

try:
    from gymnasium import spaces
    from gymnasium.utils import seeding
except ImportError:  # pragma: no cover - optional dependency
    from usv_mj.core.errors import missing_extra

    raise missing_extra("gymnasium", "the PettingZoo traffic environment (usv_mj.envs.traffic_parallel)") from None
try:
    from pettingzoo import ParallelEnv
except ImportError:  # pragma: no cover - optional dependency
    from usv_mj.core.errors import missing_extra

    raise missing_extra("pettingzoo", "the PettingZoo traffic environment (usv_mj.envs.traffic_parallel)") from None

from usv_mj.envs.traffic import (Traffic, checked_action, physical_action, scaled_observation, split_options,
                                 traffic_situation)
from usv_mj.physics.encounters import G_RANGE


class TrafficParallelEnv(ParallelEnv):
    """Every vessel of a traffic situation an agent (module docstring)."""

    metadata = {"name": "usv_mj_traffic_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, situation=1, *, max_cycles: int | None = None, render_mode=None, **options):
        where = "usv_mj traffic (PettingZoo)"
        if render_mode is not None:
            raise ValueError(f"{where}: render_mode must be None, got {render_mode!r}")
        if max_cycles is not None and (isinstance(max_cycles, bool) or not isinstance(max_cycles, int)
                                       or max_cycles < 1):
            raise ValueError(f"{where}: max_cycles must be None or an integer >= 1, got {max_cycles!r}")
        self.render_mode = None
        self.max_cycles = max_cycles
        sit_options, traffic_options = split_options(options, where)
        sit = traffic_situation(situation, where=where, **sit_options)
        self.traffic = Traffic(sit, range(len(sit.names)), where=where, **traffic_options)
        self.possible_agents = list(sit.names)
        self._index = {name: i for i, name in enumerate(self.possible_agents)}
        lo, hi = self.traffic.bounds_scaled()
        self._observation_spaces = {a: spaces.Box(lo.astype(np.float32), hi.astype(np.float32), lo.shape, np.float32)
                                    for a in self.possible_agents}
        self._action_spaces = {a: spaces.Box(-1.0, 1.0, (2,), np.float32) for a in self.possible_agents}
        self.agents = []
        self._reset_done = False   # step() before the first reset() is a user's mistake, said as such
        self.np_random, _ = seeding.np_random(None)
        self._cycles = 0
        self._where = where

    def observation_space(self, agent):
        """The agent's observation space (the same object at every call)."""
        return self._observation_spaces[agent]

    def action_space(self, agent):
        """The agent's action space (the same object at every call)."""
        return self._action_spaces[agent]

    def reset(self, seed=None, options=None):
        if seed is not None:
            self.np_random, _ = seeding.np_random(seed)
        self.traffic.reset()
        self.agents = list(self.possible_agents)
        self._reset_done = True
        self._cycles = 0
        observations, infos = {}, {}
        for a in self.agents:
            observations[a], infos[a] = self._observe(a, None)
        return observations, infos

    def step(self, actions):
        if not self._reset_done:
            raise ValueError(f"{self._where}: step before reset(): call reset() first")
        unknown = sorted(set(actions) - set(self.agents), key=str)
        if unknown:
            raise ValueError(f"{self._where}: step: actions for agents that are not acting: {unknown}; "
                             f"agents: {self.agents}")
        forces = {}
        for a, action in actions.items():
            i = self._index[a]
            lo, hi = self.traffic.bounds[i]
            forces[i] = physical_action(checked_action(action, f"{self._where}: step: agent {a!r}"), lo, hi)
        live = list(self.agents)
        res = self.traffic.step(forces)
        self._cycles += 1
        out = ({}, {}, {}, {}, {})
        for a in live:
            i = self._index[a]
            end = res.ended.get(i)
            if end is None and self.max_cycles is not None and self._cycles >= self.max_cycles:
                end = ("time_limit", f"max_cycles = {self.max_cycles} steps")
                self.traffic.done[i] = True
                self.traffic.end[i] = end
            out[0][a], out[4][a] = self._observe(a, end)
            out[1][a] = res.rewards[i]
            out[2][a] = bool(end is not None and end[0] != "time_limit")
            out[3][a] = bool(end is not None and end[0] == "time_limit")
        self.agents = [a for a in live if not (out[2][a] or out[3][a])]
        return out

    def _observe(self, agent, end):
        i = self._index[agent]
        tr = self.traffic
        obs, names = scaled_observation(tr, i)
        rng = [float(r) for j, r in enumerate(tr.geometry[i, :, G_RANGE]) if j != i]
        info = {"time": tr.t, "kind": None if end is None else end[0], "reason": None if end is None else end[1],
                **tr.last_controls(i), "goal_distance": float(tr.goal_distances()[i]),
                "min_range": float(np.nan_to_num(min(rng), nan=np.inf)), "targets": names}
        return obs, info

    def state(self) -> np.ndarray:
        """Every vessel's (x, y, psi, u, v, r), flattened (the global state)."""
        return np.asarray(self.traffic.X, dtype=np.float64).reshape(-1).copy()

    def render(self):
        return None

    def close(self):
        self.traffic.close()


def traffic_parallel_env(situation=1, **options) -> TrafficParallelEnv:
    """A :class:`TrafficParallelEnv` (the options of its module docstring)."""
    return TrafficParallelEnv(situation, **options)
