"""The MMG standard method (Yasukawa and Yoshimura 2015): hull, propeller and rudder forces, written once.

Yasukawa, H. and Yoshimura, Y. (2015), "Introduction of MMG standard method for ship maneuvering
predictions", J. Mar. Sci. Technol. 20, 37-52 (docs/vessels.md, KVLCC2). A vessel of this kind
(:mod:`usv_mj.vessels.kvlcc2`) has a rudder and a propeller: its two actuator inputs are the
propeller revolutions n_P [1/s] and the rudder angle delta [rad], carried in the plants' two input
channels (tau_u, tau_r) in place of a surge force and a yaw moment.

The MMG writes its equations in its own frame: origin at midship, x forward, y to starboard, z
down, so positive r and delta turn to starboard. usv_mj's body frame has y to port (README,
Conventions); the kernel mirrors (v_m = -v, r_m = -r, delta_m = -delta) in, and (Y, N) = -(Y_m, N_m)
out. The model is *not* port/starboard symmetric (gamma_R and the wake's C_2 differ with the
sign of the flow angle: the propeller turns one way), so the mirror is done exactly, not assumed.

With U = sqrt(u^2 + v_m^2), beta = atan2(-v_m, u), v' = v_m/U, r' = r L/U:

(``Q_XB`` = x_b moves the point whose lateral velocity v_m + x_b r sets U and beta; 0 is the
standard's midship; x_b = -x_G reproduces shipmmg 0.0.11, which takes them from v - x_G r:
docs/vessels.md, KVLCC2)

    hull       X_H = 1/2 rho L d U^2 (-R'_0 + X'_vv v'^2 + X'_vr v' r' + X'_rr r'^2 + X'_vvvv v'^4)
               Y_H = 1/2 rho L d U^2 (Y'_v v' + Y'_R r' + Y'_vvv v'^3 + Y'_vvr v'^2 r' + Y'_vrr v' r'^2 + Y'_rrr r'^3)
               N_H = 1/2 rho L^2 d U^2 (N'_v v' + N'_R r' + ... N'_rrr r'^3)
    propeller  beta_P = beta - x'_P r',  wake: 1 - w_P = (1 - w_P0) [1 + (1 - exp(-C_1 |beta_P|)) (C_2 - 1)]
               (C_2 = C_2+ for beta_P > 0, C_2- otherwise; Yasukawa and Yoshimura's Eq. of w_P), or
               w_P = w_P0 exp(-4 beta_P^2) (``wake_model`` 1, the form shipmmg uses)
               J_P = u (1 - w_P) / (n_P D_P),  K_T = k_0 + k_1 J_P + k_2 J_P^2,  X_P = (1 - t_P) rho n_P^2 D_P^4 K_T
    rudder     u_R = eps u (1 - w_P) sqrt(eta {1 + kappa (sqrt(1 + 8 K_T/(pi J_P^2)) - 1)}^2 + (1 - eta))
               v_R = U gamma_R beta_R,  beta_R = beta - l'_R r'  (gamma_R = gamma_R- for beta_R < 0, + otherwise)
               alpha_R = delta - atan2(v_R, u_R),  F_N = 1/2 rho A_R U_R^2 f_alpha sin alpha_R
               X_R = -(1 - t_R) F_N sin delta,  Y_R = -(1 + a_H) F_N cos delta,  N_R = -(x_R + a_H x_H) F_N cos delta

and the equations of motion at midship (mass m, COG x_G ahead of midship, added masses m_x, m_y, J_z)

    (m + m_x) u' - (m + m_y) v_m r - x_G m r^2 = X_H + X_P + X_R
    (m + m_y) v_m' + (m + m_x) u r + x_G m r' = Y_H + Y_R
    (I_zG + x_G^2 m + J_z) r' + x_G m (v_m' + u r) = N_H + N_R

i.e. M nu' = f with M = [[m + m_x, 0, 0], [0, m + m_y, x_G m], [0, x_G m, I_zG + x_G^2 m + J_z]] (the
packed hull's M, :class:`usv_mj.physics.ship.ShipParams`) and f = :func:`mmg_terms` (no Munk moment: the
(m_y - m_x) u v of a potential-flow C_A is not there; N'_v holds it).

The slipstream term is written u (1 - w_P) sqrt(1 + 8 K_T/(pi J_P^2)) = sqrt(u_P^2 + 8 K_T n_P^2 D_P^2/pi)
(u_P = u (1 - w_P)), equal for u_P > 0 and finite at u_P = 0. Outside the model's range (n_P <= 0:
MMG's propeller model is for ahead revolutions) the thrust is 0 and the rudder sees u_P alone;
K_T is used as the polynomial gives it (it goes negative past J_P = 0.97 for KVLCC2).

Packed parameters (:data:`Q_*`, offsets from a base index ``b``; the analytic plant reads them at
``usv_mj.physics.ship.P_MMG`` of the packed hull, the MuJoCo callback at ``mujoco_callback.U_MMG`` of
``d.userdata``): precomputed dimensional constants, so the kernel does no divisions by constants.
"""

