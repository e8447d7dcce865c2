"""Tracking errors in Do & Pan's coordinates and their funnel transform (docs/model.md §3 steps 1-4).

e1 = x_bar - x_bar_d, e2 = y_bar - y_bar_d (Eq. 14), H^2 = e1^2 + e2^2,
chi = atan2(-e2, -e1) on the branch nearest psi_d (the printed tan^-1(-e2/-e1) loses the quadrant),
th = tanh(H^2 / a1), psi_a = chi th + psi_d (1 - th) (Eq. 15), e3 = wrap(psi - psi_a),
rho_i by Eq. 9, z_i = e_i / rho_i, e_i* by Eq. 10.
"""

from __future__ import annotations

import math

from numba import njit

from usv_mj.physics.ship import wrap_angle

from usv_mj.controllers.base import D_E1, D_E1S, D_E2, D_E2S, D_E3, D_E3S, D_PSI_A, D_RHO1, D_RHO2, D_RHO3, D_Z1, D_Z2, D_Z3, REF_PSI, REF_R, REF_X, REF_XDOT, REF_Y, REF_YDOT
from usv_mj.controllers.performance_funnel import error_transform, funnel_bound

# funnel parameter vector: rho_0, rho_inf, rate for e1 and e2, then for e3
F_XY, F_PSI = 0, 3


#: the angle wrap to [-pi, pi): usv_mj.physics.ship.wrap_angle (this name kept for its importers)
wrap = wrap_angle


@njit(cache=True)
def offset_point_velocity(eps, ref):
    """(x_bar_d_dot, y_bar_d_dot) of Do & Pan's reference point x_bar_d = x_d + eps cos psi_d,
    y_bar_d = y_d + eps sin psi_d (Eq. 14) [m/s]: x_d_dot - eps sin psi_d r_d, y_d_dot + eps cos psi_d r_d."""
    psi_d = ref[REF_PSI]
    return (ref[REF_XDOT] - eps * math.sin(psi_d) * ref[REF_R],
            ref[REF_YDOT] + eps * math.cos(psi_d) * ref[REF_R])


@njit(cache=True)
def tracking_errors(eps, a1, t, x, ref, funnel, diag):
    """Fill diag[e1..e3, rho1..3, z1..3, e1s..e3s, psi_a]; return (e1, e2, H2, chi, th, e1_dot, e2_dot).

    ``eps`` = m23/m22 [m] of the controller's nominal model, ``a1`` [m^2] of Eq. 15, ``funnel`` the
    6-vector (rho_0, rho_inf, rate) for position then heading.
    """
    psi = x[2]
    c, s = math.cos(psi), math.sin(psi)
    psi_d = ref[REF_PSI]
    cd, sd = math.cos(psi_d), math.sin(psi_d)
    e1 = x[0] + eps * c - (ref[REF_X] + eps * cd)
    e2 = x[1] + eps * s - (ref[REF_Y] + eps * sd)
    h2 = e1 * e1 + e2 * e2
    chi = math.atan2(-e2, -e1)
    chi = psi_d + wrap_angle(chi - psi_d)
    th = math.tanh(h2 / a1)
    psi_a = chi * th + psi_d * (1.0 - th)
    e3 = wrap_angle(psi - psi_a)
    rho_xy = funnel_bound(funnel[F_XY], funnel[F_XY + 1], funnel[F_XY + 2], t)
    rho_psi = funnel_bound(funnel[F_PSI], funnel[F_PSI + 1], funnel[F_PSI + 2], t)
    diag[D_E1] = e1
    diag[D_E2] = e2
    diag[D_E3] = e3
    diag[D_RHO1] = rho_xy
    diag[D_RHO2] = rho_xy
    diag[D_RHO3] = rho_psi
    z1, z2, z3 = e1 / rho_xy, e2 / rho_xy, e3 / rho_psi
    diag[D_Z1] = z1
    diag[D_Z2] = z2
    diag[D_Z3] = z3
    diag[D_E1S] = error_transform(z1)
    diag[D_E2S] = error_transform(z2)
    diag[D_E3S] = error_transform(z3)
    diag[D_PSI_A] = psi_a
    # Eq. 16: e_dot = J(psi) [u, v_bar, r] - [x_bar_d_dot, y_bar_d_dot, ...]
    v_bar = x[4] + eps * x[5]
    xbd_dot, ybd_dot = offset_point_velocity(eps, ref)
    e1_dot = x[3] * c - v_bar * s - xbd_dot
    e2_dot = x[3] * s + v_bar * c - ybd_dot
    return e1, e2, h2, chi, th, e1_dot, e2_dot
