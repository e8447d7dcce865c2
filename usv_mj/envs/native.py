"""Native kernels of the dm_control tasks' per-step work (:mod:`usv_mj.envs.tasks`).

One ``env.step`` spent nearly as long in Python (the observation dict built entry by entry, five
reference evaluations, ``dm_control.utils.rewards.tolerance`` two or four times, the state checks,
numpy reductions over the clearances) as in the physics. Here that arithmetic runs compiled, a
few calls per step:

- the action: the control step of every loop (:mod:`usv_mj.loop.step`: clip, the hysteresis
  quantizer (Eq. 3) of both channels, the vessel's actuator model, the row of tau, Q(tau), k, f
  and sat that ``last_action``, ``last_command``, ``last_thrust`` and ``last_saturated`` view);
- :func:`track_observe`: from the state and the reference rows (at t and at the preview times),
  the whole observation vector in :meth:`TrackTask.observation_shapes` order (harbor: with the
  goal), and the numbers the reward and the termination read;
- :func:`harbor_sense`: the harbor's clearance monitor update (MuJoCo's distance queries) and
  rangefinders (``mj_sensorPos``) into the same vector;
- :class:`StepEvaluator`: the reference rows, :func:`track_observe` (and :func:`harbor_sense`)
  in one call when the reference hands a kernel (:mod:`usv_mj.core.kernels`): functions made by the
  one code generator (:mod:`usv_mj.loop.generate`) per reference and plant kernel, with the control
  step and the plant's step composed by its ``advance``; else ``reference.evaluate`` from Python;
- :func:`clearance_summary`: contact, nearest obstacle and minimum of a clearance update.

The expressions are those of the Python code they replace, term by term and in the same order
(IEEE arithmetic without fast-math, libm's cos/sin/exp as CPython's math), so observations and
rewards are the same bit for bit (tests/test_envs.py pins them against an independent
computation). What stays in Python because CPython or numpy define the result: ``math.hypot``
(CPython's own algorithm, not libm's) and the Gaussian sigmoid's power and ``np.exp`` (numpy's,
which may be a SIMD routine rather than libm's).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from usv_mj.controllers.performance_funnel import funnel_bound
from usv_mj.loop.generate import generate
from usv_mj.physics.limits import within_limits
from usv_mj.obstacles.clearance import mujoco_clearance_kernel
from usv_mj.support.native_mujoco import call_model_data
from usv_mj.physics.ship import wrap_angle

#: entries of the observation vector before the preview (position_error 2, heading_error 1,
#: heading 2, velocity 3, velocity_error 3) and after it (funnel 2, time 1)
N_HEAD, N_TAIL = 11, 3
#: layout of ``params`` (float64): funnels, the state limits, then (harbor) the goal
P_RHO_XY0, P_RHO_XYINF, P_RATE_XY, P_RHO_P0, P_RHO_PINF, P_RATE_P = range(6)
P_MAX_SPEED, P_MAX_YAW_RATE, P_MAX_DISTANCE = 6, 7, 8
P_GOAL_X, P_GOAL_Y, P_PSI_GOAL = 9, 10, 11
N_PARAMS = 12


@njit(cache=True)
def track_observe(x, t, refs, params, n_out, goal):
    """The observation vector (length ``n_out``; the rangefinder tail, if any, is left to the
    caller) at state ``x`` and time ``t`` [s] from the reference rows ``refs`` (row 0 at t, row
    k + 1 at t + preview k), and (e_x, e_y, e_psi, diverged, g_x, g_y) for the reward and
    termination: e_x, e_y = the position error of the state with non-finite entries read as 0 (as
    the observation), e_psi = wrap(psi - psi_d), diverged = the raw state left the limits
    (:func:`usv_mj.physics.limits.within_limits`) or is not finite; ``goal``: also fill the
    harbor's goal entries (after the time), and g_x, g_y = that state minus the goal (else 0)."""
    x0, x1, x2, x3, x4, x5 = x[0], x[1], x[2], x[3], x[4], x[5]
    finite = (math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2) and math.isfinite(x3)
              and math.isfinite(x4) and math.isfinite(x5))
    r = refs[0]
    ex, ey = x0 - r[0], x1 - r[1]
    diverged = not within_limits(x, ex, ey, params[P_MAX_SPEED], params[P_MAX_YAW_RATE],
                                 params[P_MAX_DISTANCE]) or not finite
    if not finite:  # np.nan_to_num(x, nan=0, posinf=0, neginf=0)
        x0 = x0 if math.isfinite(x0) else 0.0
        x1 = x1 if math.isfinite(x1) else 0.0
        x2 = x2 if math.isfinite(x2) else 0.0
        x3 = x3 if math.isfinite(x3) else 0.0
        x4 = x4 if math.isfinite(x4) else 0.0
        x5 = x5 if math.isfinite(x5) else 0.0
    c, s = math.cos(x2), math.sin(x2)
    out = np.empty(n_out)
    dx, dy = x0 - r[0], x1 - r[1]
    out[0] = c * dx + s * dy
    out[1] = -s * dx + c * dy
    e_psi = wrap_angle(x2 - r[2])
    out[2] = e_psi
    out[3] = c
    out[4] = s
    out[5] = x3
    out[6] = x4
    out[7] = x5
    out[8] = c * r[3] + s * r[4] - x3
    out[9] = -s * r[3] + c * r[4] - x4
    out[10] = r[5] - x5
    j = N_HEAD
    for k in range(1, refs.shape[0]):
        px, py = refs[k, 0] - x0, refs[k, 1] - x1
        out[j] = c * px + s * py
        out[j + 1] = -s * px + c * py
        j += 2
    out[j] = funnel_bound(params[P_RHO_XY0], params[P_RHO_XYINF], params[P_RATE_XY], t)
    out[j + 1] = funnel_bound(params[P_RHO_P0], params[P_RHO_PINF], params[P_RATE_P], t)
    out[j + 2] = t
    g_x = g_y = 0.0
    if goal:
        gx, gy = params[P_GOAL_X] - x0, params[P_GOAL_Y] - x1
        out[j + 3] = c * gx + s * gy
        out[j + 4] = -s * gx + c * gy
        out[j + 5] = wrap_angle(params[P_PSI_GOAL] - x2)
        g_x, g_y = x0 - params[P_GOAL_X], x1 - params[P_GOAL_Y]
    return out, dx, dy, e_psi, diverged, g_x, g_y


