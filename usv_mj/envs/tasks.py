"""The USV tasks (``dm_control.suite.base.Task`` subclasses): what is observed, rewarded and ends.

Conventions (all tasks)
-----------------------
Action: ``thrust`` = (tau_u [N], tau_r [N m]), a ``specs.BoundedArray`` whose bounds are the
scenario's actuator limits (``scenario.actuators.generalized_limits()``) where they are finite, else
+-``max_surge_force`` / +-``max_yaw_moment`` (1000 N, 1000 N m: the paper's ship has no thrust
limits); values outside are clipped, non-finite ones raise ValueError. With ``quantize=True`` the clipped action goes through the hysteresis quantizer of Eq. 3
(docs/model.md §2; the scenario's delta and u_min per channel), then through the vessel's actuator
model (:mod:`usv_mj.physics.actuators`: the ``[actuators]`` table, the vessel's own where it has one, e.g.
the Otter's twin propellers with their coupled limits and shaft-speed lag; the paper's are
unlimited, the command itself), exactly as in :func:`usv_mj.loop.simulate.simulate`. The actuators'
force is held over the control period: ``n_sub_steps`` = ``plant.substeps`` RK4 steps of the
plant's time step. The action bounds are each channel's own range; a twin hull cannot reach both
ends at once (full surge leaves no yaw moment), and its allocation decides as in a run
(``priority``). On a ruddered vessel (its channels n_P and the rudder angle, KVLCC2) the actuators
allocate the action to the propeller's n_P and the rudder angle at the state (usv_mj.physics.mmg.mmg_allocate),
as a force controller's command in a run; its bounds are that allocation's reach at the vessel's
approach speed (:func:`action_bounds`).

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
``scenario.limits``: :func:`usv_mj.loop.simulate.state_limit_exceeded`, the loop's own check), ``lost``
(distance to the reference >= ``max_distance``); in harbor also ``contact`` with an obstacle
(MuJoCo contact or clearance <= 0) and ``goal`` (|p - p_goal| < goal_radius). The time limit ends
the episode with discount 1 and kind ``time_limit``.

Speed: a step's arithmetic runs compiled (:mod:`usv_mj.envs.native`): one evaluation per state
gives the reference rows, the observation vector (the dict's entries are views of it), the
reward's and the termination's numbers (harbor: with the clearance monitor's update and the
rangefinders), and :meth:`usv_mj.envs.USVEnvironment.step` does the action, the plant's step and
that evaluation in one native call (the task gives the parts, :meth:`TrackTask.fused_kernels`, and
:meth:`usv_mj.envs.physics.USVPhysics.step_native` steps: a task never steps the physics). The results are those
of the definitions above bit for bit (tests/test_envs.py).
"""

from __future__ import annotations

import collections
import math
import warnings
from typing import NamedTuple

import numpy as np

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # dm_control's GLFW probe (see usv_mj.scene.compose)
    from dm_control.suite import base
from dm_env import specs

from usv_mj.builder import make_actuators, make_quantizers
from usv_mj.controllers.performance_funnel import funnels_of
from usv_mj.loop.simulate import make_reference, which_limit
from usv_mj.loop.step import C_F_U, C_Q_U, C_S_U, C_TAU_U, ControlStep
from usv_mj.record.run_record import N_CORE

from usv_mj.envs import native
from usv_mj.envs.physics import USVPhysics

_PHYSICS_STEP = USVPhysics.step
FUSED_HORIZON = 60.0  # s: the fused step asks the plant for its kernel this far ahead (the sea's grids)

DEFAULT_PREVIEW = (0.5, 1.0, 2.0, 4.0)


#: the track reward's full-reward band (the ``tolerance`` bounds' upper ends; the Rewards section above):
#: |p - p_d| [m] and |wrap(psi - psi_d)| [rad]; a learned policy's benchmark criterion (usv_mj.jobs.bench.policy)
TRACK_REWARD_POSITION_M = 0.25
TRACK_REWARD_HEADING_RAD = 0.1

DEFAULT_FORCE = 1000.0  # N and N m: the action bound of a channel whose actuator is unlimited


