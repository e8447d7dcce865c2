"""The USV tasks (``dm_control.suite.base.Task`` subclasses): what is observed, rewarded and ends.

Conventions (all tasks)
-----------------------
Action: ``thrust`` = (tau_u [N], tau_r [N m]), a ``specs.BoundedArray`` whose bounds are the
scenario's actuator limits (``scenario.actuators.generalized_limits()``) where they are finite, else
+-``max_surge_force`` / +-``max_yaw_moment`` (1000 N, 1000 N m: the paper's ship has no thrust
limits); values outside are clipped, non-finite ones raise ValueError. With ``quantize=True`` the clipped action goes through the hysteresis quantizer of Eq. 3
(docs/model.md §2; the scenario's delta and u_min per channel), exactly as in :func:`usv_mj.simulation.simulate`.
The (quantized) thrust is held over the control period: ``n_sub_steps`` = ``plant.substeps`` RK4
steps of the plant's time step.

Observations (an OrderedDict of float64 arrays; "body frame" = rotated by -psi, x forward):

- ``position_error`` (2,): R(psi)^T (p - p_d) [m], the hull origin minus the reference position;
- ``heading_error`` (1,): wrap(psi - psi_d) [rad] in [-pi, pi);
- ``heading`` (2,): (cos psi, sin psi) (the funnel of Eq. 9 bounds world-frame errors);
- ``velocity`` (3,): (u, v, r) [m/s, m/s, rad/s];
- ``velocity_error`` (3,): R(psi)^T (x_d_dot, y_d_dot) - (u, v) [m/s] and r_d - r [rad/s] (the
  reference's velocity in the body frame minus the hull's; r_d alone is constant on most of the
  paper's reference, so it is observed against r);
- ``reference_preview`` (n, 2): R(psi)^T (p_d(t + tau_k) - p) [m] at the preview times tau_k
  (default 0.5, 1, 2, 4 s);
- ``funnel`` (2,): rho_xy(t) [m], rho_psi(t) [rad] of Eq. 9 (the prescribed performance);
- ``time`` (1,): t [s], in [0, time limit];
- harbor only: ``goal`` (3,): R(psi)^T (p_goal - p) [m] and wrap(psi_goal - psi) [rad];
  ``rangefinder`` (n_rays,): distance [m] from the hull origin to the first obstacle along rays
  fanned evenly around the hull (first ray at the bow, counter-clockwise), ``max_range`` when none.

Rewards (per step, in [0, 1], ``dm_control.utils.rewards.tolerance``):

- track tasks: (2 r_pos + r_psi)/3 with r_pos = tolerance(|p - p_d|, bounds (0, 0.25 m), margin
  2 m, gaussian) and r_psi = tolerance(|heading_error|, bounds (0, 0.1 rad), margin 0.5 rad, gaussian);
- harbor: r_clear (r_goal + (2 r_pos + r_psi)/3)/2 with r_goal = tolerance(|p_goal - p|, bounds
  (0, goal_radius), margin = the start's distance, linear), r_pos/r_psi against the planned
  reference, r_clear = tolerance(min clearance, bounds (margin_m, inf), margin margin_m, linear)
  (0 at contact).

The specs of ``heading_error``, ``heading``, ``funnel``, ``time`` and ``rangefinder`` are
``BoundedArray`` s (their bounds hold by construction); the others are unbounded ``Array`` s (the
Gymnasium view, :mod:`usv_mj.envs.gymnasium_env`, bounds them through the termination thresholds).

Termination (``get_termination`` -> discount 0, reason in ``task.termination_reason`` and
``task.info``): ``diverged`` (the hydrodynamic callback failed, or the state left
``scenario.limits``: :func:`usv_mj.simulation.state_limit_exceeded`, the loop's own check), ``lost``
(distance to the reference >= ``max_distance``); in harbor also ``contact`` with an obstacle
(MuJoCo contact or clearance <= 0) and ``goal`` (|p - p_goal| < goal_radius). The time limit ends
the episode with discount 1 and kind ``time_limit``.
"""

from __future__ import annotations

import collections
import math
import warnings
from typing import NamedTuple

import numpy as np

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # dm_control's GLFW probe (see usv_mj.obstacles.compose)
    from dm_control.suite import base
from dm_env import specs

