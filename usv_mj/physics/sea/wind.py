"""Wind (docs/sea.md §5): OU gusts on a 0.05 s grid and Blendermann (1994) coefficients, "speed boat".

Relative wind in Fossen's convention: u_w = V_w cos(beta_w - psi), v_w = V_w sin(beta_w - psi),
u_rw = u - u_w, v_rw = v - v_w, gamma = -atan2(v_rw, u_rw) (0: air from the bow, +pi/2: air flowing
toward +y_b). tau_aero(nu, V) = 1/2 rho_a V_rw^2 [C_X A_Fw, C_Y A_Lw, C_N A_Lw L_oa] and the applied
load is tau_wind = tau_aero(nu, V_w(t)) - tau_aero(nu, 0): the calm-water damping already holds the
still-air drag, so V_w = 0 gives exactly 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from usv_mj.physics.sea.current import grid_interpolate
from usv_mj.physics.sea.layout import (E_CDLAF_AHEAD, E_CDLAF_ASTERN, E_CDT, E_DELTA, E_FRONTAL_AREA, E_LATERAL_AREA,
                     E_LATERAL_CENTROID, E_LENGTH_OVERALL, E_RHO_AIR, E_WIND_COS, E_WIND_DT,
                     E_WIND_MEAN, E_WIND_ON, E_WIND_SIN)

WIND_GRID_STEP = 0.05  # s (docs/sea.md §5)
# Blendermann (1994) "speed boat" (MSS blendermann94.m): C_Dt, C_DlAF ahead / astern, delta
BLENDERMANN_SPEED_BOAT = (0.90, 0.55, 0.60, 0.60)


@njit(cache=True)
def blendermann_coefficients(ep, gamma):
    """(C_X, C_Y, C_N) at the angle of attack gamma [rad] (0: air from the bow), docs/sea.md §5.

    g_a = |gamma|, sg = sign(sin gamma) (+1 at 0); C_Dl = C_DlAF A_Fw / A_Lw;
    den = 1 - delta/2 (1 - C_Dl/C_Dt) sin^2(2 g_a); C_X = -C_DlAF cos g_a / den;
    C_Y = sg C_Dt sin g_a / den; C_N = (s_L / L_oa - 0.18 (g_a - pi/2)) C_Y.
    """
    ga = abs(gamma)
    sg = 1.0 if math.sin(gamma) >= 0.0 else -1.0
    cdt = ep[E_CDT]
    cdlaf = ep[E_CDLAF_AHEAD] if ga <= 0.5 * math.pi else ep[E_CDLAF_ASTERN]
    cdl = cdlaf * ep[E_FRONTAL_AREA] / ep[E_LATERAL_AREA]
    s2 = math.sin(2.0 * ga)
    den = 1.0 - 0.5 * ep[E_DELTA] * (1.0 - cdl / cdt) * s2 * s2
    cx = -cdlaf * math.cos(ga) / den
    cy = sg * cdt * math.sin(ga) / den
    cn = (ep[E_LATERAL_CENTROID] / ep[E_LENGTH_OVERALL] - 0.18 * (ga - 0.5 * math.pi)) * cy
    return cx, cy, cn


@njit(cache=True)
def aero_force(ep, u_rw, v_rw):
    """tau_aero [N, N, N m] for the relative air velocity (u_rw, v_rw) = nu - wind in {b} [m/s]."""
    v2 = u_rw * u_rw + v_rw * v_rw
    if v2 == 0.0:
        return 0.0, 0.0, 0.0
    gamma = -math.atan2(v_rw, u_rw)
    cx, cy, cn = blendermann_coefficients(ep, gamma)
    qd = 0.5 * ep[E_RHO_AIR] * v2
    return (qd * cx * ep[E_FRONTAL_AREA], qd * cy * ep[E_LATERAL_AREA],
            qd * cn * ep[E_LATERAL_AREA] * ep[E_LENGTH_OVERALL])


@njit(cache=True)
def wind_speed_at(ep, wind_grid2d, t):
    """V_w(t) = max(0, mean + g(t)) [m/s]; g linear between the 0.05 s grid points."""
    if ep[E_WIND_ON] == 0.0:
        return 0.0
    g, _ = grid_interpolate(wind_grid2d, 0, ep[E_WIND_DT], t)
    v = ep[E_WIND_MEAN] + g
    return v if v > 0.0 else 0.0


@njit(cache=True)
def wind_load(ep, wind_grid2d, t, psi, u, v):
    """tau_wind = tau_aero(nu, V_w(t)) - tau_aero(nu, 0), body frame [N, N, N m] (absolute nu)."""
    if ep[E_WIND_ON] == 0.0:
        return 0.0, 0.0, 0.0
    vw = wind_speed_at(ep, wind_grid2d, t)
    cpsi, spsi = math.cos(psi), math.sin(psi)
    cbw, sbw = ep[E_WIND_COS], ep[E_WIND_SIN]
    u_w = vw * (cbw * cpsi + sbw * spsi)
    v_w = vw * (sbw * cpsi - cbw * spsi)
    x1, y1, n1 = aero_force(ep, u - u_w, v - v_w)
    x0, y0, n0 = aero_force(ep, u, v)
    return x1 - x0, y1 - y0, n1 - n0


@njit(cache=True)
def wind_speed_record(ep, wind_grid2d, ts):
    """V_w at each of the times ``ts`` [m/s] (for records and figures)."""
    out = np.empty(ts.shape[0])
    for i in range(ts.shape[0]):
        out[i] = wind_speed_at(ep, wind_grid2d, ts[i])
    return out