def action_bounds(scenario, max_surge_force: float = DEFAULT_FORCE, max_yaw_moment: float = DEFAULT_FORCE):
    """(low, high) of the action [N, N m]: the actuators' generalized limits where finite, else
    -+``max_surge_force`` / -+``max_yaw_moment`` (one number each side, so the task and the plant's
    ctrlrange come from the same figures). A ruddered vessel (KVLCC2), whose action is allocated to
    its propeller and rudder, has the reach of that allocation at its approach speed
    (:func:`usv_mj.builder.allocated_force_limits`; the plant's ctrlrange is then n_P's and the
    rudder's)."""
    from usv_mj.builder import allocated_force_limits

    u_lo, u_hi, r_lo, r_hi = allocated_force_limits(scenario) or scenario.actuators.generalized_limits()
    low = np.array([u_lo if math.isfinite(u_lo) else -float(max_surge_force),
                    r_lo if math.isfinite(r_lo) else -float(max_yaw_moment)])
    high = np.array([u_hi if math.isfinite(u_hi) else float(max_surge_force),
                     r_hi if math.isfinite(r_hi) else float(max_yaw_moment)])
    return low, high


#: dm_control's Gaussian sigmoid scale for value_at_margin = 0.1, computed as it computes it (numpy)
_GAUSS_SCALE = float(np.sqrt(-2 * np.log(0.1)))


def _numpy_exp_is_libm() -> bool:
    """numpy's float64 ``exp`` is libm's (CPython's ``math.exp``) here: numpy has its own SIMD
    routine for it only on AVX-512 CPUs (its loops_exponent_log dispatch); unknown -> False."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # pragma: no cover - numpy < 2
        return False
    return not any(on for name, on in features.items() if name.startswith("AVX512") or name == "X86_V4")


#: the Gaussian sigmoid's exp: math.exp where it is numpy's bit for bit (about 1 us less per call)
_EXP = math.exp if _numpy_exp_is_libm() else (lambda v: float(np.exp(v)))


def _tol_gaussian(x: float, lower: float, upper: float, margin: float) -> float:
    """``rewards.tolerance(x, (lower, upper), margin, "gaussian", value_at_margin=0.1)`` of a float,
    with the libm functions dm_control's numpy scalars call: numpy's float64 ``** 2`` is libm's
    pow (not x * x), its exp libm's exp (see :data:`_EXP`)."""
    if lower <= x <= upper:
        return 1.0
    d = (lower - x if x < lower else x - upper) / margin
    try:
        return _EXP(-0.5 * math.pow(d * _GAUSS_SCALE, 2.0))
    except OverflowError:  # numpy's power gives inf there, and exp(-inf) = 0
        return 0.0


def _tol_linear(x: float, lower: float, upper: float, margin: float) -> float:
    """``rewards.tolerance(x, (lower, upper), margin, "linear", value_at_margin=0.0)`` of a float."""
    if lower <= x <= upper:
        return 1.0
    d = (lower - x if x < lower else x - upper) / margin
    return 1 - d if abs(d) < 1 else 0.0


def track_start_pose(reference, random, start_offset):
    """A track episode's initial (eta0, nu0): the reference's pose at t = 0 plus offsets drawn
    uniformly within +-``start_offset`` from ``random`` (a RandomState), at rest (the task's
    :meth:`TrackTask.start_pose`, and each episode of a vector environment, usv_mj.envs.vector)."""
    ref = reference.evaluate(0.0)
    d = random.uniform(-1.0, 1.0, size=3) * start_offset
    return np.array([ref[0] + d[0], ref[1] + d[1], ref[2] + d[2]]), np.zeros(3)


class _Step(NamedTuple):
    """One evaluation of the track task at a state (:meth:`TrackTask._evaluate`): what the native
    step returns, as it returns it."""

    x: np.ndarray           # the state (x, y, psi, u, v, r)
    failed: bool            # the plant's step failed (the fused step only)
    refs: np.ndarray        # reference rows: at t, then at t + each preview time
    obs: np.ndarray         # the observation vector (observation_shapes order)
    ex: float               # position error x - x_d, y - y_d [m] of the state read finite (non-finite -> 0)
    ey: float
    e_psi: float            # wrap(psi - psi_d) [rad]
    diverged: bool          # the raw state left scenario.limits or is not finite
    gx: float               # harbor: x - x_goal, y - y_goal [m] of the state read finite (track: 0)
    gy: float


