"""The actuators of the hull: what it can realize of the quantized command (scenario ``[actuators]``).

The loop applies the channel in this order every control period: controller -> hysteresis
quantizer (the transmitted command Q(tau)) -> actuators (the force the thrusters realize, what
the plant receives, on either plant alike). ``kind``:

- ``"unlimited"`` (the paper's presets: the paper has no thrust limits): the force is Q(tau),
  bit for bit;
- ``"box"``: surge force in [-max_reverse_n, max_surge_n] [N], yaw moment in [-max_yaw_nm,
  max_yaw_nm] [N m], each channel clipped on its own;
- ``"twin"``: two fixed thrusters ``separation_m`` apart, each with its own forward and reverse
  limit; the generalized forces are allocated to them and saturated per thruster.

Twin allocation (project convention: body x forward, y to port, z up, positive r turns to port).
The port thruster T_p sits at y = +s/2, the starboard one T_s at y = -s/2, both pushing along +x;
the moment about z of a force F_x at (x, y) is -y F_x, so::

    tau_u = T_p + T_s
    tau_r = (s/2) (T_s - T_p)          a stronger starboard thruster turns the hull to port
    T_s = tau_u/2 + tau_r/s,  T_p = tau_u/2 - tau_r/s      (the inverse)

with each T in [-thruster_reverse_n, thruster_forward_n] = [-R, F]. The reachable set is the
parallelogram |tau_r| <= s (F + R)/2, 2(-R + |tau_r|/s) <= tau_u <= 2(F - |tau_r|/s). When a command
lies outside it, ``priority`` says which channel wins:

- ``"yaw"`` (default): tau_r is first clipped to +-s(F + R)/2, then tau_u to the surge range left at
  that tau_r. Heading is what keeps the hull on the path and pointed against a current (the surge
  loop of a path follower only sets the progress along it); a hull that loses yaw authority to
  surge cannot turn back, one that loses surge slows down but keeps its course.
- ``"surge"``: tau_u is first clipped to [-2R, 2F], then tau_r to the yaw range left at that tau_u.

Dynamics, discretized exactly at the control period h (so they are the same on both plants):

- ``time_constant_s`` = T > 0: first-order thrust, T f_dot = c - f, with c the saturated command
  held over the period. With a = exp(-h/T), the thrust at the sample times is
  f_{k+1} = c_k + (f_k - c_k) a, and the force the plant receives over [t_k, t_k + h) is its
  average over the period, c_k + (f_k - c_k) (T/h)(1 - a): the held force then carries exactly
  the impulse of the continuous lag (the plants hold their input over the period). f_0 = 0.
- ``shaft_time_constant_s`` = T_n > 0 (twin only): first-order propeller shaft speed, as Fossen's
  Otter (``vehicles/otter.py``: n_dot = (n_c - n)/T_n, thrust k n|n| with k = ``thrust_coeff_forward``
  for n > 0 and ``thrust_coeff_reverse`` for n < 0, per propeller). Each thruster's saturated thrust
  T_c becomes its shaft command n_c = sign(T_c) sqrt(|T_c| / k); over the period the shaft speed is
  n(t) = n_c + (n_k - n_c) e^(-t/T_n) exactly, and the thrust the plant receives is the period's
  average of k(n) n|n| (closed form, split where n changes sign): the held thrust carries exactly
  the impulse of the continuous model, as the thrust lag's does. A thrust lag T f_dot = c - f is
  not the same response: from rest a step in n gives thrust (1 - e^(-t/T_n))^2 of its final value
  (40 % at t = T_n, where a first-order thrust lag is at 63 %). n_0 = 0. Not with ``time_constant_s``.
- ``surge_rate_n_s`` / ``yaw_rate_nm_s``: the applied force changes by at most rate * h per period
  (after the lag); on the twin hull the result is allocated again so that it stays reachable.

``sat_u`` / ``sat_r`` are 1 in the periods where a limit (magnitude or rate) cut that channel's
command, 0 otherwise (the lag alone does not set them).

Allocation (a ruddered vessel, KVLCC2, driven by a force controller; usv_mj.builder.make_actuators):
the channels of ``spec`` are then the propeller's n_P [1/s] and the rudder angle delta [rad], and
the command (tau_u [N], tau_r [N m]) is first allocated to them at the plant state
(:func:`usv_mj.physics.mmg.mmg_allocate`, n_P within the surge channel's limits and delta within the yaw
channel's); the lag and rate limits then act on (n_P, delta) as above. sat_u / sat_r are also set
when the allocation cannot meet the command (docs/vessels.md, Force controllers on KVLCC2).

On the MuJoCo plant the same limits are also the motors' ``ctrlrange`` (``ctrllimited``) of
``models/usv.xml``, set at load from :meth:`ActuatorSpec.generalized_limits` (twin: the range of
each channel on its own; the coupling of the two channels through the thrusters is in this
module, since the model has two generalized motors). The model applies the limits before MuJoCo
sees the command, so MuJoCo's clamp never changes it; it shows a MuJoCo user the same vessel.
MuJoCo's activation dynamics (``dyntype="filter"``) are not used for the lag: MuJoCo integrates
them with its own step, not exactly at the control period, and the two plants would differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numba.extending import register_jitable

from usv_mj.physics.channels import FORCES, Channels
from usv_mj.physics.mmg import mmg_allocate

ACTUATOR_KINDS = ("unlimited", "box", "twin")
PRIORITIES = ("yaw", "surge")


@dataclass(frozen=True)
class ActuatorSpec:
    """Actuator limits and dynamics (module docstring).

    Attributes
    ----------
    kind: "unlimited" | "box" | "twin".
    max_surge_n: box: largest forward surge force [N].
    max_reverse_n: box: largest astern surge force, a magnitude [N].
    max_yaw_nm: box: largest yaw moment magnitude [N m].
    separation_m: twin: lateral distance between the two thrusters [m].
    thruster_forward_n: twin: largest forward thrust of one thruster [N].
    thruster_reverse_n: twin: largest reverse thrust of one thruster, a magnitude [N].
    time_constant_s: first-order thrust lag [s] (0: none).
    surge_rate_n_s: largest rate of change of the surge force [N/s] (inf: none).
    yaw_rate_nm_s: largest rate of change of the yaw moment [N m/s] (inf: none).
    priority: twin: which channel wins when both cannot be met, "yaw" (default) or "surge".
    shaft_time_constant_s: twin: the propellers' shaft-speed time constant T_n [s] (0: none).
    thrust_coeff_forward: twin, with the shaft lag: k of thrust = k n|n| for n > 0 [N s^2/rad^2].
    thrust_coeff_reverse: twin, with the shaft lag: k for n < 0 [N s^2/rad^2].

    In a scenario file a limit that is not given is none (or write ``inf``).
    """

    kind: str = "unlimited"
    max_surge_n: float = math.inf
    max_reverse_n: float = math.inf
    max_yaw_nm: float = math.inf
    separation_m: float = 0.79
    thruster_forward_n: float = math.inf
    thruster_reverse_n: float = math.inf
    time_constant_s: float = 0.0
    surge_rate_n_s: float = math.inf
    yaw_rate_nm_s: float = math.inf
    priority: str = "yaw"
    shaft_time_constant_s: float = 0.0
    thrust_coeff_forward: float = 0.0
    thrust_coeff_reverse: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ACTUATOR_KINDS:
            raise ValueError(f"kind must be one of {', '.join(ACTUATOR_KINDS)}, got {self.kind!r}")
        for name in ("max_surge_n", "max_reverse_n", "max_yaw_nm", "separation_m", "thruster_forward_n",
                     "thruster_reverse_n", "surge_rate_n_s", "yaw_rate_nm_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0 and not math.isnan(value)):
                raise ValueError(f"{name} must be > 0 (inf: no limit), got {value!r}")
        if not (isinstance(self.time_constant_s, (int, float)) and math.isfinite(self.time_constant_s)
                and self.time_constant_s >= 0):
            raise ValueError(f"time_constant_s must be >= 0 s, got {self.time_constant_s!r}")
        for name in ("shaft_time_constant_s", "thrust_coeff_forward", "thrust_coeff_reverse"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if self.shaft_time_constant_s > 0:
            if self.kind != "twin":
                raise ValueError(f"shaft_time_constant_s = {self.shaft_time_constant_s!r}: a shaft-speed lag needs "
                                 f"kind = 'twin' (per propeller), got kind = {self.kind!r}")
            if not (self.thrust_coeff_forward > 0 and self.thrust_coeff_reverse > 0):
                raise ValueError("shaft_time_constant_s > 0 needs thrust_coeff_forward > 0 and thrust_coeff_reverse > 0 "
                                 "(thrust = k n|n| per propeller)")
            if self.time_constant_s > 0:
                raise ValueError("give time_constant_s (a thrust lag) or shaft_time_constant_s (a shaft-speed lag), "
                                 "not both")
        if self.priority not in PRIORITIES:
            raise ValueError(f"priority must be one of {', '.join(PRIORITIES)}, got {self.priority!r}")
        if self.kind == "twin" and not (math.isfinite(self.thruster_forward_n)
                                        and math.isfinite(self.thruster_reverse_n)
                                        and math.isfinite(self.separation_m)):
            raise ValueError("kind = 'twin' needs finite thruster_forward_n, thruster_reverse_n and separation_m")

    @property
    def unlimited(self) -> bool:
        """True when nothing limits or delays the force (the paper's reading)."""
        return (self.kind == "unlimited" and self.time_constant_s == 0.0 and self.shaft_time_constant_s == 0.0
                and math.isinf(self.surge_rate_n_s) and math.isinf(self.yaw_rate_nm_s))

    def describe(self, channels: Channels = FORCES) -> str:
        """One line for reports: the kind and its limits, in the units of the ``channels`` they act
        on (:mod:`usv_mj.physics.channels`: forces, or a ruddered vessel's n_P [1/s] and rudder
        angle [rad])."""
        if self.unlimited:
            return "unlimited (the paper's reading: the plant receives the quantized command Q(tau))"
        lo_u, hi_u, lo_r, hi_r = self.generalized_limits()
        s, y = channels.surge, channels.yaw
        parts = [f"{self.kind}: {s.name} [{lo_u:g}, {hi_u:g}] {s.unit}, {y.name} [{lo_r:g}, {hi_r:g}] {y.unit}"]
        if self.kind == "twin":
            parts.append(f"two thrusters {self.separation_m:g} m apart, each [-{self.thruster_reverse_n:g}, "
                         f"{self.thruster_forward_n:g}] N, {self.priority} priority")
        if self.time_constant_s > 0:
            parts.append(f"thrust lag T = {self.time_constant_s:g} s")
        if self.shaft_time_constant_s > 0:
            parts.append(f"shaft-speed lag T_n = {self.shaft_time_constant_s:g} s, thrust k n|n| (k "
                         f"{self.thrust_coeff_forward:g} / {self.thrust_coeff_reverse:g})")
        if math.isfinite(self.surge_rate_n_s) or math.isfinite(self.yaw_rate_nm_s):
            parts.append(f"rate limits {self.surge_rate_n_s:g} {s.rate}, {self.yaw_rate_nm_s:g} {y.rate}")
        return "; ".join(parts)

    def generalized_limits(self) -> tuple[float, float, float, float]:
        """(tau_u_min, tau_u_max, tau_r_min, tau_r_max) [N, N, N m, N m] the actuators can realize
        each on its own (twin: both thrusters together for surge, opposed for yaw)."""
        if self.kind == "box":
            return -self.max_reverse_n, self.max_surge_n, -self.max_yaw_nm, self.max_yaw_nm
        if self.kind == "twin":
            f, r, half = self.thruster_forward_n, self.thruster_reverse_n, self.separation_m / 2
            return -2 * r, 2 * f, -half * (f + r), half * (f + r)
        return -math.inf, math.inf, -math.inf, math.inf


# --- the model ------------------------------------------------------------------------------------
# Plain float arithmetic on a parameter vector and a state vector: the kernel compiles with numba
# unchanged (register_jitable: plain Python here, inlined into a numba.njit loop when it is compiled).

K_UNLIMITED, K_BOX, K_TWIN = 0, 1, 2
# parameter vector
(A_KIND, A_LO_U, A_HI_U, A_LO_R, A_HI_R, A_SEP, A_FWD, A_REV, A_YAW_FIRST, A_LAG_A, A_LAG_B, A_DU, A_DR,
 A_SHAFT_T, A_SHAFT_H, A_K_FWD, A_K_REV) = range(17)
N_ACT_PARAMS = 17
# state vector: lag thrust at the sample time (u, r), last applied force (u, r), shaft speeds
# (port, starboard) at the sample time [rad/s]
S_LAG_U, S_LAG_R, S_F_U, S_F_R, S_N_P, S_N_S = range(6)
N_ACT_STATE = 6


@register_jitable
def _clip(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


@register_jitable
def saturate(p, q_u, q_r):
    """(c_u, c_r): the reachable generalized force nearest the command by the kind's rule."""
    kind = p[A_KIND]
    if kind == K_BOX:
        return _clip(q_u, p[A_LO_U], p[A_HI_U]), _clip(q_r, p[A_LO_R], p[A_HI_R])
    if kind == K_TWIN:
        s, fwd, rev = p[A_SEP], p[A_FWD], p[A_REV]
        if p[A_YAW_FIRST] > 0.5:
            c_r = _clip(q_r, p[A_LO_R], p[A_HI_R])
            a = abs(c_r) / s
            c_u = _clip(q_u, 2.0 * (a - rev), 2.0 * (fwd - a))
        else:
            c_u = _clip(q_u, p[A_LO_U], p[A_HI_U])
            m = s * min(fwd - 0.5 * c_u, 0.5 * c_u + rev)
            c_r = _clip(q_r, -m, m)
        return c_u, c_r
    return q_u, q_r


@register_jitable
def _n_squared_integral(c, d, t1, t2, tn):
    """Integral over [t1, t2] of n(t)^2 with n(t) = c + d exp(-t / tn)."""
    e1, e2 = math.exp(-t1 / tn), math.exp(-t2 / tn)
    return c * c * (t2 - t1) + 2.0 * c * d * tn * (e1 - e2) + 0.5 * d * d * tn * (e1 * e1 - e2 * e2)


@register_jitable
def shaft_step(thrust, n0, tn, h, k_fwd, k_rev):
    """One period of one propeller's shaft-speed lag (module docstring): (the period's average
    thrust [N], the shaft speed at its end [rad/s]) for the thrust command ``thrust`` [N] from the
    shaft speed ``n0`` [rad/s]; tn the time constant, h the period [s]."""
    if thrust >= 0.0:
        c = math.sqrt(thrust / k_fwd)
    else:
        c = -math.sqrt(-thrust / k_rev)
    d = n0 - c
    n1 = c + d * math.exp(-h / tn)
    if c == 0.0:
        t0 = h                            # n decays towards 0 keeping the sign of n0
    elif n0 != 0.0 and (n0 > 0.0) != (c > 0.0):
        t0 = tn * math.log(-d / c)        # n(t0) = 0: the sign changes (inside the period if t0 < h)
        if t0 >= h:
            t0 = h
    else:
        t0 = 0.0                          # n keeps the sign of c throughout
    k0 = k_fwd if n0 > 0.0 else k_rev     # the sign of n on [0, t0)
    k1 = k_fwd if c > 0.0 else k_rev      # and on [t0, h]
    s0 = 1.0 if n0 > 0.0 else -1.0
    s1 = 1.0 if c > 0.0 else -1.0
    impulse = 0.0
    if t0 > 0.0:
        impulse += s0 * k0 * _n_squared_integral(c, d, 0.0, t0, tn)
    if t0 < h:
        impulse += s1 * k1 * _n_squared_integral(c, d, t0, h, tn)
    return impulse / h, n1


@register_jitable
def actuator_step(p, state, q_u, q_r):
    """One control period: (f_u, f_r, sat_u, sat_r) from the quantized command (q_u, q_r); updates
    ``state`` (module docstring for the equations)."""
    c_u, c_r = saturate(p, q_u, q_r)
    sat_u = 1.0 if c_u != q_u else 0.0
    sat_r = 1.0 if c_r != q_r else 0.0
    a, b = p[A_LAG_A], p[A_LAG_B]
    if a > 0.0:  # exact first-order lag: held force = the period's average
        lu, lr = state[S_LAG_U], state[S_LAG_R]
        f_u = c_u + (lu - c_u) * b
        f_r = c_r + (lr - c_r) * b
        state[S_LAG_U] = c_u + (lu - c_u) * a
        state[S_LAG_R] = c_r + (lr - c_r) * a
    elif p[A_SHAFT_T] > 0.0:  # twin: each propeller's shaft speed lags, thrust k n|n|
        half = 0.5 * p[A_SEP]
        t_s, n_s = shaft_step(0.5 * c_u + c_r / p[A_SEP], state[S_N_S], p[A_SHAFT_T], p[A_SHAFT_H],
                              p[A_K_FWD], p[A_K_REV])
        t_p, n_p = shaft_step(0.5 * c_u - c_r / p[A_SEP], state[S_N_P], p[A_SHAFT_T], p[A_SHAFT_H],
                              p[A_K_FWD], p[A_K_REV])
        state[S_N_S], state[S_N_P] = n_s, n_p
        f_u = t_p + t_s
        f_r = half * (t_s - t_p)
    else:
        f_u, f_r = c_u, c_r
    du, dr = p[A_DU], p[A_DR]
    if du < math.inf or dr < math.inf:
        pu, pr = state[S_F_U], state[S_F_R]
        g_u = _clip(f_u, pu - du, pu + du)
        g_r = _clip(f_r, pr - dr, pr + dr)
        if g_u != f_u:
            sat_u = 1.0
        if g_r != f_r:
            sat_r = 1.0
        f_u, f_r = saturate(p, g_u, g_r) if p[A_KIND] == K_TWIN else (g_u, g_r)
    state[S_F_U] = f_u
    state[S_F_R] = f_r
    return f_u, f_r, sat_u, sat_r


@register_jitable
def unlimited_step(q_u, q_r):
    """The ``unlimited`` kind: the force is the command, nothing saturated (f_u, f_r, sat_u, sat_r)."""
    return q_u, q_r, 0.0, 0.0


@njit(cache=True)
def actuator_kernel(q_u, q_r, x, unlimited, p, state, mmg):
    """:meth:`Actuators.apply` (which calls it, or runs :func:`unlimited_step` as Python) and its
    kernel for the compiled loop (usv_mj.core.kernels) and the environments' step (usv_mj.envs.native).

    ``mmg``: empty, or the MMG block of a ruddered vessel driven by a force controller (module
    docstring, Allocation): the command (surge force, yaw moment) then becomes (n_P, delta) at the
    plant state ``x`` (:func:`usv_mj.physics.mmg.mmg_allocate`, n_P within the surge channel's limits, delta
    within the yaw channel's) and the vessel's own limits and rates act on those; ``x`` is not read
    otherwise."""
    if mmg.shape[0] > 0:
        n_p, delta, a_u, a_r = mmg_allocate(mmg, 0, x[3], x[4], x[5], q_u, q_r, p[A_LO_U], p[A_HI_U], p[A_HI_R])
        f_u, f_r, s_u, s_r = actuator_step(p, state, n_p, delta)
        return f_u, f_r, max(a_u, s_u), max(a_r, s_r)
    if unlimited:
        return unlimited_step(q_u, q_r)
    return actuator_step(p, state, q_u, q_r)


_NO_STATE = np.zeros(6)
NO_ALLOCATION = np.zeros(0)


def pack(spec: ActuatorSpec, control_period: float) -> np.ndarray:
    """The parameter vector of :func:`actuator_step` for ``spec`` at the control period h [s]."""
    h = float(control_period)
    if not (math.isfinite(h) and h > 0):
        raise ValueError(f"control_period must be > 0 s, got {control_period!r}")
    p = np.zeros(N_ACT_PARAMS)
    p[A_KIND] = {"unlimited": K_UNLIMITED, "box": K_BOX, "twin": K_TWIN}[spec.kind]
    p[A_LO_U], p[A_HI_U], p[A_LO_R], p[A_HI_R] = spec.generalized_limits()
    p[A_SEP], p[A_FWD], p[A_REV] = spec.separation_m, spec.thruster_forward_n, spec.thruster_reverse_n
    p[A_YAW_FIRST] = 1.0 if spec.priority == "yaw" else 0.0
    if spec.time_constant_s > 0:
        x = h / spec.time_constant_s
        p[A_LAG_A] = math.exp(-x)
        p[A_LAG_B] = -math.expm1(-x) / x  # (T/h)(1 - exp(-h/T)), accurate for small h/T
    p[A_DU] = spec.surge_rate_n_s * h
    p[A_DR] = spec.yaw_rate_nm_s * h
    if spec.shaft_time_constant_s > 0:
        p[A_SHAFT_T], p[A_SHAFT_H] = spec.shaft_time_constant_s, h
        p[A_K_FWD], p[A_K_REV] = spec.thrust_coeff_forward, spec.thrust_coeff_reverse
    return p


class Actuators:
    """The actuator model of ``spec`` at ``control_period`` h [s]: :meth:`reset`, then
    :meth:`apply` once per control period (module docstring).

    ``allocation``: None, or the packed MMG block (usv_mj.physics.mmg) of a ruddered vessel that a force
    controller drives: the command is then allocated to (n_P, delta) first (module docstring,
    Allocation), and ``spec``'s channels are n_P [1/s] and delta [rad]."""

    def __init__(self, spec: ActuatorSpec = ActuatorSpec(), control_period: float = 1e-3, allocation=None):
        self.spec = spec
        self.control_period = float(control_period)
        self.params = pack(spec, control_period)
        self.state = np.zeros(N_ACT_STATE)
        # the kernel's argument: the MMG block, or empty (no allocation)
        self.mmg = NO_ALLOCATION if allocation is None else np.array(allocation, dtype=float)
        self.unlimited = spec.unlimited and allocation is None
        self.limits = spec.generalized_limits()

    @property
    def allocation(self):
        """The MMG block the command is allocated through, or None."""
        return self.mmg if self.mmg.shape[0] else None

    @classmethod
    def from_scenario(cls, scenario, allocation=None) -> "Actuators":
        return cls(scenario.actuators, scenario.control_period, allocation)

    def reset(self) -> None:
        """Zero thrust, no history."""
        self.state[:] = 0.0

    def kernel(self):
        """(the kernel, its parameters and state) for the compiled loop."""
        from usv_mj.core.kernels import Kernel

        return Kernel(actuator_kernel, (bool(self.unlimited), self.params, self.state, self.mmg))

    def apply(self, q_u: float, q_r: float, x=None) -> tuple[float, float, float, float]:
        """(f_u, f_r, sat_u, sat_r) realized over the coming period from the command (f: [N], [N m],
        or (n_P [1/s], delta [rad]) with an allocation, which reads the plant state ``x``)."""
        if self.mmg.shape[0] and x is None:
            raise ValueError("Actuators.apply: an allocated command needs the plant state x")
        if self.unlimited:  # the kernel's own branch, as plain Python (a native call costs more than it)
            return unlimited_step(q_u, q_r)
        x = _NO_STATE if x is None else np.asarray(x, dtype=float)
        return actuator_kernel(float(q_u), float(q_r), x, False, self.params, self.state, self.mmg)
