"""Line-of-sight guidance with a PID heading autopilot and a PI surge loop (Fossen 2021, ch. 12 and 15).

A conventional path-tracking controller of the field, written as a plug-in would be: one file, one
registration (``@CONTROLLERS.register("los", gains=LOSGains)``), a typed gains dataclass, the
interface of :mod:`usv_mj.controllers.base` and the criterion it is judged by. Underactuated: it
commands a surge force and a yaw moment, no sway force.

Reference: T. I. Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2nd ed.
(Wiley 2021): LOS guidance in ch. 12 (lookahead-based steering, integral LOS), the heading
autopilot in ch. 15 (PID with a reference model, pole placement) and PI speed control. Conventions are the
README's (x east, y north, psi counter-clockwise from east, positive r turns to port).

The law at time t, for the state (x, y, psi, u, v, r) and the reference vector (x_d, y_d, psi_d,
x_d_dot, y_d_dot, r_d, u_d):

1. Path frame (the path is the one the time-parameterized reference point runs along): path angle
   pi_p = atan2(y_d_dot, x_d_dot) (psi_d when the reference stands still), along-track error
   x_e = (x - x_d) cos pi_p + (y - y_d) sin pi_p (> 0: ahead of the reference point) and
   cross-track error y_e = -(x - x_d) sin pi_p + (y - y_d) cos pi_p (> 0: left of the path).
2. LOS steering (Fossen ch. 12, lookahead-based, K_p = 1/Delta; the integral LOS of Borhaug,
   Pavlov and Pettersen 2008): chi_d = pi_p - atan((y_e + sigma y_int) / Delta), with
   y_int_dot = U Delta y_e / ((y_e + sigma y_int)^2 + Delta^2), U = sqrt(u^2 + v^2) (sigma = 0, the
   default: plain LOS). The heading command is the course command less the measured crab angle,
   psi_c = chi_d - beta, beta = atan2(v, u) (Fossen ch. 12: the course over ground is psi + beta;
   ``crab_compensation = false`` commands psi_c = chi_d, and the integral LOS then takes up the crab).
3. Heading reference model (Fossen ch. 15, the third-order model: a low-pass cascaded with a mass-damper-spring), with
   the path's turn rate r_d as velocity feed-forward so that it follows a turning path without lag:
   a_m_dot = omega^3 wrap(psi_c - psi_m) - (2 zeta + 1) omega a_m - (2 zeta + 1) omega^2 (r_m - r_d),
   r_m_dot = a_m, psi_m_dot = r_m; it starts at the vessel's heading and yaw rate.
4. PID heading autopilot (Fossen ch. 15, with the nominal model's feed-forward):
   tau_r = m33 a_m + d33 r_m - kp_psi psi_e - kd_psi (r - r_m) - ki_psi integral(psi_e),
   psi_e = wrap(psi - psi_m); m33 and d33 (its constant coefficient) from the nominal ship.
5. Surge speed (trajectory-tracking LOS: keep pace with the reference point): the path speed
   U_p = sqrt(x_d_dot^2 + y_d_dot^2) corrected by the along-track error,
   u_c = clip(U_p - u_at x_e / sqrt(x_e^2 + l_at^2), u_c_min, u_c_max), and a PI loop with the
   nominal drag as feed-forward: tau_u = d11(u_c) u_c + kp_u (u_c - u) + ki_u integral(u_c - u).

The states (y_int, the reference model, the integrators) advance by explicit Euler over the control
period after the outputs are formed; the integrators are clamped (anti-windup). The law is one
numba function, :func:`los_law`: ``__call__`` calls it, and it is the compiled loop's kernel.

Default gains, tuned on the paper's hull (docs/model.md §1, about 2 m long) and the ``paper``
preset (on another hull the gains a scenario does not set are these placed again on its nominal
model at its bandwidth: :meth:`LOSGains.for_vessel`, docs/gains.md): Delta = 3 m (1.5 hull lengths, Fossen's lower bound; the guidance loop's time constant
Delta/U is 5 s at 0.6 m/s); the heading loop by Fossen's pole placement on the yaw inertia
m33 = 15.6 kg m^2 with omega_n = 8 rad/s, zeta = 1 (kp = m33 omega_n^2 = 998, taken as 1000 N m/rad;
kd = 2 zeta omega_n m33 - d33 = 244, taken as 250 N m s/rad; ki = omega_n/10 kp = 800 N m/(rad s)): stiff enough
for the hull's unstable sway-yaw mode (+0.60 1/s at 0.6 m/s, docs/model.md §8) and for the
preset's yaw disturbance of up to 20 N m (|psi - psi_m| under 0.009 rad after 20 s); a softer loop
(omega_n = 3 rad/s: 140, 94, 42) lets the disturbance swing y_e by 0.37 m. Reference model 3 rad/s; the surge PI
as the PI baseline's (200 N s/m, 40 N/m); along-track correction up to 0.3 m/s, 0.15 1/s near
x_e = 0. On the ``paper`` preset (both plants) the cross-track error is under 0.08 m after 20 s and
0.022 m after 40 s; on the default ``circle`` 0.027 m after 40 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numba import njit

from usv_mj.record.criteria import PathTolerance
from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import CONTROLLERS
from usv_mj.physics.ship import P_D33, P_M33, ShipParams, damping_coefficients, wrap_angle

from usv_mj.controllers.base import REF_PSI, REF_R, REF_X, REF_XDOT, REF_Y, REF_YDOT

# the internal state vector: integral LOS, reference model, integrators, started flag
S_YINT, S_PSI_M, S_R_M, S_A_M, S_INT_PSI, S_INT_U, S_STARTED = range(7)
N_STATE = 7
CRAB_MIN_SPEED = 0.05  # m/s: below this surge speed the crab angle is not compensated (atan2(v, u) is noise)

DIAGNOSTIC_FIELDS = (
    "cross_track_error",   # y_e [m], > 0 left of the path
    "along_track_error",   # x_e [m], > 0 ahead of the reference point
    "path_angle",          # pi_p [rad]
    "chi_d",               # LOS course command [rad]
    "psi_ref",             # reference model heading psi_m [rad]
    "r_ref",               # reference model yaw rate r_m [rad/s]
    "psi_error",           # wrap(psi - psi_m) [rad]
    "r_error",             # r - r_m [rad/s]
    "u_ref",               # speed set-point u_c [m/s]
    "u_error",             # u - u_c [m/s]
    "integral_los",        # y_int [m]
    "integral_psi",        # integral of psi_e [rad s]
    "integral_u",          # integral of u_c - u [m]
)


@dataclass(frozen=True)
class LOSGains:
    """Gains of the LOS controller (module docstring for the law and how the defaults were chosen)."""

    lookahead: float = 3.0           # m: Delta, K_p = 1/Delta (> 0)
    ilos_sigma: float = 0.0          # -: integral LOS gain, K_i = sigma/Delta (0: plain LOS)
    ilos_limit: float = 10.0         # m: clamp on |y_int|
    ref_omega: float = 3.0           # rad/s: natural frequency of the heading reference model (> 0)
    ref_zeta: float = 1.0            # -: its relative damping (> 0)
    kp_psi: float = 1000.0           # N m/rad: heading proportional gain
    ki_psi: float = 800.0            # N m/(rad s): heading integral gain
    kd_psi: float = 250.0            # N m s/rad: yaw-rate gain
    integral_limit_psi: float = 2.0  # rad s: clamp on |integral of psi_e|
    u_at: float = 0.3                # m/s: largest along-track correction of the speed set-point
    l_at: float = 2.0                # m: along-track length where the correction saturates (> 0)
    kp_u: float = 200.0              # N s/m: surge-speed proportional gain
    ki_u: float = 40.0               # N/m: surge-speed integral gain
    integral_limit_u: float = 5.0    # m: clamp on |integral of u_c - u|
    u_c_min: float = 0.0             # m/s: lower limit of the speed set-point
    u_c_max: float = 1.5             # m/s: upper limit of the speed set-point
    crab_compensation: bool = True   # command the heading chi_d - beta, beta = atan2(v, u) the measured crab angle

    def __post_init__(self) -> None:
        if not isinstance(self.crab_compensation, bool):
            raise ScenarioError(f"controller.crab_compensation must be true or false, got {self.crab_compensation!r}")
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "crab_compensation":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ScenarioError(f"controller.{f.name} must be a finite number, got {v!r}")
            if f.name not in ("u_c_min", "u_c_max") and v < 0:
                raise ScenarioError(f"controller.{f.name} must be >= 0, got {v!r}")
        for name in ("lookahead", "ref_omega", "ref_zeta", "l_at"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"controller.{name} must be > 0, got {getattr(self, name)!r}")
        if not self.u_c_max > self.u_c_min:
            raise ScenarioError(f"controller.u_c_max ({self.u_c_max!r}) must be greater than "
                                f"controller.u_c_min ({self.u_c_min!r})")

    #: the gains :meth:`for_vessel` derives from the vessel (the others keep the defaults above)
    DERIVED = ("lookahead", "ref_omega", "kp_psi", "ki_psi", "kd_psi", "u_at", "l_at", "kp_u", "ki_u")

    @classmethod
    def for_vessel(cls, scaling) -> dict:
        """The default gains on the hull of ``scaling`` (a :class:`usv_mj.physics.design.Scaling`):
        the defaults above (the paper hull's design) placed again on that hull (docs/gains.md): the
        heading PID and the surge PI by pole placement with its nominal m33, m11 and damping at its
        bandwidth, the reference model's frequency a rate, the look-ahead and l_at lengths, u_at a
        speed. The paper hull gets the defaults exactly."""
        d = cls()
        kp_u, ki_u = scaling.surge_pi(d.kp_u, d.ki_u)
        kp, kd, ki = scaling.heading_pid(d.kp_psi, d.kd_psi, d.ki_psi)
        lam = scaling.length
        return {"lookahead": d.lookahead * lam, "ref_omega": scaling.rate(d.ref_omega), "kp_psi": kp, "ki_psi": ki,
                "kd_psi": kd, "u_at": d.u_at * scaling.speed, "l_at": d.l_at * lam, "kp_u": kp_u, "ki_u": ki_u}

    def as_array(self) -> np.ndarray:
        """The gains packed in field order (the kernel reads them by position: G_* below)."""
        return np.array([float(getattr(self, f.name)) for f in fields(self)])


(G_DELTA, G_SIGMA, G_YINT_LIM, G_W, G_Z, G_KP_PSI, G_KI_PSI, G_KD_PSI, G_INT_PSI_LIM, G_U_AT, G_L_AT,
 G_KP_U, G_KI_U, G_INT_U_LIM, G_U_MIN, G_U_MAX, G_CRAB) = range(17)
assert len(fields(LOSGains)) == 17


@njit(cache=True)
def los_steering(y_e, y_int, lookahead, sigma, pi_p):
    """The LOS course command chi_d = pi_p - atan((y_e + sigma y_int)/Delta) [rad] (step 2)."""
    return pi_p - math.atan((y_e + sigma * y_int) / lookahead)


@njit(cache=True)
def path_errors(x, ref):
    """(pi_p, x_e, y_e): the path angle [rad] and the along- and cross-track errors [m] (step 1)."""
    vx, vy = ref[REF_XDOT], ref[REF_YDOT]
    pi_p = math.atan2(vy, vx) if vx * vx + vy * vy > 1e-12 else ref[REF_PSI]
    c, s = math.cos(pi_p), math.sin(pi_p)
    dx, dy = x[0] - ref[REF_X], x[1] - ref[REF_Y]
    return pi_p, c * dx + s * dy, -s * dx + c * dy


@njit(cache=True)
def los_law(t, x, ref, p, g, st, dt, diag):
    """One evaluation of the law (module docstring, steps 1-5); advances ``st`` by ``dt``. The one
    implementation: :meth:`LOSController.__call__` and the compiled loop both run it."""
    psi, u, v, r = x[2], x[3], x[4], x[5]
    if st[S_STARTED] == 0.0:  # the reference model starts at the vessel's heading and yaw rate
        st[S_PSI_M], st[S_R_M], st[S_A_M], st[S_STARTED] = psi, r, 0.0, 1.0
    pi_p, x_e, y_e = path_errors(x, ref)
    delta, sigma = g[G_DELTA], g[G_SIGMA]
    chi_d = los_steering(y_e, st[S_YINT], delta, sigma, pi_p)
    beta = math.atan2(v, u) if (g[G_CRAB] > 0.0 and u > CRAB_MIN_SPEED) else 0.0  # measured crab angle
    # heading autopilot on the reference model's output
    psi_m, r_m, a_m = st[S_PSI_M], st[S_R_M], st[S_A_M]
    psi_e = wrap_angle(psi - psi_m)
    r_e = r - r_m
    tau_r = (p[P_M33] * a_m + p[P_D33] * r_m
             - g[G_KP_PSI] * psi_e - g[G_KD_PSI] * r_e - g[G_KI_PSI] * st[S_INT_PSI])
    # surge: the path speed, corrected by the along-track error, then PI with drag feedforward
    u_p = math.sqrt(ref[REF_XDOT] ** 2 + ref[REF_YDOT] ** 2)
    u_c = u_p - g[G_U_AT] * x_e / math.sqrt(x_e * x_e + g[G_L_AT] ** 2)
    u_c = min(max(u_c, g[G_U_MIN]), g[G_U_MAX])
    d11 = damping_coefficients(p, (u_c, 0.0, 0.0))[0]
    e_u = u_c - u
    tau_u = d11 * u_c + g[G_KP_U] * e_u + g[G_KI_U] * st[S_INT_U]
    # diagnostics (the values the outputs were formed from)
    diag[0], diag[1], diag[2], diag[3] = y_e, x_e, pi_p, chi_d
    diag[4], diag[5], diag[6], diag[7] = psi_m, r_m, psi_e, r_e
    diag[8], diag[9] = u_c, -e_u
    diag[10], diag[11], diag[12] = st[S_YINT], st[S_INT_PSI], st[S_INT_U]
    # states, explicit Euler over the control period
    w, z = g[G_W], g[G_Z]
    big_u = math.sqrt(u * u + v * v)
    ys = y_e + sigma * st[S_YINT]
    lim = g[G_YINT_LIM]
    st[S_YINT] = min(max(st[S_YINT] + dt * big_u * delta * y_e / (ys * ys + delta * delta), -lim), lim)
    st[S_A_M] = a_m + dt * (w ** 3 * wrap_angle(chi_d - beta - psi_m) - (2 * z + 1) * w * a_m
                            - (2 * z + 1) * w * w * (r_m - ref[REF_R]))
    st[S_R_M] = r_m + dt * a_m
    st[S_PSI_M] = wrap_angle(psi_m + dt * r_m)
    lim = g[G_INT_PSI_LIM]
    st[S_INT_PSI] = min(max(st[S_INT_PSI] + dt * psi_e, -lim), lim)
    lim = g[G_INT_U_LIM]
    st[S_INT_U] = min(max(st[S_INT_U] + dt * e_u, -lim), lim)
    return tau_u, tau_r


@njit(cache=True)
def los_kernel(t, x, ref, p, g, st, dt, diag):
    """The compiled loop's kernel of :class:`LOSController` (usv_mj.core.kernels): ``__call__`` natively."""
    tau_u, tau_r = los_law(t, x, ref, p, g, st, dt, diag)
    return tau_u, tau_r, diag


@CONTROLLERS.register("los", gains=LOSGains)
class LOSController:
    """LOS guidance + PID heading autopilot + PI surge (see the module docstring)."""

    name = "los"
    diagnostic_fields = DIAGNOSTIC_FIELDS
    diagnostic_units = {"cross_track_error": "m", "along_track_error": "m", "path_angle": "rad", "chi_d": "rad",
                        "psi_ref": "rad", "r_ref": "rad/s", "psi_error": "rad", "r_error": "rad/s", "u_ref": "m/s",
                        "u_error": "m/s", "integral_los": "m", "integral_psi": "rad s", "integral_u": "m"}
    #: judged on the path: after 20 s the cross-track error stays under 0.25 m, the along-track under 0.5 m
    criterion = PathTolerance(settle_time_s=20.0, cross_track_m=0.25, along_track_m=0.5)

    @classmethod
    def from_scenario(cls, gains: LOSGains, scenario) -> "LOSController":
        """The controller for ``scenario``: its nominal ship (the vessel's times
        ``[vessel] model_mismatch``: ``scenario.nominal_ship``) (feedforward) and control period."""
        return cls(gains, scenario.nominal_ship, scenario.control_period)

    def __init__(self, gains: LOSGains, nominal: ShipParams, control_period: float):
        self.gains = gains
        self.nominal = nominal
        self._p = nominal.as_array()
        self._g = gains.as_array()
        self.dt = float(control_period)
        self._st = np.zeros(N_STATE)
        self._diag = np.zeros(len(DIAGNOSTIC_FIELDS))   # what los_law writes, whatever a subclass declares

    def reset(self) -> None:
        self._st[:] = 0.0
        self._diag[:] = 0.0

    def kernel(self):
        """(los_kernel, its arrays) for the compiled loop."""
        from usv_mj.core.kernels import Kernel

        return Kernel(los_kernel, (self._p, self._g, self._st, self.dt, self._diag), n_diag=len(self._diag))

    def __call__(self, t, state, reference):
        tau_u, tau_r = los_law(float(t), state, reference, self._p, self._g, self._st, self.dt, self._diag)
        return tau_u, tau_r, self._diag