class _HarbourStep(NamedTuple):
    """:class:`_Step` and the harbor's clearance update made with it."""

    x: np.ndarray
    failed: bool
    refs: np.ndarray
    obs: np.ndarray
    ex: float
    ey: float
    e_psi: float
    diverged: bool
    gx: float
    gy: float
    contact: bool           # a contact or a clearance <= 0
    nearest: int            # np.argmin of the clearances (-1: no obstacle)
    c_min: float            # their minimum [m]


class _FusedKernels(NamedTuple):
    """What a fused step runs (:meth:`TrackTask.fused_kernels`), and what it was made for."""

    plant: object           # the plant whose kernel it steps
    reference: object       # the reference it evaluates
    t_end: float            # [s] the last step time it holds for (FUSED_HORIZON, the reference's table)
    t0: float               # [s] the plant's time at step 0 when it was made
    plant_kernel: object    # the plant's kernel (plant.kernel(t_end)): args, sync, fail
    step: object            # the native step function (native.step_track / step_harbor), or its entry point
    key_fn: object          # None, or the reference's key function: the kernels are made again when it changes
    key: object             # the key they were made at
    entered: bool           # ``step`` is already the entry point (native.entry_point)


class TrackTask(base.Task):
    """Follow the scenario's reference (docs/model.md §4 for the paper preset) from a randomised start.

    The start pose is the reference's pose at t = 0 plus uniform offsets of at most
    ``start_offset`` = (dx [m], dy [m], dpsi [rad]), at rest. See the module docstring for the
    action, observations, reward and termination.

    Parameters: ``scenario`` (:class:`usv_mj.scenario.spec.Scenario`), ``quantize`` (bool),
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
        self._ref_rows = None       # the last evaluation's reference rows (at _ref_t first)
        self.reference = reference if reference is not None else make_reference(scenario)
        self.funnel_xy, self.funnel_psi = funnels_of(scenario)
        # the control step of every loop (usv_mj.loop.step): clip to the action bounds, quantize (Eq. 3),
        # the vessel's actuator model (the Otter's twin propellers and their shaft-speed lag; the
        # paper's: unlimited, the command itself), into a record row's control columns
        self.actuators = make_actuators(scenario)
        self.control = ControlStep(make_quantizers(scenario), self.actuators, self._bounds_t)
        self._row = np.zeros(N_CORE)
        self.last_action = self._row[C_TAU_U:C_TAU_U + 2]      # clipped action [N, N m]
        self.last_command = self._row[C_Q_U:C_Q_U + 2]         # after the quantizer: the command the actuators get
        self.last_thrust = self._row[C_F_U:C_F_U + 2]          # after the actuators: the force the plant got [N, N m]
        self.last_saturated = self._row[C_S_U:C_S_U + 2]       # 1 where the actuators cut that channel's command
        self.termination_reason: str | None = None
        self.termination_kind: str | None = None
        self.episode_scenario = scenario  # what the plant was built from (harbor: with the layout's obstacles)
        # per-step evaluation (usv_mj.envs.native): one call for the observation vector, the
        # reference rows and the reward's and termination's numbers, kept for the step's state
        self._params = np.zeros(native.N_PARAMS)
        self._n_obs = native.N_HEAD + 2 * preview.size + native.N_TAIL
        self._evaluator = None
        self._ev = None             # the last evaluation, for the state ...
        self._ev_key = None         # ... (state array, time, physics, reference)
        self._ev_handed = False     # its observation vector was handed out (the next one gets a copy)
        self._fused = None          # the fused step's kernels (fused_kernels)
        self._views = None          # observation_views, once made
        TrackTask._fill_params(self, self._params)
        self._fusable = self._fusable_class()

    # --- episode -------------------------------------------------------------------------------

    def start_pose(self):
        """The randomised initial (eta0, nu0) of an episode (uses ``self.random``)."""
        return track_start_pose(self.reference, self.random, self.start_offset)

    def initialize_episode(self, physics):
        self.control.reset()
        self._ref_t = None
        self._ev = None
        self._fill_params(self._params)
        self._row[:] = 0.0
        self.termination_reason = None
        self.termination_kind = None
        eta0, nu0 = self.start_pose()
        physics.set_initial_state(eta0, nu0)

    def action_spec(self, physics):
        return specs.BoundedArray((2,), np.float64, self.action_low.copy(), self.action_high.copy(), name="thrust")

    def before_step(self, action, physics):
        self._act(action, physics)

    def _act(self, action, physics):
        """Check the action, then the control step (usv_mj.loop.step: clip, quantize (Eq. 3), the
        vessel's actuators, into last_action, last_command, last_thrust, last_saturated) and the
        force into ``ctrl`` (what the physics' step holds); returns it (f_u [N], f_r [N m])."""
        a0, a1 = self._checked(action)
        self._ev = None  # the state is about to change
        f_u, f_r = self._control(a0, a1, physics.state)
        ctrl = physics.plant.data.ctrl
        ctrl[0], ctrl[1] = f_u, f_r
        return f_u, f_r

    def _control(self, a0, a1, x):
        self.control.quantize = self.quantize
        return self.control(a0, a1, x, self._row)

    def _checked(self, action) -> tuple[float, float]:
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2,):
            raise ValueError(f"{type(self).__name__}: action must be (tau_u [N], tau_r [N m]), shape (2,), "
                             f"got shape {a.shape}")
        a0, a1 = a.tolist()
        if not (math.isfinite(a0) and math.isfinite(a1)):
            raise ValueError(f"{type(self).__name__}: action must be finite, got {a.tolist()}")
        return a0, a1

    def after_step(self, physics):
        self._check(physics, None)

    def _check(self, physics, ev) -> None:
        """after_step's termination checks, with the step's evaluation ``ev`` (None: made when needed)."""
        if self.termination_reason is not None:
            return
        if physics.failure is not None:
            self._terminate("diverged", physics.failure)
            return
        if ev is None:
            ev = self._evaluate(physics)
        if ev.diverged:  # usv_mj.loop.simulate.state_limit_exceeded, or not finite
            x, ref = physics.state, ev.refs[0]
            ex, ey = x[0] - ref[0], x[1] - ref[1]
            lim = self.scenario.limits
            self._terminate("diverged", f"state left its limits at t = {physics.time():.3f} s: "
                                        f"{which_limit(x, ex, ey, lim)}")
            return
        dist = math.hypot(ev.ex, ev.ey)  # the state is finite here: ex, ey are those of the raw state
        if dist >= self.max_distance:
            self._terminate("lost", f"distance to the reference {dist:.3g} m reached max_distance = "
                                    f"{self.max_distance:g} m at t = {physics.time():.3f} s")

    # --- one step in fewer layers (USVEnvironment.step) -------------------------------------------

    def fused_kernels(self, physics, n_sub_steps: int) -> _FusedKernels | None:
        """The native functions of a fused step (:meth:`usv_mj.envs.USVEnvironment.step`: the
        action, the plant's step and the evaluation in one native call, as dm_control's
        ``Environment.step`` calls ``before_step``, ``physics.step``, ``after_step``, ``get_reward``
        and the observation), or None when it does not apply (a subclass overriding one of those
        methods, another physics, a step that is not one control period, a physics that failed, a
        plant or reference without a kernel). Made again when the plant, the reference or its
        key change, or the step's time passes ``t_end``."""
        if not self._fusable or physics.failure is not None or type(physics).step is not _PHYSICS_STEP:
            return None
        plant = physics.plant
        t = plant.time_at(plant.step_count + 1)
        f = self._fused
        if (f is None or f.plant is not plant or f.reference is not self.reference or t > f.t_end
                or f.t0 != plant.time_at(0) or (f.key_fn is not None and f.key_fn() != f.key)):
            f = self._fused = self._fused_setup(plant, t)
            if f is None:
                return None
        if n_sub_steps != plant.substeps:
            return None
        return f

    def fused_action(self, action, physics) -> tuple[float, float]:
        """before_step's part of a fused step: the action checked (tau_u [N], tau_r [N m]), the
        last evaluation dropped and what happens before the physics step (:meth:`_before_physics`)."""
        a0, a1 = self._checked(action)
        self._ev = None
        self._before_physics(physics)
        return a0, a1

    def fused_native(self, k: int, t: float, f: _FusedKernels, a0: float, a1: float, physics):
        """The native call of a fused step from step k to time t [s] (what
        :meth:`usv_mj.envs.physics.USVPhysics.step_native` runs before it keeps the plant's step):
        the action, the plant's kernel and the evaluation at the new state. After the first call,
        the step function's entry point is called (native.entry_point)."""
        ev = self._native_step(f.step, a0, a1, physics, k, t, f.plant_kernel.args)
        if not f.entered:  # compiled (or loaded) now: call its entry point from here on
            self._fused = f._replace(step=native.entry_point(f.step) or f.step, entered=True)
        return ev

    def fused_result(self, ev, t: float, physics) -> tuple[float, np.ndarray]:
        """after_step, get_reward and the observation vector of a fused step made to the state of
        ``ev`` at t [s]: (reward, observation vector)."""
        self._keep(ev, ev.x, t, physics)
        self._check(physics, ev)
        reward = self._reward(ev)
        self._ev_handed = True
        return reward, ev.obs

    def _fused_setup(self, plant, t):
        """The fused step's kernels for steps up to t [s] and beyond (FUSED_HORIZON), or None."""
        make = getattr(plant, "kernel", None)
        evaluator = self._evaluator_now()
        if make is None or not evaluator.native:
            return None
        t_end = t + FUSED_HORIZON
        if evaluator.t_max is not None:  # the reference's table: the preview must stay in it
            t_end = min(t_end, evaluator.t_max - evaluator.horizon)
            if t > t_end:
                return None
        pk = make(t_end)
        if pk is None:
            return None
        mod = evaluator.module(pk)
        if mod is None:
            return None
        return _FusedKernels(plant, self.reference, t_end, plant.time_at(0), pk, self._step_function(mod),
                             evaluator.key_fn, evaluator.key, False)

    @staticmethod
    def _step_function(mod):
        return mod.step_track

    def _native_step(self, step, a0, a1, physics, k, t, plant_args) -> _Step:
        ev = self._evaluator
        self.control.quantize = self.quantize
        return _Step._make(step(a0, a1, self._row, self.control.args(), k, physics.state, t, plant_args, ev.preview,
                                self._params, self._n_obs, ev.ref_args))

    def _before_physics(self, physics) -> None:
        """What happens between the action and the physics step (harbor: obstacles move)."""

    @classmethod
    def _fusable_class(cls) -> bool:
        base = HarbourTask if issubclass(cls, HarbourTask) else TrackTask
        return all(getattr(cls, name) is getattr(base, name)
                   for name in ("before_step", "after_step", "get_reward", "get_observation", "_check", "_reward",
                                "_before_physics"))

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
        "goal" or "time_limit"; ``reason``: one sentence), the last action, the quantized command
        and the force the plant got (after the vessel's actuators)."""
        return {"kind": self.termination_kind, "reason": self.termination_reason,
                "action": self.last_action.copy(), "command": self.last_command.copy(),
                "thrust": self.last_thrust.copy()}

    # --- observations and reward ---------------------------------------------------------------

    def reference_at(self, t: float) -> np.ndarray:
        """The reference vector (REF_FIELDS) at t [s] (cached for the current step; do not modify)."""
        if t != self._ref_t or self._ref is None:
            if t == self._ref_t and self._ref_rows is not None:  # the step's evaluation has it
                self._ref = self._ref_rows[0]
            else:
                self._ref = self.reference.evaluate(t).copy()
                self._ref_t, self._ref_rows = t, None
        return self._ref

    # --- the per-step evaluation ---------------------------------------------------------------
    #
    # One native call per step (usv_mj.envs.native) gives the reference rows, the observation
    # vector and the numbers of the reward and the termination; after_step, get_reward and
    # get_observation share it. It is kept for the state it was computed at: the same state array
    # (the plant hands a new one at every step, and a reset a fresh one at every read), the same
    # time, physics and reference, and it is dropped at before_step and at every episode.

    def _fill_params(self, p) -> None:
        """The task's constant numbers for :func:`native.track_observe` (filled at every episode)."""
        fx, fp, lim = self.funnel_xy, self.funnel_psi, self.scenario.limits
        p[native.P_RHO_XY0], p[native.P_RHO_XYINF], p[native.P_RATE_XY] = fx.rho_0, fx.rho_inf, fx.rate
        p[native.P_RHO_P0], p[native.P_RHO_PINF], p[native.P_RATE_P] = fp.rho_0, fp.rho_inf, fp.rate
        p[native.P_MAX_SPEED], p[native.P_MAX_YAW_RATE] = lim.max_speed, lim.max_yaw_rate
        p[native.P_MAX_DISTANCE] = lim.max_distance

    def _evaluator_now(self) -> native.StepEvaluator:
        evaluator = self._evaluator
        if evaluator is None or evaluator.reference is not self.reference:
            evaluator = self._evaluator = native.StepEvaluator(self.reference, self.preview_times)
        return evaluator

    def _evaluate(self, physics):
        """The task at the physics' state and time (:class:`native.StepEvaluator`), or the
        evaluation already made there."""
        x = physics.state
        t = physics.time()
        key = self._ev_key
        if self._ev is not None and key[0] is x and key[1] == t and key[2] is physics and key[3] is self.reference:
            return self._ev
        ev = self._run_evaluator(self._evaluator_now(), x, t, physics)
        self._keep(ev, x, t, physics)
        return ev

    def _keep(self, ev, x, t, physics) -> None:
        """Keep ``ev`` as the evaluation at (x, t) (reference_at(t) reads its reference rows)."""
        self._ev, self._ev_key, self._ev_handed = ev, (x, t, physics, self.reference), False
        self._ref, self._ref_t, self._ref_rows = None, t, ev.refs

    def _run_evaluator(self, evaluator, x, t, physics):
        return _Step._make((x, False) + evaluator.track(x, t, self._params, self._n_obs, False))

    def _observation_vector(self, physics) -> np.ndarray:
        """The step's observation vector (a fresh array for every observation handed out)."""
        ev = self._evaluate(physics)
        if self._ev_handed:
            return ev.obs.copy()
        self._ev_handed = True
        return ev.obs

    def get_observation(self, physics):
        return self.observation_dict(self._observation_vector(physics))

    def observation_dict(self, v):
        """The observation dict of the vector ``v`` (views of it, in observation_shapes order)."""
        obs = collections.OrderedDict()
        for name, part, shape, flat in self.observation_views():
            obs[name] = v[part] if flat else v[part].reshape(shape)
        return obs

    def observation_views(self) -> tuple:
        """(name, slice of the vector, shape, the shape is 1-d) per observation in
        :meth:`observation_shapes` order: where each one lies in the vector (made once, the
        shapes are fixed at construction)."""
        views = self._views
        if views is None:
            out, i = [], 0
            for name, shape in self.observation_shapes():
                n = int(np.prod(shape))
                out.append((name, slice(i, i + n), tuple(shape), len(shape) == 1))
                i += n
            views = self._views = tuple(out)
        return views

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
        return self._tracking_reward(self._evaluate(physics))

    @staticmethod
    def _tracking_reward(ev) -> float:
        return (2.0 * _tol_gaussian(math.hypot(ev.ex, ev.ey), 0.0, TRACK_REWARD_POSITION_M, 2.0)      # r_pos
                + _tol_gaussian(abs(ev.e_psi), 0.0, TRACK_REWARD_HEADING_RAD, 0.5)) / 3.0               # r_psi

    def get_reward(self, physics):
        return self._reward(self._evaluate(physics))

    def _reward(self, ev) -> float:
        return self._tracking_reward(ev)


class HarbourTask(TrackTask):
    """Reach a goal through a randomised harbour (piers with a gap, then a buoy field) without contact.

    Each episode draws a layout (:func:`usv_mj.envs.layout.harbour_layout`), plans the guidance
    reference around it (:func:`usv_mj.references.planner.plan_reference`; the reference observed is
    that plan) and builds the harbour physics with rangefinders (the environment rebuilds the model
    when the layout changes: see :class:`usv_mj.envs.USVEnvironment`). Observations add ``goal`` and
    ``rangefinder``; the reward adds the goal distance and the clearance; contact ends the episode
    (module docstring). Only the minimum clearance, its obstacle and the contact test are read, so
    the per-step update skips obstacles provably farther than the nearest
    (``MuJoCoClearance.kernel_args(min_only=True)``): after a step, ``monitor.clearance`` holds
    their bounds there (``monitor.exact`` False).
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
        self._sense_of = (None, None)  # (monitor, harbor_sense's arguments)
        self._moving = True            # the layout has moving obstacles (set with the layout)
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
        plant = getattr(monitor, "plant", None)
        mocap = getattr(plant, "obstacle_mocap", None)
        self._moving = mocap is None or bool(np.any(np.asarray(mocap) >= 0))  # (unknown: move them)

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
        self._before_physics(physics)

    def _before_physics(self, physics) -> None:
        if self._moving:
            physics.plant.move_obstacles(physics.time())

    def _clearance(self, physics) -> float:
        c = self.monitor.update(physics.time(), physics.plant)
        # any contact or c <= 0, np.argmin(c) and np.min(c) in one native call
        self._contact, self._nearest, c_min = native.clearance_summary(c, self.monitor.in_contact)
        return c_min

    def after_step(self, physics):
        # observation, clearance and rangefinders at the new state, in one native call
        self._check(physics, self._evaluate(physics))

    def _check(self, physics, ev) -> None:
        if ev is None:
            ev = self._evaluate(physics)
        super()._check(physics, ev)
        self._contact, self._nearest, self.min_clearance = ev.contact, ev.nearest, ev.c_min  # made with ev
        if self.termination_reason is not None:
            return
        if self._contact:
            name = self.layout.obstacles[self._nearest].name if self._nearest >= 0 else "?"
            self._terminate("contact", f"hull touched obstacle {name!r} at t = {physics.time():.3f} s "
                                       f"(clearance {self.min_clearance:.3f} m)")
        elif math.hypot(ev.gx, ev.gy) < self.goal_radius:  # the state is finite here
            self._terminate("goal", f"reached the goal at t = {physics.time():.3f} s")

    def _fill_params(self, p) -> None:
        super()._fill_params(p)
        if self.layout is None:
            return
        g = self.layout.goal
        p[native.P_GOAL_X], p[native.P_GOAL_Y], p[native.P_PSI_GOAL] = g[0], g[1], self.layout.psi_goal

    def _sense_args(self, physics) -> tuple:
        """:func:`native.harbor_sense`'s arguments but the observation vector, for this episode's
        plant and monitor (made once per episode)."""
        of, args = self._sense_of
        if of is not self.monitor or self.monitor.plant is not physics.plant:
            plant = physics.plant
            args = (self._n_obs + 3, self.max_range, plant.model._address, plant.data._address,
                    native.sensor_pos_address(), plant.data.sensordata, plant.rangefinder_adr,
                    self.monitor.kernel_args(min_only=True))
            self._sense_of = (self.monitor, args)
        return args

    def _run_evaluator(self, evaluator, x, t, physics):
        out = evaluator.harbor(x, t, self._params, self._n_obs + 3 + self.n_rays, self._sense_args(physics))
        return self._with_contacts(_HarbourStep._make((x, False) + out))

    @staticmethod
    def _step_function(mod):
        return mod.step_harbor

    def _native_step(self, step, a0, a1, physics, k, t, plant_args):
        ev = self._evaluator
        self.control.quantize = self.quantize
        return self._with_contacts(_HarbourStep._make(step(
            a0, a1, self._row, self.control.args(), k, physics.state, t, plant_args, ev.preview, self._params,
            self._n_obs + 3 + self.n_rays, ev.ref_args, self._sense_args(physics))))

    def _with_contacts(self, ev):
        """``ev`` with the monitor's contacts added (``d.ncon`` > 0: the summary again)."""
        monitor = self.monitor
        if not monitor.add_contacts():
            return ev
        contact, nearest, c_min = native.clearance_summary(monitor.clearance, monitor.in_contact)
        return ev._replace(contact=contact, nearest=nearest, c_min=c_min)

    def observation_shapes(self):
        return super().observation_shapes() + [("goal", (3,)), ("rangefinder", (self.n_rays,))]

    def observation_bounds(self) -> dict:
        return {**super().observation_bounds(), "rangefinder": (0.0, self.max_range)}

    def _reward(self, ev) -> float:
        r_goal = _tol_linear(math.hypot(ev.gx, ev.gy), 0.0, self.goal_radius, self._start_distance)
        if self.margin_m > 0:
            r_clear = _tol_linear(self.min_clearance, self.margin_m, math.inf, self.margin_m)
        else:
            r_clear = 1.0 if self.min_clearance > 0 else 0.0
        return r_clear * 0.5 * (r_goal + self._tracking_reward(ev))