from __future__ import annotations

import math

from numba import njit

# --- packed MMG block (offsets from the base index) -------------------------------------------
(Q_RHO, Q_L, Q_HULL_X, Q_HULL_N, Q_R0, Q_XVV, Q_XVR, Q_XRR, Q_XVVVV,
 Q_YV, Q_YR, Q_YVVV, Q_YVVR, Q_YVRR, Q_YRRR, Q_NV, Q_NR, Q_NVVV, Q_NVVR, Q_NVRR, Q_NRRR,
 Q_DP, Q_K0, Q_K1, Q_K2, Q_TP, Q_WP0, Q_XP, Q_WAKE, Q_C1, Q_C2P, Q_C2M,
 Q_RUDDER, Q_EPS, Q_KAPPA, Q_ETA, Q_TR, Q_AH, Q_XRAH, Q_GRM, Q_GRP, Q_LR,
 Q_MMX, Q_MMY, Q_MXG, Q_XB) = range(46)
N_MMG_PARAMS = 46
WAKE_YASUKAWA, WAKE_EXPONENTIAL = 0.0, 1.0


@njit(cache=True)
def mmg_flow(q, b, u, v_m, r_m):
    """(U [m/s], v', r', beta [rad]) of the hull at (u, v_m, r_m) in the MMG's frame (module docstring)."""
    L = q[b + Q_L]
    v_b = v_m + q[b + Q_XB] * r_m     # the standard: x_b = 0, U and beta of the midship velocity
    U = math.sqrt(u * u + v_b * v_b)
    if U > 0.0:
        return U, v_m / U, r_m * L / U, math.atan2(-v_b, u)
    return U, 0.0, 0.0, 0.0


@njit(cache=True)
def mmg_wake(q, b, beta, rd):
    """1 - w_P of the propeller in manoeuvring (module docstring) at the drift angle beta and r'."""
    beta_p = beta - q[b + Q_XP] * rd
    if q[b + Q_WAKE] == WAKE_EXPONENTIAL:
        return 1.0 - q[b + Q_WP0] * math.exp(-4.0 * beta_p * beta_p)
    c2 = q[b + Q_C2P] if beta_p > 0.0 else q[b + Q_C2M]
    return (1.0 - q[b + Q_WP0]) * (1.0 + (1.0 - math.exp(-q[b + Q_C1] * abs(beta_p))) * (c2 - 1.0))


@njit(cache=True)
def mmg_thrust(q, b, u_p, n_p):
    """K_T n_P^2 D_P^2 = T / (rho D_P^2) [m^2/s^2] at the propeller inflow u_p [m/s] and n_p [1/s]
    (0 for n_p <= 0, module docstring): K_T(J_P) n^2 D^2 = k_0 n^2 D^2 + k_1 u_p n D + k_2 u_p^2."""
    if n_p > 0.0:
        dp = q[b + Q_DP]
        j = u_p / (n_p * dp)
        kt = q[b + Q_K0] + q[b + Q_K1] * j + q[b + Q_K2] * j * j
        return kt * n_p * n_p * dp * dp
    return 0.0