from usv_mj.builder import make_quantizers
from usv_mj.controllers.performance_funnel import funnels_of
from usv_mj.simulation import _which_limit, make_reference

from . import native

DEFAULT_PREVIEW = (0.5, 1.0, 2.0, 4.0)


DEFAULT_FORCE = 1000.0  # N and N m: the action bound of a channel whose actuator is unlimited


def action_bounds(scenario, max_surge_force: float = DEFAULT_FORCE, max_yaw_moment: float = DEFAULT_FORCE):
    """(low, high) of the action [N, N m]: the actuators' generalized limits where finite, else
    -+``max_surge_force`` / -+``max_yaw_moment`` (one number each side, so the task and the plant's
    ctrlrange come from the same figures)."""
    u_lo, u_hi, r_lo, r_hi = scenario.actuators.generalized_limits()
    low = np.array([u_lo if math.isfinite(u_lo) else -float(max_surge_force),
                    r_lo if math.isfinite(r_lo) else -float(max_yaw_moment)])
    high = np.array([u_hi if math.isfinite(u_hi) else float(max_surge_force),
                     r_hi if math.isfinite(r_hi) else float(max_yaw_moment)])
    return low, high


#: dm_control's Gaussian sigmoid scale for value_at_margin = 0.1, computed as it computes it (numpy)
_GAUSS_SCALE = np.sqrt(-2 * np.log(0.1))


def _tol_gaussian(x: float, lower: float, upper: float, margin: float) -> float:
    """``rewards.tolerance(x, (lower, upper), margin, "gaussian", value_at_margin=0.1)`` of a float,
    with dm_control's own numpy operations where they define the result (the power and the exp)."""
    if lower <= x <= upper:
        return 1.0
    d = np.float64(lower - x if x < lower else x - upper) / margin
    return float(np.exp(-0.5 * (d * _GAUSS_SCALE) ** 2))


def _tol_linear(x: float, lower: float, upper: float, margin: float) -> float:
    """``rewards.tolerance(x, (lower, upper), margin, "linear", value_at_margin=0.0)`` of a float."""
    if lower <= x <= upper:
        return 1.0
    d = (lower - x if x < lower else x - upper) / margin
    return 1 - d if abs(d) < 1 else 0.0


def _tol_pos(d: float) -> float:
    return _tol_gaussian(d, 0.0, 0.25, 2.0)


def _tol_psi(e: float) -> float:
    return _tol_gaussian(abs(e), 0.0, 0.1, 0.5)


class _Step(NamedTuple):
    """One evaluation of the task at a state (:meth:`TrackTask._evaluate`)."""

    refs: np.ndarray        # reference rows: at t, then at t + each preview time
    obs: np.ndarray         # the observation vector (observation_shapes order)
    ex: float               # position error x - x_d, y - y_d [m] of the state read finite (non-finite -> 0)
    ey: float
    e_psi: float            # wrap(psi - psi_d) [rad]
    diverged: bool          # the raw state left scenario.limits or is not finite
    x: np.ndarray           # the key: the state array, time, physics and reference it is for
    t: float
    physics: object
    reference: object
    handed: list            # [True] once obs was handed out (the next one gets a copy)


