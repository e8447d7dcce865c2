"""``usv_mj/Encounter-v0``: the own ship among other vessels, as a ``gymnasium.Env`` (issue 35, item 6).

::

    import gymnasium, usv_mj.envs
    env = gymnasium.make("usv_mj/Encounter-v0", situation=5)        # Imazu case 5: head-on + crossing
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    info["kind"], info["reason"]      # "collision", "goal", "diverged", "time_limit" (None while it runs)
    env.unwrapped.decode(obs)         # the observation in physical units

The simulation, the observation, the reward and the end of an episode are
:mod:`usv_mj.envs.traffic`'s, with the own ship the one agent: the other vessels follow their own
controllers (an Imazu case's targets keep course and speed by LOS on their straight course, or run
``target_controller``, any registered controller, e.g. a collision-avoidance one).

Options (keywords of ``gymnasium.make`` or :class:`EncounterEnv`):

- ``situation``: an Imazu case 1-22 (default 1), a scenario with ``[[vessels]]`` (a
  :class:`usv_mj.scenario.spec.Scenario` or a file's path), a list of these (one drawn per episode
  with the environment's random generator) or ``"imazu"`` (all 22). ``reset(options={"situation": x})``
  runs ``x`` in that episode.
- An Imazu case's placement (:func:`usv_mj.envs.traffic.traffic_situation`): ``vessel`` (the own
  ship's kind, default ``"otter"``: 2 m), ``target_vessel`` (default the own's), ``speed`` U [m/s]
  (1.0), ``k_R`` (R = k_R L, default 50: R = 100 m, T = R / U = 100 s for the Otter), ``target_controller``;
  and for any situation ``plant`` (``"mujoco"``, the default, or ``"analytic"``), ``control_period``
  [s] (0.01), ``substeps`` (10), ``duration`` [s] (3 T), ``goals``, ``overrides`` (scenario tables,
  e.g. ``{"sea": {"preset": "moderate"}}``).
- The agent (:class:`usv_mj.envs.traffic.Traffic`): ``action_repeat`` (control periods per step,
  10: a step of 0.1 s), ``quantize`` (True), ``max_surge_force`` / ``max_yaw_moment`` (the bounds of
  an unlimited channel, 1000), ``max_targets`` (3 slots), ``sensor_range`` [m] (3 R), ``goal_radius``
  [m] (2 L), ``domain_penalty`` (0.1 per second at full depth), ``goal_reward`` (1), ``collision_penalty`` (5).
- ``physical_actions`` (False): the action in newtons, ``Box(low, high)`` of the Track task's
  bounds (:func:`usv_mj.envs.tasks.action_bounds`), instead of the normalized ``Box(-1, 1)``.

Action: (surge force, yaw moment), by default normalized as the Track view's (+1 the largest forward
force / counter-clockwise moment, -1 the largest astern / clockwise one), then the own ship's control
step: clip, quantize (Eq. 3), its actuators. Observation: one float32 vector, the own block
(u, v, r, the goal in the body frame) and ``max_targets`` slots (mask, relative position and
velocity in the body frame, range, sine and cosine of the relative bearing, DCPA, TCPA), scaled
(lengths / R, speeds / U, times / T, the yaw rate / (U / L)) and clipped to +-10.

``info``: ``time`` [s], ``situation``, ``kind`` and ``reason`` (None while the episode runs),
``action`` (the clipped thrust [N, N m]), ``command`` (after the quantizer), ``thrust`` (the
actuators' force), ``goal_distance`` [m], ``min_range`` [m] to the nearest other vessel and
``targets`` (the vessels' names in the slots, nearest first).
"""

from __future__ import annotations

import math

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
    from gymnasium.error import ResetNeeded
except ImportError:  # pragma: no cover - optional dependency
    from usv_mj.core.errors import missing_extra

    raise missing_extra("gymnasium", "usv_mj/Encounter-v0 (usv_mj.envs.encounter_env)") from None

from usv_mj.envs.traffic import (ALL_IMAZU, Traffic, checked_action, decode_observation, physical_action,
                                 scaled_observation, split_options, traffic_situation)
from usv_mj.physics.encounters import G_RANGE
from usv_mj.scenario.imazu import IMAZU_CASES


def _key(situation):
    """A hashable key of one situation (the cache of built fleets)."""
    if isinstance(situation, (int, np.integer)) and not isinstance(situation, bool):
        return ("imazu", int(situation))
    if isinstance(situation, str):
        return ("file", situation)
    return ("object", id(situation))


