"""Policies for the USV environments: the paper's controller and uniform random actions.

A policy is a callable ``policy(time_step) -> action`` (numpy (2,) = (tau_u [N], tau_r [N m])).
"""

from __future__ import annotations

import math

import numpy as np

from usv_mj.builder import make_controller


def _views(env):
    """(dm_env, gymnasium view or None) of ``env``: a USVEnvironment, or a Gymnasium env (wrapped or
    not) whose ``unwrapped`` is a :class:`usv_mj.envs.gymnasium_env.USVGymEnv`."""
    unwrapped = getattr(env, "unwrapped", env)
    if hasattr(unwrapped, "dm_env") and hasattr(unwrapped, "decode"):
        return unwrapped.dm_env, unwrapped
    return env, None


class PPCPolicy:
    """The adaptive PPC law (docs/model.md §3, Eqs. 14-37) run on the environment's observations.

    Works on both views: ``PPCPolicy(dm_env)`` is called with a ``dm_env.TimeStep`` and returns
    the thrust (tau_u [N], tau_r [N m]); ``PPCPolicy(gym_env)`` (``gymnasium.make("usv_mj/Track-v0")``
    or :func:`usv_mj.envs.gym_env`) is called with the Gymnasium observation and returns the
    normalized action in [-1, 1]^2. Flat observations (``flat_observation=True``, the Gymnasium
    view's default) are decoded first.

    What it reads
    -------------
    From the observation: ``time``, ``heading`` (cos psi, sin psi), ``position_error`` (body
    frame), ``velocity`` (u, v, r). From the environment: the task's reference trajectory
    (``env.task.reference_at(t)``: the same trajectory the ``reference_preview`` and
    ``velocity_error`` observations are sampled from; the law needs its pose, velocity and yaw
    rate at t) and the scenario's controller design (gains, nominal ship model, funnel, quantizer
    delta for Eq. 37's margin, control period). It does not read the physics: the world-frame pose
    is rebuilt as p = p_d + R(psi) position_error, psi = atan2(sin, cos) (within rounding of the
    plant's own state: about 1e-15 m in float64, 1e-6 m through the float32 Gymnasium view).

    The output is the unquantized law; the environment's quantizer (``quantize=True``) plays the
    actuator's role as in :func:`usv_mj.loop.simulate.simulate`. The first step of an episode (a FIRST
    time step; on the Gymnasium view, t = 0) resets the adaptive states (W = 0, s2 = 0).
    """

    def __init__(self, env, controller=None):
        self.env, self.gym = _views(env)
        if not hasattr(self.env, "task") or not hasattr(self.env.task, "reference_at"):
            from usv_mj.core.errors import expected

            raise expected("PPCPolicy", "env", "a usv_mj environment (usv_mj.envs.load) or its Gymnasium view "
                           "(usv_mj.envs.gym_env, gymnasium.make('usv_mj/Track-v0'))", env)
        task = self.env.task
        self.controller = controller if controller is not None else make_controller(task.scenario, "ppc")
        self._x = np.zeros(6)

    @property
    def reference(self):
        return self.env.task.reference  # read each call: the harbor task re-plans every episode

    def __call__(self, observation) -> np.ndarray:
        if self.gym is not None:
            obs = self.gym.decode(observation)
            first = float(obs["time"][0]) == 0.0
        else:
            obs = self.env.unflatten(observation.observation) if hasattr(self.env, "unflatten") \
                else observation.observation
            first = observation.first()
        if first:
            self.controller.reset()
        t = float(obs["time"][0])
        ref = self.env.task.reference_at(t)
        c, s = float(obs["heading"][0]), float(obs["heading"][1])
        eb = obs["position_error"]
        x = self._x
        x[0] = ref[0] + c * eb[0] - s * eb[1]
        x[1] = ref[1] + s * eb[0] + c * eb[1]
        x[2] = math.atan2(s, c)
        x[3:6] = obs["velocity"]
        tau_u, tau_r, _ = self.controller(t, x, ref)
        thrust = np.array([tau_u, tau_r])
        return thrust if self.gym is None else self.gym.normalized_action(thrust)


class RandomPolicy:
    """Actions drawn uniformly within the action spec's bounds (seeded ``numpy`` RandomState)."""

    def __init__(self, env, seed=None):
        spec = env.action_spec()
        self.low, self.high = np.asarray(spec.minimum, float), np.asarray(spec.maximum, float)
        self.random = np.random.RandomState(seed)

    def __call__(self, time_step) -> np.ndarray:
        return self.random.uniform(self.low, self.high)