@njit(cache=True)
def mmg_rudder_inflow(q, b, U, beta, rd, u_p, kt_n2d2):
    """(u_R, v_R) [m/s]: the rudder's inflow (module docstring); neither depends on delta."""
    s = math.sqrt(max(u_p * u_p + 8.0 * kt_n2d2 / math.pi, 0.0))
    a = u_p + q[b + Q_KAPPA] * (s - u_p)
    eta = q[b + Q_ETA]
    u_r = q[b + Q_EPS] * math.sqrt(eta * a * a + (1.0 - eta) * u_p * u_p)
    beta_r = beta - q[b + Q_LR] * rd
    gamma_r = q[b + Q_GRM] if beta_r < 0.0 else q[b + Q_GRP]
    return u_r, U * gamma_r * beta_r


@njit(cache=True)
def mmg_forces(q, b, u, v_m, r_m, n_p, delta_m):
    """(X_H, Y_H, N_H, X_P, X_R, Y_R, N_R) [N, N m] of the MMG in its own frame (module docstring):
    surge u [m/s], sway v_m [m/s, to starboard] at midship, yaw rate r_m [rad/s, to starboard],
    propeller revolutions n_p [1/s], rudder angle delta_m [rad, to starboard] at parameters ``q[b:]``."""
    U, vd, rd, beta = mmg_flow(q, b, u, v_m, r_m)
    u2 = U * U
    vd2 = vd * vd
    rd2 = rd * rd
    x_h = q[b + Q_HULL_X] * u2 * (-q[b + Q_R0] + q[b + Q_XVV] * vd2 + q[b + Q_XVR] * vd * rd
                                  + q[b + Q_XRR] * rd2 + q[b + Q_XVVVV] * vd2 * vd2)
    y_h = q[b + Q_HULL_X] * u2 * (q[b + Q_YV] * vd + q[b + Q_YR] * rd + q[b + Q_YVVV] * vd2 * vd
                                  + q[b + Q_YVVR] * vd2 * rd + q[b + Q_YVRR] * vd * rd2 + q[b + Q_YRRR] * rd2 * rd)
    n_h = q[b + Q_HULL_N] * u2 * (q[b + Q_NV] * vd + q[b + Q_NR] * rd + q[b + Q_NVVV] * vd2 * vd
                                  + q[b + Q_NVVR] * vd2 * rd + q[b + Q_NVRR] * vd * rd2 + q[b + Q_NRRR] * rd2 * rd)
    u_p = u * mmg_wake(q, b, beta, rd)
    kt_n2d2 = mmg_thrust(q, b, u_p, n_p)
    dp = q[b + Q_DP]
    x_p = (1.0 - q[b + Q_TP]) * q[b + Q_RHO] * kt_n2d2 * dp * dp
    u_r, v_r = mmg_rudder_inflow(q, b, U, beta, rd, u_p, kt_n2d2)
    f_n = q[b + Q_RUDDER] * (u_r * u_r + v_r * v_r) * math.sin(delta_m - math.atan2(v_r, u_r))
    sd, cd = math.sin(delta_m), math.cos(delta_m)
    x_r = -(1.0 - q[b + Q_TR]) * f_n * sd
    y_r = -(1.0 + q[b + Q_AH]) * f_n * cd
    n_r = -q[b + Q_XRAH] * f_n * cd
    return x_h, y_h, n_h, x_p, x_r, y_r, n_r