class EncounterEnv(gymnasium.Env):
    """The own ship among other vessels (module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, situation=1, *, render_mode=None, physical_actions: bool = False, **options):
        where = "usv_mj/Encounter-v0"
        if render_mode is not None:
            raise ValueError(f"{where}: render_mode must be None (the encounter has no frames yet), got {render_mode!r}")
        self.render_mode = None
        self._where = where
        self._situation_options, self._traffic_options = split_options(options, where)
        if isinstance(situation, str) and situation == ALL_IMAZU:
            choices = tuple(sorted(IMAZU_CASES))
        elif isinstance(situation, (list, tuple)):
            if not situation:
                raise ValueError(f"{where}: situation: an empty list")
            choices = tuple(situation)
        else:
            choices = (situation,)
        self.situations = choices
        self.physical_actions = bool(physical_actions)
        self._built = {}
        self.traffic = None
        self.traffic = self._traffic(choices[0])
        lo, hi = self.traffic.bounds[self.traffic.situation.own_index]
        self._low, self._high = lo.copy(), hi.copy()
        if self.physical_actions:
            self.action_space = spaces.Box(lo.astype(np.float64), hi.astype(np.float64), (2,), np.float64)
        else:
            self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        olo, ohi = self.traffic.bounds_scaled()
        self.observation_space = spaces.Box(olo.astype(np.float32), ohi.astype(np.float32), olo.shape, np.float32)
        self._over = True

    # --- situations --------------------------------------------------------------------------------

    def _traffic(self, situation) -> Traffic:
        key = _key(situation)
        traffic = self._built.get(key)
        if traffic is None:
            sit = traffic_situation(situation, where=self._where, **self._situation_options)
            traffic = Traffic(sit, [sit.own_index], where=self._where, **self._traffic_options)
            if self.traffic is not None:
                lo, hi = traffic.bounds[sit.own_index]
                if self.physical_actions and not (np.array_equal(lo, self._low) and np.array_equal(hi, self._high)):
                    traffic.close()
                    raise ValueError(f"{self._where}: situation {sit.name}: its own ship's action bounds {lo.tolist()}, "
                                     f"{hi.tolist()} differ from the action space's ({self._low.tolist()}, "
                                     f"{self._high.tolist()}); physical_actions needs one own vessel")
                if traffic.obs_size != self.traffic.obs_size:   # pragma: no cover - max_targets is one option
                    traffic.close()
                    raise ValueError(f"{self._where}: situation {sit.name}: another observation size")
            self._built[key] = traffic
        return traffic

    @property
    def own(self) -> int:
        return self.traffic.situation.own_index

    # --- gymnasium.Env -------------------------------------------------------------------------------

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - {"situation"})
        if unknown:
            raise ValueError(f"{self._where}: reset: unknown options {unknown}; reset takes 'situation'")
        if "situation" in options:
            situation = options["situation"]
        elif len(self.situations) == 1:
            situation = self.situations[0]
        else:
            situation = self.situations[int(self.np_random.integers(len(self.situations)))]
        self.traffic = self._traffic(situation)
        self.traffic.reset()
        self._over = False
        self._kind, self._reason = None, None
        obs, names = scaled_observation(self.traffic, self.own)
        return obs, self._info(names)

    def step(self, action):
        """One step (``action_repeat`` control periods). After the step that ended the episode, or
        before the first reset, raises ``gymnasium.error.ResetNeeded``."""
        if self._over:
            raise ResetNeeded(f"{self._where}: step: the episode has ended (the last step returned terminated or "
                              f"truncated) or was never started; call reset() first")
        a = checked_action(action, f"{self._where}: step")
        if self.physical_actions:
            f = (float(a[0]), float(a[1]))
        else:
            lo, hi = self.traffic.bounds[self.own]
            f = physical_action(a, lo, hi)
        res = self.traffic.step({self.own: f})
        reward = res.rewards[self.own]
        end = res.ended.get(self.own)
        terminated = truncated = False
        if end is not None:
            self._kind, self._reason = end
            terminated = end[0] != "time_limit"
            truncated = not terminated
            self._over = True
        obs, names = scaled_observation(self.traffic, self.own)
        return obs, float(reward), terminated, truncated, self._info(names)

    def _info(self, names) -> dict:
        tr, i = self.traffic, self.own
        rng = tr.geometry[i, :, G_RANGE]
        others = [float(r) for j, r in enumerate(rng) if j != i]
        return {"time": tr.t, "situation": tr.situation.name, "kind": self._kind, "reason": self._reason,
                **tr.last_controls(i), "goal_distance": float(tr.goal_distances()[i]),
                "min_range": min(others) if others and all(map(math.isfinite, others)) else math.inf,
                "targets": names}

    def decode(self, observation) -> dict:
        """The physical observation (the present situation's scales) of a scaled one:
        ``{"own": {"u", "v", "r", "goal_x", "goal_y"}, "targets": (max_targets, 10)}`` with the columns
        of :data:`usv_mj.envs.traffic.TARGET_FIELDS`."""
        return decode_observation(self.traffic, self.own, observation)

    def physical_action(self, action) -> tuple[float, float]:
        """The thrust (tau_u [N], tau_r [N m]) an action stands for (before the control step's clip)."""
        if self.physical_actions:
            a = np.asarray(action, dtype=np.float64).reshape(2)
            return float(a[0]), float(a[1])
        lo, hi = self.traffic.bounds[self.own]
        return physical_action(action, lo, hi)

    def render(self):
        return None

    def close(self):
        for traffic in self._built.values():
            traffic.close()
        self._built.clear()
        super().close()