@njit(cache=True)
def clearance_summary(c, in_contact):
    """(contact, nearest, minimum) of a clearance update: any in_contact or any c <= 0; np.argmin(c)
    (-1 when empty); np.min(c) (inf when empty); a NaN is numpy's minimum (its first index)."""
    n = c.shape[0]
    contact = False
    for i in range(n):
        if in_contact[i] or c[i] <= 0.0:
            contact = True
            break
    if n == 0:
        return contact, -1, math.inf
    best, nearest = c[0], 0
    for i in range(n):
        v = c[i]
        if math.isnan(v):
            return contact, i, v
        if v < best:
            best, nearest = v, i
    return contact, nearest, best


@njit(cache=True)
def harbor_sense(obs, start, max_range, m_addr, d_addr, sensor_pos, sensordata, sensor_adr, monitor):
    """The harbor's sensing at the current state in one call: the clearance monitor's distances
    (:func:`usv_mj.obstacles.clearance.mujoco_clearance_kernel` with ``monitor`` =
    ``MuJoCoClearance.kernel_args(min_only=True)``: its branch and bound, as only the summary
    is read; it runs ``mj_kinematics``), then ``mj_sensorPos`` (at
    address ``sensor_pos``) and the rangefinder readings into ``obs[start:]``, ``max_range``
    where nothing was hit (-1) or beyond it; returns :func:`clearance_summary` (before the contacts, which the
    caller adds when ``d.ncon`` > 0)."""
    mujoco_clearance_kernel(*monitor)
    call_model_data(sensor_pos, m_addr, d_addr)
    for i in range(sensor_adr.shape[0]):
        v = sensordata[sensor_adr[i]]
        obs[start + i] = max_range if (v < 0.0 or v > max_range) else v
    return clearance_summary(monitor[12], monitor[17])


