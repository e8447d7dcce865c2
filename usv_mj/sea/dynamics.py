"""The one physics function with the sea (docs/sea.md §1), over usv_mj.ship's kernels.

    nu_r     = nu - nu_c
    M nu_dot = M nu_c_dot + tau + tau_env + Delta(eta, nu) + d(t) - C(nu_r) nu_r - D(nu_r) nu_r
    eta_dot  = J(psi) nu                                   (absolute nu)

nu_r enters the whole C (rigid body and added mass) and all damping; Delta (the paper's model
uncertainty, Sec. 4), d(t), kinematics and wind use absolute nu. With a calm environment every output
is bit-identical to :func:`usv_mj.ship.state_derivative`: calm is this same code with the sea's terms
absent (:func:`sea_force` is then :func:`usv_mj.ship.hydrodynamic_force`).

Written once: the hull's force is :func:`usv_mj.ship.hull_force` (with nu_r), the M^-1 solve and the
eta_dot assembly are usv_mj.ship's, and :func:`sea_rk4_advance` is the only RK4 loop of the package
(:func:`usv_mj.plants.analytic.rk4_advance` is its calm case, :func:`calm_rk4_advance`).

Kernel arguments: ``p`` (ShipParams.as_array()), ``dp`` (PaperDisturbance.as_array()), then the four
arrays of ``Environment.packed`` (``ep, waves, current_grid, wind_grid``; :mod:`usv_mj.sea.layout`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from usv_mj.ship import (P_M11, P_M22, P_M23, P_M33, hull_force, hydrodynamic_force, stack_derivative,
                         state_derivative, thrust_acceleration)

from .environment import environment_loads
from .layout import (E_CURRENT_ON, E_WAVES_ON, E_WIND_ON, L_DRIFT, L_NU_C, L_NU_C_DOT, L_WAVE1,
                     L_WIND, N_ENV_PARAMS, N_WAVE_COLS)


@njit(cache=True)
def is_calm(ep):
    """True when the packed environment ``ep`` has no waves, current or wind (the sea's terms absent)."""
    return ep[E_WAVES_ON] == 0.0 and ep[E_CURRENT_ON] == 0.0 and ep[E_WIND_ON] == 0.0


@njit(cache=True)
def sea_force(p, dp, ep, waves, current_grid, wind_grid, t, eta, nu):
    """Everything on the hull but the thrust, body frame [N, N, N m] (docs/sea.md §1):

    f = M nu_c_dot + tau_env + Delta(eta, nu) + d(t) - C(nu_r) nu_r - D(nu_r) nu_r.

    For the MuJoCo callback (docs/sea.md §6): f_callback = -M_A nu_dot + f + C_RB(nu) nu.
    In a calm environment this is usv_mj.ship.hydrodynamic_force itself.
    """
    if is_calm(ep):
        return hydrodynamic_force(p, dp, t, eta, nu)
    env = environment_loads(ep, waves, current_grid, wind_grid, t, eta, nu)
    nu_r = np.empty(3)
    for i in range(3):
        nu_r[i] = nu[i] - env[L_NU_C + i]
    f = hull_force(p, dp, t, eta, nu, nu_r)
    a0 = env[L_NU_C_DOT]
    a1 = env[L_NU_C_DOT + 1]
    a2 = env[L_NU_C_DOT + 2]
    m_a = (p[P_M11] * a0, p[P_M22] * a1 + p[P_M23] * a2, p[P_M23] * a1 + p[P_M33] * a2)
    for i in range(3):
        f[i] = f[i] + (m_a[i] + (env[L_WIND + i] + env[L_WAVE1 + i] + env[L_DRIFT + i]))
    return f


@njit(cache=True)
def sea_body_acceleration(p, dp, ep, waves, current_grid, wind_grid, t, eta, nu, tau_u, tau_r):
    """nu_dot = M^-1 (sea_force + [tau_u, 0, tau_r]) [m/s^2, m/s^2, rad/s^2]."""
    return thrust_acceleration(p, sea_force(p, dp, ep, waves, current_grid, wind_grid, t, eta, nu), tau_u, tau_r)


@njit(cache=True)
def sea_state_derivative(p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r):
    """d/dt of x = (x, y, psi, u, v, r) with the sea; calm: equal to usv_mj.ship.state_derivative."""
    if is_calm(ep):
        return state_derivative(p, dp, t, x, tau_u, tau_r)  # calm: the sea's terms absent
    return stack_derivative(x, sea_body_acceleration(p, dp, ep, waves, current_grid, wind_grid, t, x[:3], x[3:],
                                                     tau_u, tau_r))


@njit(cache=True)
def sea_rk4_advance(p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r, h, n):
    """``n`` classic RK4 steps of size ``h`` from (t, x) under constant thrust, the sea evaluated at
    the stage times; returns the new x. The one RK4 step: calm water is :func:`calm_rk4_advance`."""
    for _ in range(n):
        k1 = sea_state_derivative(p, dp, ep, waves, current_grid, wind_grid, t, x, tau_u, tau_r)
        k2 = sea_state_derivative(p, dp, ep, waves, current_grid, wind_grid, t + 0.5 * h, x + 0.5 * h * k1,
                                  tau_u, tau_r)
        k3 = sea_state_derivative(p, dp, ep, waves, current_grid, wind_grid, t + 0.5 * h, x + 0.5 * h * k2,
                                  tau_u, tau_r)
        k4 = sea_state_derivative(p, dp, ep, waves, current_grid, wind_grid, t + h, x + h * k3, tau_u, tau_r)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        t = t + h
    return x


@njit(cache=True)
def calm_rk4_advance(p, dp, t, x, tau_u, tau_r, h, n):
    """:func:`sea_rk4_advance` in calm water (no waves, current or wind: every switch of ``ep`` off),
    i.e. RK4 of :func:`usv_mj.ship.state_derivative`, bit for bit."""
    return sea_rk4_advance(p, dp, np.zeros(N_ENV_PARAMS), np.zeros((N_WAVE_COLS, 0)), np.zeros((0, 2)),
                           np.zeros((0, 1)), t, x, tau_u, tau_r, h, n)


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