@njit(cache=True)
def mmg_terms(q, b, u, v, r, n_p, delta):
    """The right side f of M nu' = f of the MMG (module docstring) in usv_mj's body frame (y to
    port, r and delta positive to port) at (u, v, r) [m/s, m/s, rad/s] with n_p [1/s] and delta [rad]:
    (X + (m + m_y) v_m r + x_G m r^2, Y - (m + m_x) u r, N - x_G m u r), mirrored, a 3-tuple [N, N, N m]."""
    v_m, r_m = -v, -r
    x_h, y_h, n_h, x_p, x_r, y_r, n_r = mmg_forces(q, b, u, v_m, r_m, n_p, -delta)
    f0 = x_h + x_p + x_r + q[b + Q_MMY] * v_m * r_m + q[b + Q_MXG] * r_m * r_m
    f1 = y_h + y_r - q[b + Q_MMX] * u * r_m
    f2 = n_h + n_r - q[b + Q_MXG] * u * r_m
    return f0, -f1, -f2


# --- allocation: a surge force and a yaw moment -> (n_P, delta) ----------------------------------
ALLOCATION_ITERATIONS = 12   # secant steps at most on the propeller's share (docs/vessels.md)


@njit(cache=True)
def _allocate_at(q, b, U, beta, rd, u_p, lo, n_hi, delta_max, n_m, thrust):
    """(n_P, delta_m, X_R, sat_u, sat_r) for the propeller's thrust ``thrust`` [N] and the MMG-frame
    yaw moment ``n_m`` [N m] (:func:`mmg_allocate`)."""
    sat_u = 0.0
    if thrust < 0.0:
        thrust, sat_u = 0.0, 1.0
    dp = q[b + Q_DP]
    c = (1.0 - q[b + Q_TP]) * q[b + Q_RHO] * dp * dp
    qa = c * q[b + Q_K0] * dp * dp
    qb = c * q[b + Q_K1] * dp * u_p
    qc = c * q[b + Q_K2] * u_p * u_p - thrust
    n_p = (-qb + math.sqrt(max(qb * qb - 4.0 * qa * qc, 0.0))) / (2.0 * qa)
    if n_p > n_hi:
        n_p, sat_u = n_hi, 1.0
    elif n_p < lo:
        n_p, sat_u = lo, 1.0
    u_r, v_r = mmg_rudder_inflow(q, b, U, beta, rd, u_p, mmg_thrust(q, b, u_p, n_p))
    ur2 = u_r * u_r + v_r * v_r
    g = q[b + Q_XRAH] * q[b + Q_RUDDER] * ur2
    if g == 0.0:   # no flow past the rudder: it can do nothing
        return n_p, 0.0, 0.0, sat_u, (1.0 if n_m != 0.0 else 0.0)
    sat_r = 0.0
    phi = math.atan2(v_r, u_r)
    s = math.sin(phi) - 2.0 * n_m / g
    if s > 1.0:
        s, sat_r = 1.0, 1.0
    elif s < -1.0:
        s, sat_r = -1.0, 1.0
    delta_m = 0.5 * (phi + math.asin(s))
    if delta_m > delta_max:
        delta_m, sat_r = delta_max, 1.0
    elif delta_m < -delta_max:
        delta_m, sat_r = -delta_max, 1.0
    x_r = -(1.0 - q[b + Q_TR]) * q[b + Q_RUDDER] * ur2 * math.sin(delta_m - phi) * math.sin(delta_m)
    return n_p, delta_m, x_r, sat_u, sat_r


