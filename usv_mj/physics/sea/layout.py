"""Layout of the packed arrays that the sea kernels take (so a native callback can call them).

An environment is four float64 arrays, :class:`usv_mj.physics.sea.environment.PackedEnvironment`:

``ep`` (vector, ``N_ENV_PARAMS``)
    scalars: hull box, ramp, switches, mean current, wind, windage and Blendermann coefficients
    (indices ``E_*`` below).
``waves`` (C-contiguous, shape ``(N_WAVE_COLS, N)``; N = 0 in calm water)
    one column per wave component j, rows ``W_*``: a_j [m], w_j [rad/s], k_j [rad/m],
    cos beta_j, sin beta_j (going-to direction), eps_j [rad], c_j = c_dif rho g a_j (1 - e^{-k_j T})
    [N/m^2], q_j = 1/2 rho g R^2(k_j T) [N/m^2] (drift factor, docs/sea.md §3).
``current_grid`` (C-contiguous, shape ``(n_c, 2)``)
    OU deviations of the current (earth x, y) [m/s] at t = i * ep[E_CURRENT_DT], i = 0..n_c-1.
``wind_grid`` (C-contiguous, shape ``(n_w, 1)``)
    OU gust deviations g [m/s] at t = i * ep[E_WIND_DT].

A grid of zero rows means "no variation" (sigma = 0).

Past the end of a grid the kernels hold the last value (slope 0): call
``Environment.ensure_horizon(t_end)`` before taking the arrays for a run.
"""

from numba import njit


# --- ep: environment scalars ----------------------------------------------------------------------
E_LENGTH = 0          # L [m]
E_BEAM = 1            # B [m]
E_DRAFT = 2           # T [m]
E_BOX_X = 3           # x_b [m], box centre ahead of the origin
E_RAMP = 4            # tau_ramp [s]; 0: no ramp (s = 1)
E_DRIFT_MODE = 5      # 0 off, 1 mean, 2 newman
E_WAVES_ON = 6        # 1.0 when there is at least one component
E_CURRENT_ON = 7      # 1.0 when the current is not identically 0
E_CURRENT_X = 8       # mean current, earth x [m/s]
E_CURRENT_Y = 9       # mean current, earth y [m/s]
E_CURRENT_DT = 10     # grid step of the current OU [s]
E_WIND_ON = 11        # 1.0 when there is wind
E_WIND_MEAN = 12      # mean wind speed [m/s]
E_WIND_COS = 13       # cos of the going-to direction of the wind
E_WIND_SIN = 14       # sin of it
E_WIND_DT = 15        # grid step of the gust OU [s]
E_RHO_AIR = 16        # [kg/m^3]
E_FRONTAL_AREA = 17   # A_Fw [m^2]
E_LATERAL_AREA = 18   # A_Lw [m^2]
E_LENGTH_OVERALL = 19  # L_oa [m]
E_LATERAL_CENTROID = 20  # s_L [m]
E_CDT = 21            # Blendermann C_Dt
E_CDLAF_AHEAD = 22    # C_DlAF for |gamma| <= pi/2
E_CDLAF_ASTERN = 23   # C_DlAF for |gamma| > pi/2
E_DELTA = 24          # Blendermann delta
N_ENV_PARAMS = 25

DRIFT_OFF, DRIFT_MEAN, DRIFT_NEWMAN = 0, 1, 2

# --- waves: rows of the component array ----------------------------------------------------------
W_A, W_W, W_K, W_COSB, W_SINB, W_EPS, W_C, W_Q = 0, 1, 2, 3, 4, 5, 6, 7
N_WAVE_COLS = 8

# --- environment_loads output (15-vector) ----------------------------------------------------------
L_NU_C = 0            # nu_c (3): current in the body frame [m/s, m/s, 0]
L_NU_C_DOT = 3        # nu_c_dot (3) [m/s^2]
L_WIND = 6            # tau_wind (3) [N, N, N m]
L_WAVE1 = 9           # s(t) tau_wave1 (3), ramp applied
L_DRIFT = 12          # s(t)^2 tau_drift (3), ramp applied
N_LOADS = 15


@njit(cache=True)
def is_calm(ep):
    """True when the packed environment ``ep`` has no waves, current or wind (the sea's terms absent)."""
    return ep[E_WAVES_ON] == 0.0 and ep[E_CURRENT_ON] == 0.0 and ep[E_WIND_ON] == 0.0