# --- the track reward in native code (the vector environments: usv_mj.envs.vector) ------------------
#
# The single environment computes its reward in Python (tasks.TrackTask._tracking_reward) with CPython's
# math.hypot and libm's exp and pow; these are the same operations compiled, so a batch's rewards equal
# the single environment's bit for bit (tests/test_vector_env.py).

_T27 = 134217729.0   # 2**27 + 1: Veltkamp's split of a double into two 26-bit halves


@njit(cache=True)
def hypot_py(x, y):
    """CPython's ``math.hypot(x, y)`` (Modules/mathmodule.c ``vector_norm``, 3.10-3.11: scaled,
    with the sums of squares carried in double-double, then one correction of the square root),
    which is not libm's hypot: the same IEEE operations in the same order, so the same double."""
    ax, ay = abs(x), abs(y)
    if math.isinf(ax) or math.isinf(ay):
        return math.inf
    if math.isnan(ax) or math.isnan(ay):
        return math.nan
    mx = max(ax, ay)
    if mx == 0.0:
        return mx
    _, e = math.frexp(mx)
    csum, frac1, frac2, frac3 = 1.0, 0.0, 0.0, 0.0
    if e >= -1023:
        scale = math.ldexp(1.0, -e)
        for v in (ax, ay):
            v *= scale
            t = v * _T27
            hi = t - (t - v)
            lo = v - hi
            v = hi * hi
            old = csum
            csum += v
            frac1 += (old - csum) + v
            v = 2.0 * hi * lo
            old = csum
            csum += v
            frac2 += (old - csum) + v
            frac3 += lo * lo
        h = math.sqrt(csum - 1.0 + (frac1 + frac2 + frac3))
        t = h * _T27
        hi = t - (t - h)
        lo = h - hi
        v = -hi * hi
        old = csum
        csum += v
        frac1 += (old - csum) + v
        v = -2.0 * hi * lo
        old = csum
        csum += v
        frac2 += (old - csum) + v
        v = -lo * lo
        old = csum
        csum += v
        frac3 += (old - csum) + v
        v = csum - 1.0 + (frac1 + frac2 + frac3)
        return (h + v / (2.0 * h)) / scale
    for v in (ax, ay):   # subnormal maximum: divide by it instead of scaling
        v /= mx
        v = v * v
        old = csum
        csum += v
        frac1 += (old - csum) + v
    return mx * math.sqrt(csum - 1.0 + frac1)


#: layout of the reward parameters ``rp`` of :func:`track_reward` (float64)
R_TWO, R_GAUSS_SCALE, R_POSITION, R_HEADING, R_MAX_DISTANCE = range(5)
N_REWARD = 5


@njit(cache=True)
def tol_gaussian(x, lower, upper, margin, rp):
    """``usv_mj.envs.tasks._tol_gaussian`` compiled: dm_control's Gaussian tolerance with libm's pow
    and exp (the exponent 2 is read from ``rp[R_TWO]`` at run time, so that the compiler calls pow
    instead of squaring, as CPython's math.pow does)."""
    if lower <= x <= upper:
        return 1.0
    d = (lower - x if x < lower else x - upper) / margin
    return math.exp(-0.5 * math.pow(d * rp[R_GAUSS_SCALE], rp[R_TWO]))


@njit(cache=True)
def track_reward(ex, ey, e_psi, rp):
    """The track tasks' reward (usv_mj.envs.tasks.TrackTask._tracking_reward) of the errors."""
    return (2.0 * tol_gaussian(hypot_py(ex, ey), 0.0, rp[R_POSITION], 2.0, rp)
            + tol_gaussian(abs(e_psi), 0.0, rp[R_HEADING], 0.5, rp)) / 3.0