@njit(cache=True)
def mmg_allocate(q, b, u, v, r, tau_u, tau_r, n_lo, n_hi, delta_max):
    """(n_P [1/s], delta [rad], sat_u, sat_r): the propeller revolutions and the rudder angle whose
    propeller and rudder forces are the surge force ``tau_u`` [N] and the yaw moment ``tau_r`` [N m]
    of a force controller, in usv_mj's body frame (y to port; delta positive to port), at the state
    (u, v, r) and parameters ``q[b:]``:

        X_P(n_P) + X_R(n_P, delta) = tau_u,   N_R(n_P, delta) = tau_r

    (module docstring for X_P, X_R, N_R; the rudder's sway force Y_R is what the hull gets besides,
    as any rudder gives). Each is solved in closed form given the other:

    - the moment: u_R and v_R do not depend on delta, so with phi = atan2(v_R, u_R) and
      g = (x_R + a_H x_H) 1/2 rho A_R f_alpha U_R^2, N_R = -g sin(delta - phi) cos delta
      = -g (sin(2 delta - phi) - sin phi)/2 (MMG frame) gives delta = (phi + asin(sin phi - 2 N_R/g))/2;
    - the thrust X_P = (1 - t_P) rho D_P^2 (k_0 D_P^2 n^2 + k_1 D_P u_P n + k_2 u_P^2) is a quadratic in
      n_P: its larger root for X_P = T;

    and the rudder's drag X_R couples them: the propeller's share T solves T = tau_u - X_R(T) by the
    secant method from T = tau_u (at most :data:`ALLOCATION_ITERATIONS` steps, to 1e-9 N relative;
    where it has not reached 1e-6 N relative, near the rudder's limit, sat_u is set). n_P stays
    in [max(n_lo, 0), n_hi] (the MMG's propeller model is for ahead revolutions: it cannot pull
    astern, so a thrust below 0 is 0) and |delta| <= delta_max; sat_u / sat_r are 1 when a limit (or
    a moment beyond the rudder's largest) cut the channel, else 0. With no flow past the rudder
    (U_R = 0) delta is 0. An infinite command is the largest one (saturated); a NaN gives no
    revolutions, the rudder amidships and both flags."""
    if not (math.isfinite(tau_u) and math.isfinite(tau_r)):   # an infinite command is the largest, NaN none
        if tau_u != tau_u or tau_r != tau_r:
            return max(n_lo, 0.0), 0.0, 1.0, 1.0
        tau_u = min(max(tau_u, -1e30), 1e30)
        tau_r = min(max(tau_r, -1e30), 1e30)
    n_m = -tau_r
    U, vd, rd, beta = mmg_flow(q, b, u, -v, -r)
    u_p = u * mmg_wake(q, b, beta, rd)
    lo = max(n_lo, 0.0)
    t0 = tau_u
    n_p, delta_m, x_r, sat_u, sat_r = _allocate_at(q, b, U, beta, rd, u_p, lo, n_hi, delta_max, n_m, t0)
    f0 = t0 - (tau_u - x_r)
    tol = 1e-9 * (1.0 + abs(tau_u))
    t1 = tau_u - x_r
    f1 = f0
    for _ in range(ALLOCATION_ITERATIONS):
        if abs(f0) <= tol:
            f1 = f0
            break
        n_p, delta_m, x_r, sat_u, sat_r = _allocate_at(q, b, U, beta, rd, u_p, lo, n_hi, delta_max, n_m, t1)
        f1 = t1 - (tau_u - x_r)
        if abs(f1) <= tol or f1 == f0:
            break
        t0, t1, f0 = t1, t1 - f1 * (t1 - t0) / (f1 - f0), f1
    if not abs(f1) <= 1e-6 * (1.0 + abs(tau_u)):   # not met (steep near the rudder's limit): say so
        sat_u = 1.0
    return n_p, -delta_m, sat_u, sat_r


def mmg_force_limits(q, b, u, n_max, delta_max):
    """(tau_u_max [N], tau_r_max [N m]): the largest surge force X_P + X_R (the rudder amidships) and
    yaw moment |N_R| (the rudder hard over) that the propeller at ``n_max`` [1/s] and the rudder at
    ``delta_max`` [rad] give going straight ahead at ``u`` [m/s]: the reach of the allocation
    (:func:`mmg_allocate`) at that speed, e.g. the environments' action bounds on a ruddered vessel."""
    ahead = mmg_forces(q, b, u, 0.0, 0.0, n_max, 0.0)
    hard_over = mmg_forces(q, b, u, 0.0, 0.0, n_max, delta_max)
    return ahead[3] + ahead[4], abs(hard_over[6])