class TrackTask(base.Task):
    """Follow the scenario's reference (docs/model.md §4 for the paper preset) from a randomised start.

    The start pose is the reference's pose at t = 0 plus uniform offsets of at most
    ``start_offset`` = (dx [m], dy [m], dpsi [rad]), at rest. See the module docstring for the
    action, observations, reward and termination.

    Parameters: ``scenario`` (:class:`usv_mj.scenario.Scenario`), ``quantize`` (bool),
    ``max_surge_force`` [N], ``max_yaw_moment`` [N m], ``preview_times`` [s], ``start_offset``,
    ``max_distance`` [m], ``random`` (seed or RandomState).
    """

    def __init__(self, scenario, quantize: bool = True, max_surge_force: float = DEFAULT_FORCE,
                 max_yaw_moment: float = DEFAULT_FORCE, preview_times=DEFAULT_PREVIEW, start_offset=(3.0, 3.0, 0.5),
                 max_distance: float = 50.0, reference=None, random=None, time_limit: float = math.inf):
        for name, value in (("max_surge_force", max_surge_force), ("max_yaw_moment", max_yaw_moment),
                            ("max_distance", max_distance)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{type(self).__name__}: {name} must be a finite number > 0, got {value!r}")
        preview = np.asarray(preview_times, dtype=float).reshape(-1)
        if preview.size == 0 or not np.all(np.isfinite(preview)) or np.any(preview <= 0):
            raise ValueError(f"{type(self).__name__}: preview_times must be finite times > 0 s, got {preview_times!r}")
        offset = np.asarray(start_offset, dtype=float).reshape(-1)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)) or np.any(offset < 0):
            raise ValueError(f"{type(self).__name__}: start_offset must be 3 finite numbers >= 0, got {start_offset!r}")
        super().__init__(random=random)
        self.scenario = scenario
        self.quantize = bool(quantize)
        self.max_distance = float(max_distance)
        self.preview_times = preview
        self.start_offset = offset
        self.action_low, self.action_high = action_bounds(scenario, max_surge_force, max_yaw_moment)
        self._bounds_t = (float(self.action_low[0]), float(self.action_high[0]),
                          float(self.action_low[1]), float(self.action_high[1]))
        self.time_limit = float(time_limit)
        self._ref_t = None          # cache: the reference at the last time asked for
        self._ref = None
        self.reference = reference if reference is not None else make_reference(scenario)
        self.funnel_xy, self.funnel_psi = funnels_of(scenario)
        q_u, q_r = make_quantizers(scenario)
        self._qp = ((q_u.params.delta, q_u.params.u_min), (q_r.params.delta, q_r.params.u_min))
        self._act_p = np.array([*self._bounds_t, *self._qp[0], *self._qp[1]], dtype=np.float64)
        self._k = np.zeros(2, dtype=np.int64)  # the quantizers' signed level indices
        self.last_action = np.zeros(2)      # clipped action [N, N m]
        self.last_thrust = np.zeros(2)      # after the quantizer: what the plant got
        self.termination_reason: str | None = None
        self.termination_kind: str | None = None
        self.episode_scenario = scenario  # what the plant was built from (harbor: with the layout's obstacles)
        # per-step evaluation (usv_mj.envs.native): one call for the observation vector, the
        # reference rows and the reward's and termination's numbers, kept for the step's state
        self._params = np.zeros(native.N_PARAMS)
        self._n_obs = native.N_HEAD + 2 * preview.size + native.N_TAIL
        self._evaluator = None
        self._ev = None
        self._ctrl_of = (None, None)  # (physics, its data.ctrl)
        TrackTask._fill_params(self, self._params)

    # --- episode -------------------------------------------------------------------------------

    def start_pose(self):
        """The randomised initial (eta0, nu0) of an episode (uses ``self.random``)."""
        ref = self.reference.evaluate(0.0)
        d = self.random.uniform(-1.0, 1.0, size=3) * self.start_offset
        return np.array([ref[0] + d[0], ref[1] + d[1], ref[2] + d[2]]), np.zeros(3)

    def initialize_episode(self, physics):
        self._k[:] = 0
        self._ref_t = None
        self._ev = None
        self._fill_params(self._params)
        self.last_action[:] = 0.0
        self.last_thrust[:] = 0.0
        self.termination_reason = None
        self.termination_kind = None
        eta0, nu0 = self.start_pose()
        physics.set_initial_state(eta0, nu0)

    def action_spec(self, physics):
        return specs.BoundedArray((2,), np.float64, self.action_low.copy(), self.action_high.copy(), name="thrust")

    def before_step(self, action, physics):
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2,):
            raise ValueError(f"{type(self).__name__}: action must be (tau_u [N], tau_r [N m]), shape (2,), "
                             f"got shape {a.shape}")
        a0, a1 = a
        if not (math.isfinite(a0) and math.isfinite(a1)):
            raise ValueError(f"{type(self).__name__}: action must be finite, got {a.tolist()}")
        self._ev = None  # the state is about to change
        of, ctrl = self._ctrl_of
        if of is not physics:
            ctrl = physics.plant.data.ctrl
            self._ctrl_of = (physics, ctrl)
        # clip, quantize (Eq. 3) and write last_action, last_thrust and ctrl in one native call
        native.act_kernel(float(a0), float(a1), self._act_p, self.quantize, self._k, self.last_action,
                          self.last_thrust, ctrl)

    def after_step(self, physics):
        if self.termination_reason is not None:
            return
        t = physics.time()
        if physics.failure is not None:
            self._terminate("diverged", physics.failure)
            return
        ev = self._evaluate(physics)
        if ev.diverged:  # usv_mj.simulation.state_limit_exceeded, or not finite
            x, ref = physics.state, ev.refs[0]
            ex, ey = x[0] - ref[0], x[1] - ref[1]
            lim = self.scenario.limits
            self._terminate("diverged", f"state left its limits at t = {t:.3f} s: {_which_limit(x, ex, ey, lim)}")
            return
        dist = math.hypot(ev.ex, ev.ey)  # the state is finite here: ex, ey are those of the raw state
        if dist >= self.max_distance:
            self._terminate("lost", f"distance to the reference {dist:.3g} m reached max_distance = "
                                    f"{self.max_distance:g} m at t = {t:.3f} s")

    def _terminate(self, kind: str, reason: str) -> None:
        self.termination_kind = kind
        self.termination_reason = f"{kind}: {reason}"

    def get_termination(self, physics):
        return 0.0 if self.termination_reason is not None else None

    def mark_time_limit(self, t: float) -> None:
        """The environment ended the episode at its time limit (discount 1): say so in :attr:`info`."""
        if self.termination_reason is None:
            self._terminate("time_limit", f"reached the time limit at t = {t:.3f} s")

    @property
    def info(self) -> dict:
        """Why the episode ended (``kind``: None while it runs, else "diverged", "lost", "contact",
        "goal" or "time_limit"; ``reason``: one sentence), the last action and the thrust the plant got."""
        return {"kind": self.termination_kind, "reason": self.termination_reason,
                "action": self.last_action.copy(), "thrust": self.last_thrust.copy()}

    # --- observations and reward ---------------------------------------------------------------

    def reference_at(self, t: float) -> np.ndarray:
        """The reference vector (REF_FIELDS) at t [s] (cached for the current step; do not modify)."""
        if t != self._ref_t or self._ref is None:
            self._ref = self.reference.evaluate(t).copy()
            self._ref_t = t
        return self._ref

    def _frame(self, physics):
        x = self._finite_state(physics)
        return x, math.cos(x[2]), math.sin(x[2])

    @staticmethod
    def _finite_state(physics):
        """The state with non-finite entries read as 0 (what the observations and rewards see)."""
        x = physics.state
        if not (math.isfinite(x[0]) and math.isfinite(x[1]) and math.isfinite(x[2]) and math.isfinite(x[3])
                and math.isfinite(x[4]) and math.isfinite(x[5])):
            x = np.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0)
        return x

    # --- the per-step evaluation ---------------------------------------------------------------
    #
    # One native call per step (usv_mj.envs.native) gives the reference rows, the observation
    # vector and the numbers of the reward and the termination; after_step, get_reward and
    # get_observation share it. It is kept for the state it was computed at: the same state array
    # (the plant hands a new one at every step, and a reset a fresh one at every read), the same
    # time, physics and reference, and it is dropped at before_step and at every episode.

    _has_goal = False  # harbor: the observation vector carries the goal after the time

    def _fill_params(self, p) -> None:
        """The task's constant numbers for :func:`native.track_observe` (filled at every episode)."""
        fx, fp, lim = self.funnel_xy, self.funnel_psi, self.scenario.limits
        p[native.P_RHO_XY0], p[native.P_RHO_XYINF], p[native.P_RATE_XY] = fx.rho_0, fx.rho_inf, fx.rate
        p[native.P_RHO_P0], p[native.P_RHO_PINF], p[native.P_RATE_P] = fp.rho_0, fp.rho_inf, fp.rate
        p[native.P_MAX_SPEED], p[native.P_MAX_YAW_RATE] = lim.max_speed, lim.max_yaw_rate
        p[native.P_MAX_DISTANCE] = lim.max_distance

    def _n_observed(self) -> int:
        """Length of the observation vector."""
        return self._n_obs

    def _evaluate(self, physics) -> _Step:
        """The task at the physics' state and time (:class:`native.StepEvaluator`, then
        :meth:`_complete`), or the evaluation already made there."""
        x = physics.state
        t = physics.time()
        ev = self._ev
        if ev is not None and ev.x is x and ev.t == t and ev.physics is physics and ev.reference is self.reference:
            return ev
        evaluator = self._evaluator
        if evaluator is None or evaluator.reference is not self.reference:
            evaluator = self._evaluator = native.StepEvaluator(self.reference, self.preview_times)
        refs, obs, ex, ey, e_psi, diverged = evaluator(x, t, self._params, self._n_observed(), self._has_goal)
        self._ref, self._ref_t = refs[0], t
        self._complete(obs, physics)
        ev = self._ev = _Step(refs, obs, ex, ey, e_psi, diverged, x, t, physics, self.reference, [False])
        return ev

    def _complete(self, obs, physics) -> None:
        """Fill what the native evaluation left of the observation vector (harbor: the rangefinders)."""

    def _observation_vector(self, physics) -> np.ndarray:
        """The step's observation vector (a fresh array for every observation handed out)."""
        ev = self._evaluate(physics)
        if ev.handed[0]:
            return ev.obs.copy()
        ev.handed[0] = True
        return ev.obs

    def get_observation(self, physics):
        return self._split(self._observation_vector(physics))

    def _split(self, v):
        """The observation dict of the vector ``v`` (views of it, in observation_shapes order)."""
        n = self.preview_times.size
        j = native.N_HEAD + 2 * n
        obs = collections.OrderedDict()
        obs["position_error"] = v[0:2]
        obs["heading_error"] = v[2:3]
        obs["heading"] = v[3:5]
        obs["velocity"] = v[5:8]
        obs["velocity_error"] = v[8:11]
        obs["reference_preview"] = v[11:j].reshape(n, 2)
        obs["funnel"] = v[j:j + 2]
        obs["time"] = v[j + 2:j + 3]
        return obs

    def observation_spec(self, physics):
        spec = collections.OrderedDict()
        bounds = self.observation_bounds()
        for name, shape in self.observation_shapes():
            if name in bounds:
                lo, hi = bounds[name]
                spec[name] = specs.BoundedArray(shape, np.float64, np.broadcast_to(lo, shape).copy(),
                                                np.broadcast_to(hi, shape).copy(), name=name)
            else:
                spec[name] = specs.Array(shape, np.float64, name=name)
        return spec

    def observation_shapes(self):
        """(name, shape) of every observation, in order (the flat layouts concatenate them so)."""
        return [("position_error", (2,)), ("heading_error", (1,)), ("heading", (2,)), ("velocity", (3,)),
                ("velocity_error", (3,)), ("reference_preview", (self.preview_times.size, 2)),
                ("funnel", (2,)), ("time", (1,))]

    def observation_bounds(self) -> dict:
        """name -> (low, high) of the observations bounded by construction."""
        fx, fp = self.funnel_xy, self.funnel_psi
        lo_f = [min(fx.rho_0, fx.rho_inf), min(fp.rho_0, fp.rho_inf)]
        hi_f = [max(fx.rho_0, fx.rho_inf), max(fp.rho_0, fp.rho_inf)]
        t_hi = self.time_limit if math.isfinite(self.time_limit) else np.finfo(np.float64).max
        return {"heading_error": (-math.pi, math.pi), "heading": (-1.0, 1.0),
                "funnel": (np.array(lo_f), np.array(hi_f)), "time": (0.0, t_hi)}

    def tracking_reward(self, physics) -> float:
        ev = self._evaluate(physics)
        return (2.0 * _tol_pos(math.hypot(ev.ex, ev.ey)) + _tol_psi(ev.e_psi)) / 3.0

    def get_reward(self, physics):
        return self.tracking_reward(physics)