@njit(cache=True)
def observe_scaled(out, scale, lo, hi, dst):
    """The Gymnasium view's observation of the vector ``out`` into ``dst`` (float32):
    ``np.clip(out / scale, lo, hi).astype(np.float32)`` (usv_mj.envs.gymnasium_env.USVGymEnv._observe),
    element by element (a NaN stays NaN, as numpy's clip leaves it)."""
    for j in range(out.shape[0]):
        v = out[j] / scale[j]
        if v < lo[j]:
            v = lo[j]
        elif v > hi[j]:
            v = hi[j]
        dst[j] = np.float32(v)


def entry_point(dispatcher):
    """The compiled entry point of an njit function with exactly one compiled signature, or None.

    Calling it skips the dispatcher's type resolution (about 1.5 us with the fused step's ~50
    arguments); the caller must keep passing arguments of that signature's types (the fused step
    does: the same arrays, tuples and scalar kinds at every step of an episode)."""
    overloads = getattr(dispatcher, "overloads", None)
    if not overloads or len(overloads) != 1:
        return None
    return getattr(next(iter(overloads.values())), "entry_point", None)


def sensor_pos_address() -> int:
    """Address of ``mj_sensorPos`` in this process's libmujoco (for :func:`harbor_sense`)."""
    from usv_mj.support.native_mujoco import mujoco_function_address

    return mujoco_function_address("mj_sensorPos")


def _rows_python(reference, t, preview):
    """The reference rows through ``reference.evaluate`` (references without a kernel)."""
    refs = np.empty((preview.size + 1, 7))
    refs[0] = reference.evaluate(t)[:7]   # the 7 entries the observation reads (not the accelerations)
    for k, tau in enumerate(preview):
        refs[k + 1] = reference.evaluate(t + tau)[:7]
    return refs


_TEMPLATE = '''

@njit(cache=True)
def evaluate(x, t, preview, params, n_out, goal, ref_a):
    refs = np.empty((preview.shape[0] + 1, 7))
    r = ref_fn(t, {ref_args})
    for i in range(7):
        refs[0, i] = r[i]
    for k in range(preview.shape[0]):
        r = ref_fn(t + preview[k], {ref_args})
        for i in range(7):
            refs[k + 1, i] = r[i]
    out, ex, ey, e_psi, diverged, gx, gy = track_observe(x, t, refs, params, n_out, goal)
    return refs, out, ex, ey, e_psi, diverged, gx, gy


@njit(cache=True)
def evaluate_harbor(x, t, preview, params, n_out, ref_a, sense_a):
    refs, out, ex, ey, e_psi, diverged, gx, gy = evaluate(x, t, preview, params, n_out, True, ref_a)
    contact, nearest, c_min = harbor_sense(out, *sense_a)
    return refs, out, ex, ey, e_psi, diverged, gx, gy, contact, nearest, c_min


@njit(cache=True)
def step_track(a0, a1, row, step_a, k, x, t, plant_a, preview, params, n_out, ref_a):
    x, failed = advance(k, x, a0, a1, row, step_a, plant_a)
    return (x, failed) + evaluate(x, t, preview, params, n_out, False, ref_a)


@njit(cache=True)
def step_harbor(a0, a1, row, step_a, k, x, t, plant_a, preview, params, n_out, ref_a, sense_a):
    x, failed = advance(k, x, a0, a1, row, step_a, plant_a)
    return (x, failed) + evaluate_harbor(x, t, preview, params, n_out, ref_a, sense_a)
'''


def _generated(ref_fn, n_ref: int, plant_fn, n_plant: int):
    """The generated module (``evaluate``, ``evaluate_harbor``: the reference rows and the
    observation; ``step_track``, ``step_harbor``: the control step, the plant's step and that, through
    the generator's ``advance``) for these kernels (:func:`usv_mj.loop.generate.generate`)."""
    return generate("usv_mj_envstep", _TEMPLATE, {"ref": (ref_fn, n_ref), "plant": (plant_fn, n_plant)},
                    imports="from usv_mj.envs.native import harbor_sense, track_observe")


