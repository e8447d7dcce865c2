"""The one physics function with the sea (docs/sea.md §1), over usv_mj.physics.ship's kernels.

    nu_r     = nu - nu_c
    M nu_dot = M nu_c_dot + tau + tau_env + Delta(eta, nu) + d(t) - C(nu_r) nu_r - D(nu_r) nu_r
    eta_dot  = J(psi) nu                                   (absolute nu)

nu_r enters the whole C (rigid body and added mass) and all damping; Delta (the paper's model
uncertainty, Sec. 4), d(t), kinematics and wind use absolute nu. With a calm environment every output
is bit-identical to :func:`usv_mj.physics.ship.state_derivative`: calm is this same code with the sea's terms
absent (:func:`sea_force` is then :func:`usv_mj.physics.ship.hydrodynamic_force`).

Written once: the hull's force is :func:`usv_mj.physics.ship.hull_terms` (with nu_r), the M^-1 solve and the
eta_dot assembly are usv_mj.physics.ship's, and :func:`sea_rk4_advance` is the only RK4 loop of the package
(:func:`usv_mj.plants.analytic.rk4_advance` is its calm case, :func:`calm_rk4_advance`).

Kernel arguments: ``p`` (ShipParams.as_array()), ``dp`` (the packed d(t) of any disturbance kind,
usv_mj.physics.disturbances.packed_disturbance; a bare PaperDisturbance.as_array() is the paper's), then the four
arrays of ``Environment.packed`` (``ep, waves, current_grid, wind_grid``; :mod:`usv_mj.physics.sea.layout`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from usv_mj.physics.ship import P_M11, P_M22, P_M23, P_M33, array3, derivative_into, hull_terms

from usv_mj.physics.sea.environment import environment_loads
from usv_mj.physics.sea.layout import (L_DRIFT, L_NU_C, L_NU_C_DOT, L_WAVE1, L_WIND, N_ENV_PARAMS, N_WAVE_COLS,
                                       is_calm)


@njit(cache=True)
def sea_terms(p, dp, ep, waves, current_grid, wind_grid, t, eta, nu):
    """Everything on the hull but the thrust, body frame [N, N, N m] (docs/sea.md §1), a 3-tuple:

    f = M nu_c_dot + tau_env + Delta(eta, nu) + d(t) - C(nu_r) nu_r - D(nu_r) nu_r.

    For the MuJoCo callback (docs/sea.md §6): f_callback = -M_A nu_dot + f + C_RB(nu) nu.
    In a calm environment this is usv_mj.physics.ship.hull_terms with nu_r = nu (the sea's terms absent).
    """
    if is_calm(ep):
        return hull_terms(p, dp, t, eta, nu, nu)
    env = environment_loads(ep, waves, current_grid, wind_grid, t, eta, nu)
    nu_r = (nu[0] - env[L_NU_C], nu[1] - env[L_NU_C + 1], nu[2] - env[L_NU_C + 2])
    f0, f1, f2 = hull_terms(p, dp, t, eta, nu, nu_r)
    a0 = env[L_NU_C_DOT]
    a1 = env[L_NU_C_DOT + 1]
    a2 = env[L_NU_C_DOT + 2]
    m_a0, m_a1, m_a2 = p[P_M11] * a0, p[P_M22] * a1 + p[P_M23] * a2, p[P_M23] * a1 + p[P_M33] * a2
    return (f0 + (m_a0 + (env[L_WIND] + env[L_WAVE1] + env[L_DRIFT])),
            f1 + (m_a1 + (env[L_WIND + 1] + env[L_WAVE1 + 1] + env[L_DRIFT + 1])),
            f2 + (m_a2 + (env[L_WIND + 2] + env[L_WAVE1 + 2] + env[L_DRIFT + 2])))


@njit(cache=True)
def sea_force(p, dp, ep, waves, current_grid, wind_grid, t, eta, nu):
    """:func:`sea_terms` as an array; in a calm environment usv_mj.physics.ship.hydrodynamic_force itself."""
    return array3(sea_terms(p, dp, ep, waves, current_grid, wind_grid, t, eta, nu))


@njit(cache=True)
def sea_body_acceleration(p, dp, ep, waves, current_grid, wind_grid, t, eta, nu, tau_u, tau_r):
    """nu_dot = M^-1 (sea_force + [tau_u, 0, tau_r]) [m/s^2, m/s^2, rad/s^2]: the velocity part of
    :func:`sea_derivative_into`, the assembly the plants run."""
    x = np.empty(6)
    x[:3] = eta
    x[3:] = nu
    return sea_derivative_into(np.empty(6), p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r)[3:]


@njit(cache=True)
def sea_derivative_into(out, p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r):
    """out = d/dt of x = (x, y, psi, u, v, r) with the sea (usv_mj.physics.ship.derivative_into of sea_terms)."""
    f0, f1, f2 = sea_terms(p, dp, ep, waves, current_grid, wind_grid, t, x[:3], x[3:])
    return derivative_into(out, p, x, f0, f1, f2, tau_u, tau_r)


@njit(cache=True)
def sea_state_derivative(p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r):
    """d/dt of x = (x, y, psi, u, v, r) with the sea; calm: equal to usv_mj.physics.ship.state_derivative."""
    return sea_derivative_into(np.empty(6), p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r)


@njit(cache=True)
def sea_rk4_advance(p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r, h, n):
    """``n`` classic RK4 steps of size ``h`` from (t, x) under constant thrust, the sea evaluated at
    the stage times; returns the new x. The one RK4 step: calm water is :func:`calm_rk4_advance`.

    x_{n+1} = x_n + h/6 (k1 + 2 k2 + 2 k3 + k4), the stages in one work array (no allocation per stage)."""
    w = np.empty((6, 6))  # rows: k1, k2, k3, k4, the stage state, the new state
    k1, k2, k3, k4, xs, xn = w[0], w[1], w[2], w[3], w[4], w[5]
    for i in range(6):
        xn[i] = x[i]
    half = 0.5 * h
    sixth = h / 6.0
    for _ in range(n):
        sea_derivative_into(k1, p, dp, ep, waves, current_grid, wind_grid, t, xn, tau_u, tau_r)
        for i in range(6):
            xs[i] = xn[i] + half * k1[i]
        sea_derivative_into(k2, p, dp, ep, waves, current_grid, wind_grid, t + 0.5 * h, xs, tau_u, tau_r)
        for i in range(6):
            xs[i] = xn[i] + half * k2[i]
        sea_derivative_into(k3, p, dp, ep, waves, current_grid, wind_grid, t + 0.5 * h, xs, tau_u, tau_r)
        for i in range(6):
            xs[i] = xn[i] + h * k3[i]
        sea_derivative_into(k4, p, dp, ep, waves, current_grid, wind_grid, t + h, xs, tau_u, tau_r)
        for i in range(6):
            xn[i] = xn[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        t = t + h
    return xn.copy()


_CALM_EP = np.zeros(N_ENV_PARAMS)
_CALM_WAVES = np.zeros((N_WAVE_COLS, 0))
_CALM_CURRENT = np.zeros((0, 2))
_CALM_WIND = np.zeros((0, 1))


@njit(cache=True)
def calm_rk4_advance(p, dp, t, x, tau_u, tau_r, h, n):
    """:func:`sea_rk4_advance` in calm water (no waves, current or wind: every switch of ``ep`` off),
    i.e. RK4 of :func:`usv_mj.physics.ship.state_derivative`, bit for bit."""
    return sea_rk4_advance(p, dp, _CALM_EP, _CALM_WAVES, _CALM_CURRENT, _CALM_WIND, t, x, tau_u, tau_r, h, n)


@njit(cache=True)
def sea_rk4_trajectory(p, dp, ep, waves, current_grid, wind_grid, t0, x0, tau_u, tau_r, h, n, every):
    """RK4 from (t0, x0) for n steps of h, returning the state every ``every`` steps (rows, incl. x0)."""
    m = n // every + 1
    out = np.empty((m, 6))
    out[0] = x0
    x = x0.copy()
    t = t0
    for i in range(1, m):
        x = sea_rk4_advance(p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r, h, every)
        t = t0 + i * every * h
        out[i] = x
    return out