class HarbourTask(TrackTask):
    """Reach a goal through a randomised harbour (piers with a gap, then a buoy field) without contact.

    Each episode draws a layout (:func:`usv_mj.envs.layout.harbour_layout`), plans the guidance
    reference around it (:func:`usv_mj.obstacles.planner.plan_reference`; the reference observed is
    that plan) and builds the harbour physics with rangefinders (the environment rebuilds the model
    when the layout changes: see :class:`usv_mj.envs.USVEnvironment`). Observations add ``goal`` and
    ``rangefinder``; the reward adds the goal distance and the clearance; contact ends the episode
    (module docstring).
    """

    def __init__(self, scenario, *, n_rays: int = 16, max_range: float = 20.0, goal_radius: float = 1.5,
                 margin_m: float = 0.3, **kwargs):
        if not (isinstance(n_rays, int) and n_rays >= 1):
            raise ValueError(f"HarbourTask: n_rays must be an integer >= 1, got {n_rays!r}")
        for name, value in (("max_range", max_range), ("goal_radius", goal_radius)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"HarbourTask: {name} must be a finite number > 0, got {value!r}")
        kwargs.setdefault("start_offset", (0.0, 0.0, 0.0))
        super().__init__(scenario, **kwargs)
        self.n_rays = n_rays
        self.ray_angles = 2.0 * math.pi * np.arange(n_rays) / n_rays
        self.max_range = float(max_range)
        self.goal_radius = float(goal_radius)
        self.margin_m = float(margin_m)
        self.layout = None          # set by the environment before each episode
        self.monitor = None
        self.min_clearance = math.inf
        self._start_distance = 1.0

    def attach_layout(self, layout, monitor, episode_scenario=None) -> None:
        """Use ``layout`` (:class:`usv_mj.envs.layout.HarbourLayout`), its clearance monitor and the
        episode's scenario (the task's with the layout's obstacles: what the plant was built from)."""
        self.layout = layout
        self.episode_scenario = episode_scenario if episode_scenario is not None else self.scenario
        self.reference = layout.plan.reference
        self._ref_t = None
        self._ev = None
        self.monitor = monitor
        self._fill_params(self._params)

    def start_pose(self):
        lay = self.layout
        return np.array([lay.start[0], lay.start[1], lay.psi0]), np.zeros(3)

    def initialize_episode(self, physics):
        super().initialize_episode(physics)
        g = self.layout.goal
        self._start_distance = max(math.hypot(g[0] - self.layout.start[0], g[1] - self.layout.start[1]), 1e-6)
        self.min_clearance = self._clearance(physics)

    def before_step(self, action, physics):
        super().before_step(action, physics)
        physics.plant.move_obstacles(physics.time())

    def _clearance(self, physics) -> float:
        c = self.monitor.update(physics.time(), physics.plant)
        # any contact or c <= 0, np.argmin(c) and np.min(c) in one native call
        self._contact, self._nearest, c_min = native.clearance_summary(c, self.monitor.in_contact)
        return c_min

    def after_step(self, physics):
        super().after_step(physics)
        self.min_clearance = self._clearance(physics)
        if self.termination_reason is not None:
            return
        t = physics.time()
        x = physics.state
        if self._contact:
            name = self.layout.obstacles[self._nearest].name if self._nearest >= 0 else "?"
            self._terminate("contact", f"hull touched obstacle {name!r} at t = {t:.3f} s "
                                       f"(clearance {self.min_clearance:.3f} m)")
        elif math.hypot(x[0] - self.layout.goal[0], x[1] - self.layout.goal[1]) < self.goal_radius:
            self._terminate("goal", f"reached the goal at t = {t:.3f} s")

    _has_goal = True

    def _n_observed(self) -> int:
        return self._n_obs + 3 + self.n_rays

    def _fill_params(self, p) -> None:
        super()._fill_params(p)
        if self.layout is None:
            return
        g = self.layout.goal
        p[native.P_GOAL_X], p[native.P_GOAL_Y], p[native.P_PSI_GOAL] = g[0], g[1], self.layout.psi_goal

    def _complete(self, obs, physics) -> None:
        native.clip_ranges(obs, self._n_obs + 3, physics.plant.rangefinders(), self.max_range)

    def _split(self, v):
        obs = super()._split(v)
        j = self._n_obs
        obs["goal"] = v[j:j + 3]
        obs["rangefinder"] = v[j + 3:]
        return obs

    def observation_shapes(self):
        return super().observation_shapes() + [("goal", (3,)), ("rangefinder", (self.n_rays,))]

    def observation_bounds(self) -> dict:
        return {**super().observation_bounds(), "rangefinder": (0.0, self.max_range)}

    def get_reward(self, physics):
        x = self._finite_state(physics)
        g = self.layout.goal
        d_goal = math.hypot(x[0] - g[0], x[1] - g[1])
        r_goal = _tol_linear(d_goal, 0.0, self.goal_radius, self._start_distance)
        if self.margin_m > 0:
            r_clear = _tol_linear(self.min_clearance, self.margin_m, math.inf, self.margin_m)
        else:
            r_clear = 1.0 if self.min_clearance > 0 else 0.0
        return r_clear * 0.5 * (r_goal + self.tracking_reward(physics))
