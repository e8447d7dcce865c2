"""Adaptive prescribed-performance controller with RBF networks (paper Eqs. 14-37, docs/model.md §3).

One evaluation at time t (docs/model.md §3, steps 1-11):

1. Reference and Do & Pan's point x_bar_d = x_d + eps cos psi_d (eps = m23/m22 of the nominal model).
2-4. e1, e2, psi_a (Eq. 15 with chi = atan2(-e2, -e1)), e3, the funnel rho_i and e_i* (Eqs. 8-10, 14).
5. Virtual controls (Eq. 17): A = x_bar_d_dot - l1 e1*, B = y_bar_d_dot - l1 e2*,
   alpha_u = A cos psi + B sin psi, alpha_v = -A sin psi + B cos psi, alpha_r = psi_dot_ref - l2 e3*
   where psi_dot_ref is psi_d_dot as printed, or the analytic psi_a_dot (``alpha_r="analytic"``),
   which Eq. 16 implies.
6. Velocity errors (Eq. 19): u_e = u - alpha_u, v_e = v_bar - alpha_v - b2 s2, r_e = r - alpha_r.
7. RBF regressors S_u, S_v, S_r on Z = [u, v, r, alpha_u, alpha_v, alpha_r, e1*, e2*, e3*].
8. Eq. 34: gamma_1 = (k1 + l3) u_e + phi_u + W_u.S_u + l3 v_e,
           gamma_3 = (k3 + l3) r_e + phi_r + W_r.S_r + l3 v_e.
9. Eq. 37 (the quantization-robust law):
   tau_u = -m11 u_e gamma_1^2 / ((1 - delta_u) sqrt(u_e^2 gamma_1^2 + b1^2)),
   tau_r = -Delta_M r_e gamma_3^2 / (m22 (1 - delta_r) sqrt(r_e^2 gamma_3^2 + b3^2)).
11. States, explicit Euler over the control period: s2_dot = (W_v.S_v + phi_v - l3 u_e + l3 v_e
    - l3 r_e)/b2 (Eq. 29 divided by cosh^2 gamma_2), |s2| <= s2_limit (clamps counted);
    W_i_dot = Gamma_i (i_e S_i - theta_i W_i) (Eq. 37).

The nominal ship model (phi_u, phi_v, phi_r of Eq. 28) is handed in at construction as a
:class:`usv_mj.physics.ship.ShipParams`; it may differ from the plant's truth (robustness studies).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.core.registry import CONTROLLERS
from usv_mj.physics.ship import P_M11, P_M22, P_M23, P_M33, ShipParams, do_pan_offset, nominal_terms

from usv_mj.controllers.base import D_ALPHA_R, D_ALPHA_U, D_ALPHA_V, D_E1S, D_E2S, D_E3S, D_R_E, D_S2, D_S2_CLAMPED, D_U_E, D_V_E, D_W_R_NORM, D_W_U_NORM, D_W_V_NORM, DIAG_FIELDS, N_DIAG, REF_PSI, REF_R
from usv_mj.controllers.performance_funnel import PerformanceFunnel, funnels_of
from usv_mj.controllers.rbf_network import node_centres, rbf_activations3
from usv_mj.controllers.tracking_errors import offset_point_velocity, tracking_errors

ALPHA_R_MODES = ("printed", "analytic")


@dataclass(frozen=True)
class PPCGains:
    """Design parameters of the adaptive PPC law (docs/model.md §3; printed values unless noted).

    Attributes
    ----------
    l1, l2:
        Virtual-control gains of Eq. 17 [1/s]; printed 1 and 2.
    l3:
        Coupling gain of Eqs. 29 and 34 [1/s]; printed 1.
    k1, k3:
        Velocity-loop gains of Eq. 34 [1/s]; printed 3 and 10 (k2 = 5 is used nowhere).
    a1:
        Blend width of psi_a in Eq. 15 [m^2]; not printed (docs/model.md §5: 1).
    b1, b3:
        Smoothing constants of Eq. 37 (beta_1, beta_3); not printed (0.1).
    b2:
        Sway auxiliary gain of Eq. 19 (beta_2) [m/s]; not printed (1).
    gamma_u, gamma_v, gamma_r:
        Adaptation rates Gamma_i of Eq. 37; printed 1e5, 1e4, 1e3 (``paper``: 1e3, 1e2, 10).
    theta_u, theta_v, theta_r:
        sigma-modification leakage (the paper's vartheta_i); printed 1e-8, 1e-5, 1e-7.
    sigma_u, sigma_v, sigma_r:
        Gaussian widths of Eq. 12; printed 0.7e-8 (u, v) and 1.5e-7 (r) (``paper``: 0.7, 0.7, 1.5).
    rbf_nodes, rbf_span:
        Number of nodes and the half-span of their centres (39 on [-16, 16]).
    alpha_r:
        "printed" (alpha_r = psi_d_dot - l2 e3*) or "analytic" (psi_a_dot in place of psi_d_dot).
    s2_limit:
        Clamp on |s2| = |tanh gamma_2| (< 1).
    """

    l1: float = 1.0
    l2: float = 2.0
    l3: float = 1.0
    k1: float = 3.0
    k3: float = 10.0
    a1: float = 1.0
    b1: float = 0.1
    b2: float = 1.0
    b3: float = 0.1
    gamma_u: float = 1e3
    gamma_v: float = 1e2
    gamma_r: float = 10.0
    theta_u: float = 1e-8
    theta_v: float = 1e-5
    theta_r: float = 1e-7
    sigma_u: float = 0.7
    sigma_v: float = 0.7
    sigma_r: float = 1.5
    rbf_nodes: int = 39
    rbf_span: float = 16.0
    alpha_r: str = "printed"
    s2_limit: float = 1.0 - 1e-9

    def __post_init__(self) -> None:
        positive = ("l1", "l2", "l3", "k1", "k3", "a1", "b1", "b2", "b3", "sigma_u", "sigma_v", "sigma_r", "rbf_span")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"controller.{name} must be > 0, got {value!r}")
        for name in ("gamma_u", "gamma_v", "gamma_r", "theta_u", "theta_v", "theta_r"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"controller.{name} must be >= 0, got {value!r}")
        if not (isinstance(self.rbf_nodes, int) and self.rbf_nodes >= 1):
            raise ValueError(f"controller.rbf_nodes must be an integer >= 1, got {self.rbf_nodes!r}")
        if self.alpha_r not in ALPHA_R_MODES:
            raise ValueError(f"controller.alpha_r must be one of {ALPHA_R_MODES}, got {self.alpha_r!r}")
        if not 0 < self.s2_limit < 1:
            raise ValueError(f"controller.s2_limit must be in (0, 1), got {self.s2_limit!r}")

    def as_array(self, delta_u: float, delta_r: float) -> np.ndarray:
        return np.array(
            [self.l1, self.l2, self.l3, self.k1, self.k3, self.a1, self.b1, self.b2, self.b3,
             self.gamma_u, self.gamma_v, self.gamma_r, self.theta_u, self.theta_v, self.theta_r,
             self.sigma_u, self.sigma_v, self.sigma_r, float(ALPHA_R_MODES.index(self.alpha_r)),
             self.s2_limit, delta_u, delta_r],
            dtype=np.float64,
        )


@njit(cache=True)
def _dot(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


@njit(cache=True)
def ppc_law(t, x, ref, p, g, funnel, centres, w, s2, dt, diag, s_buf, z_buf):
    """Evaluate docs/model.md §3 once, advance (W, s2) by ``dt``; returns (tau_u, tau_r).

    ``w`` is the 3 x n weight matrix (rows W_u, W_v, W_r), ``s2`` a 1-vector, ``s_buf`` 3 x n scratch.
    """
    l1, l2, l3, k1, k3, a1, b1, b2, b3 = g[0], g[1], g[2], g[3], g[4], g[5], g[6], g[7], g[8]
    gam_u, gam_v, gam_r, th_u, th_v, th_r = g[9], g[10], g[11], g[12], g[13], g[14]
    sig_u, sig_v, sig_r, analytic, s2_lim, delta_u, delta_r = g[15], g[16], g[17], g[18], g[19], g[20], g[21]
    m11, m22, m23, m33 = p[P_M11], p[P_M22], p[P_M23], p[P_M33]
    eps = do_pan_offset(m22, m23)
    e1, e2, h2, chi, th, e1_dot, e2_dot = tracking_errors(eps, a1, t, x, ref, funnel, diag)
    e1s, e2s, e3s = diag[D_E1S], diag[D_E2S], diag[D_E3S]
    psi = x[2]
    c, s = math.cos(psi), math.sin(psi)
    psi_d = ref[REF_PSI]
    xbd_dot, ybd_dot = offset_point_velocity(eps, ref)
    big_a = xbd_dot - l1 * e1s
    big_b = ybd_dot - l1 * e2s
    alpha_u = big_a * c + big_b * s
    alpha_v = -big_a * s + big_b * c
    if analytic > 0.5:
        chi_dot = (e1 * e2_dot - e2 * e1_dot) / h2 if h2 > 1e-12 else 0.0
        th_dot = (1.0 - th * th) * 2.0 * (e1 * e1_dot + e2 * e2_dot) / a1
        psi_ref_dot = chi_dot * th + (chi - psi_d) * th_dot + ref[REF_R] * (1.0 - th)
    else:
        psi_ref_dot = ref[REF_R]
    alpha_r = psi_ref_dot - l2 * e3s
    u, v, r = x[3], x[4], x[5]
    v_bar = v + eps * r
    s2v = s2[0]
    u_e = u - alpha_u
    v_e = v_bar - alpha_v - b2 * s2v
    r_e = r - alpha_r
    z_buf[0], z_buf[1], z_buf[2] = u, v, r
    z_buf[3], z_buf[4], z_buf[5] = alpha_u, alpha_v, alpha_r
    z_buf[6], z_buf[7], z_buf[8] = e1s, e2s, e3s
    rbf_activations3(z_buf, centres, sig_u, sig_v, sig_r, s_buf)  # Eq. 12 per width
    s_u, s_v, s_r = s_buf[0], s_buf[1], s_buf[2]
    phi_u, phi_v, phi_r = nominal_terms(p, x[3:])
    gamma1 = (k1 + l3) * u_e + phi_u + _dot(w[0], s_u) + l3 * v_e
    gamma3 = (k3 + l3) * r_e + phi_r + _dot(w[2], s_r) + l3 * v_e
    delta_m = m22 * m33 - m23 * m23
    g1sq = gamma1 * gamma1
    g3sq = gamma3 * gamma3
    tau_u = -m11 * u_e * g1sq / ((1.0 - delta_u) * math.sqrt(u_e * u_e * g1sq + b1 * b1))
    tau_r = -delta_m * r_e * g3sq / (m22 * (1.0 - delta_r) * math.sqrt(r_e * r_e * g3sq + b3 * b3))
    # state updates over the control period
    s2_dot = (_dot(w[1], s_v) + phi_v - l3 * u_e + l3 * v_e - l3 * r_e) / b2
    s2_new = s2v + dt * s2_dot
    clamped = 0.0
    if s2_new > s2_lim:
        s2_new = s2_lim
        clamped = 1.0
    elif s2_new < -s2_lim:
        s2_new = -s2_lim
        clamped = 1.0
    s2[0] = s2_new
    n = centres.shape[0]
    nu_acc = 0.0
    nv_acc = 0.0
    nr_acc = 0.0
    for j in range(n):
        w[0, j] += dt * gam_u * (u_e * s_u[j] - th_u * w[0, j])
        w[1, j] += dt * gam_v * (v_e * s_v[j] - th_v * w[1, j])
        w[2, j] += dt * gam_r * (r_e * s_r[j] - th_r * w[2, j])
        nu_acc += w[0, j] * w[0, j]
        nv_acc += w[1, j] * w[1, j]
        nr_acc += w[2, j] * w[2, j]
    diag[D_U_E] = u_e
    diag[D_V_E] = v_e
    diag[D_R_E] = r_e
    diag[D_ALPHA_U] = alpha_u
    diag[D_ALPHA_V] = alpha_v
    diag[D_ALPHA_R] = alpha_r
    diag[D_W_U_NORM] = math.sqrt(nu_acc)
    diag[D_W_V_NORM] = math.sqrt(nv_acc)
    diag[D_W_R_NORM] = math.sqrt(nr_acc)
    diag[D_S2] = s2v  # the s2 this step's law used, like every other field of the row
    diag[D_S2_CLAMPED] = clamped
    return tau_u, tau_r


@njit(cache=True)
def ppc_kernel(t, x, ref, p, g, funnel, centres, w, s2, dt, diag, s_buf, z_buf):
    """The compiled loop's kernel of :class:`PPCController` (usv_mj.core.kernels): ``__call__`` natively."""
    tau_u, tau_r = ppc_law(t, x, ref, p, g, funnel, centres, w, s2, dt, diag, s_buf, z_buf)
    return tau_u, tau_r, diag


@CONTROLLERS.register("ppc", gains=PPCGains)
class PPCController:
    """The paper's adaptive PPC tracking controller (docs/model.md §3) behind the controller interface.

    Parameters
    ----------
    gains:
        :class:`PPCGains`.
    nominal:
        The ship model the controller knows (phi_u, phi_v, phi_r of Eq. 28 and eps = m23/m22).
    funnel_xy, funnel_psi:
        Performance bounds of Eq. 9 for e1, e2 [m] and e3 [rad].
    delta_u, delta_r:
        The quantizer's delta of each channel, used by Eq. 37's 1/(1 - delta) margin.
    control_period:
        dt [s] over which the adaptive states are integrated (explicit Euler).
    """

    name = "ppc"
    diagnostic_fields = DIAG_FIELDS
    #: from the paper's start pose it drives paper-limited's thrusters into their limits (usv-mj compare's
    #: saturated case runs with it; controllers/base.py)
    reaches_actuator_limits = True
    diagnostic_events = {"s2_clamped": "s2_clamp"}

    @classmethod
    def from_scenario(cls, gains: PPCGains, scenario) -> "PPCController":
        """The law for ``scenario``: its nominal ship (the vessel's times
        ``[vessel] model_mismatch``: ``scenario.nominal_ship``), funnels, quantizer deltas and control period."""
        fxy, fpsi = funnels_of(scenario)
        return cls(gains, scenario.nominal_ship, fxy, fpsi, scenario.quantizer.delta_u, scenario.quantizer.delta_r,
                   scenario.control_period)

    def __init__(self, gains: PPCGains, nominal: ShipParams, funnel_xy: PerformanceFunnel,
                 funnel_psi: PerformanceFunnel, delta_u: float, delta_r: float, control_period: float):
        self.gains = gains
        self.nominal = nominal
        self._p = nominal.as_array()
        self._g = gains.as_array(delta_u, delta_r)
        self._funnel = np.array([funnel_xy.rho_0, funnel_xy.rho_inf, funnel_xy.rate,
                                 funnel_psi.rho_0, funnel_psi.rho_inf, funnel_psi.rate])
        self._centres = node_centres(gains.rbf_nodes, gains.rbf_span)
        self.dt = float(control_period)
        self.weights = np.zeros((3, gains.rbf_nodes))
        self._s2 = np.zeros(1)
        self._diag = np.zeros(N_DIAG)
        self._s_buf = np.zeros((3, gains.rbf_nodes))
        self._z_buf = np.zeros(9)

    @property
    def s2(self) -> float:
        return float(self._s2[0])

    def reset(self) -> None:
        """W(0) = 0 and s2(0) = 0 (docs/model.md §3 step 11)."""
        self.weights[:] = 0.0
        self._s2[0] = 0.0
        self._diag[:] = 0.0

    def kernel(self):
        """(ppc_kernel, its arrays): the law and its adaptive states for the compiled loop."""
        from usv_mj.core.kernels import Kernel

        return Kernel(ppc_kernel, (self._p, self._g, self._funnel, self._centres, self.weights, self._s2,
                                   self.dt, self._diag, self._s_buf, self._z_buf), n_diag=len(self._diag))

    def __call__(self, t, state, reference):
        tau_u, tau_r = ppc_law(float(t), state, reference, self._p, self._g, self._funnel, self._centres,
                               self.weights, self._s2, self.dt, self._diag, self._s_buf, self._z_buf)
        return tau_u, tau_r, self._diag