class StepEvaluator:
    """The per-step evaluation of the tasks for one reference, with the reference rows at t and
    t + ``preview``: native when the reference has a kernel and t + max(preview) is within a
    tabulated reference's ``t_max``; else through ``reference.evaluate`` (which raises as before).

    - ``track(x, t, params, n_out, goal)`` -> (refs, obs, e_x, e_y, e_psi, diverged, g_x, g_y), as
      :func:`track_observe`;
    - ``harbor(x, t, params, n_out, sense_a)`` -> the same and (contact, nearest, c_min) of
      :func:`harbor_sense` with its arguments ``sense_a`` (all but ``obs``);
    - ``module(plant_kernel)``: the generated ``step_track`` / ``step_harbor`` for the plant's
      kernel (the action, the plant's step and the evaluation in one call).
    """

    def __init__(self, reference, preview: np.ndarray):
        from usv_mj.core.kernels import kernel_of

        self.reference = reference
        self.preview = np.ascontiguousarray(preview, dtype=np.float64)
        self.horizon = float(np.max(self.preview))
        self.t_max = getattr(reference, "t_max", None)
        self._make = kernel_of(reference, "evaluate")
        # a reference that can change (a guided one: detours, re-timing) says when its kernel's
        # snapshot is stale: key_fn() != key
        self.key_fn = getattr(reference, "kernel_key", None) if self._make is not None else None
        self._native = None
        self._bind()

    def _bind(self) -> None:
        self._native = None
        self._modules = {}
        self.key = self.key_fn() if self.key_fn is not None else None
        k = self._make() if self._make is not None else None
        if k is not None:
            self._ref_kernel = k
            self.ref_args = tuple(k.args)
            self._native = self._module(*_default_plant_kernel())

    def _module(self, plant_fn, n_plant):
        mod = self._modules.get((plant_fn, n_plant))
        if mod is None:
            mod = self._modules[(plant_fn, n_plant)] = _generated(self._ref_kernel.fn, len(self._ref_kernel.args),
                                                                  plant_fn, n_plant)
        return mod

    @property
    def native(self) -> bool:
        """The reference has a kernel (its snapshot refreshed when stale)."""
        if self.key_fn is not None and self.key_fn() != self.key:
            self._bind()
        return self._native is not None

    def _native_now(self, t) -> bool:
        return self.native and (self.t_max is None or t + self.horizon <= self.t_max)

    def module(self, plant_kernel):
        """The generated module with ``step_track`` / ``step_harbor`` for this plant kernel (the
        action, the plant's step and the evaluation in one call), or None without a reference kernel."""
        return self._module(plant_kernel.fn, len(plant_kernel.args)) if self.native else None

    def track(self, x, t, params, n_out, goal):
        if self._native_now(t):
            return self._native.evaluate(x, t, self.preview, params, n_out, goal, self.ref_args)
        refs = _rows_python(self.reference, t, self.preview)
        return (refs, *track_observe(x, t, refs, params, n_out, goal))

    def harbor(self, x, t, params, n_out, sense_a):
        if self._native_now(t):
            return self._native.evaluate_harbor(x, t, self.preview, params, n_out, self.ref_args, sense_a)
        refs = _rows_python(self.reference, t, self.preview)
        out = track_observe(x, t, refs, params, n_out, True)
        return (refs, *out, *harbor_sense(out[0], *sense_a))


def _default_plant_kernel():
    """(the MuJoCo plant's kernel, the number of its arguments after (k, x, f_u, f_r))."""
    from usv_mj.plants.mujoco_callback import mujoco_kernel

    return mujoco_kernel, mujoco_kernel.py_func.__code__.co_argcount - 4
