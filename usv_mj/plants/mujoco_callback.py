"""The hydrodynamic passive-force callback of the MuJoCo plant (docs/model.md §1), native and Python.

MuJoCo carries the rigid body of :class:`usv_mj.physics.ship.RigidBodySplit` (mass m, COM offset x_g, yaw
inertia about the origin). This callback adds everything else of Eq. 2, so that the total is the
paper's ship:

    M_RB nu_dot + C_RB(nu) nu = tau + f_h,
    f_h = -M_A nu_dot - C_A(nu) nu - D(nu) nu + Delta(eta, nu) + d(t)           (body frame)

with C_A = C - C_RB (C of docs/model.md §1 from :mod:`usv_mj.physics.ship`, C_RB of the rigid body with COM offset
x_g: C_RB nu = [-m (v + x_g r) r, m u r, m x_g u r]).

Added mass is exact (no lag). With q = (x, y, psi) the joint coordinates, qvel = J(psi) nu and
qacc = J nu_dot + J_dot nu, so nu_dot = J^T qacc - r [-v, u, 0] (since J^T J_dot = r [[0, -1, 0],
[1, 0, 0], [0, 0, 0]]). Hence

    J (-M_A nu_dot) = -(J M_A J^T) qacc + J M_A r [-v, u, 0].

The first term moves to the left side: the callback adds J M_A J^T to MuJoCo's joint-space mass
matrix ``d.M`` and re-factors it (``mj_factorM``); the second joins the generalized passive force

    qfrc_passive += J(psi) (f_h' + M_A r [-v, u, 0]),   f_h' = d(t) + Delta - C nu - D nu + C_RB nu,

where ``d + Delta - C nu - D nu`` is :func:`usv_mj.physics.ship.hull_terms` (never re-written here).
In a sea (docs/sea.md §6; ``d.userdata[U_SEA_ON]`` = 1) that term is :func:`usv_mj.physics.sea.dynamics.sea_terms`,
``M nu_c_dot + tau_env + Delta + d - C(nu_r) nu_r - D(nu_r) nu_r``, on the four arrays of
``Environment.packed`` whose addresses and sizes the plant writes into ``d.userdata[U_SEA_*]`` (the
plant keeps the arrays alive and rewrites the addresses whenever the environment's grids grow). The
C_RB nu and exact added-mass terms are unchanged. The environment is a pure function of
(t, eta, nu), so every RK4 stage sees the sea at its own stage time and pose.
An MMG hull (KVLCC2, :mod:`usv_mj.physics.mmg`; ``ud[U_P + P_MODEL]`` = MODEL_MMG) adds the MMG's hull,
propeller and rudder force :func:`usv_mj.physics.mmg.mmg_terms` of the inputs ``d.ctrl`` = (n_P, delta) (its
motors have zero gear) on the constants at ``U_MMG``, after the layout (``N_USERDATA_MMG`` words).
MuJoCo calls the passive callback once per RK4 stage after building ``d.M`` for that stage's pose
and with ``d.time`` at the stage time, so d(t) is evaluated exactly where the analytic plant
evaluates it. d(t) is the scenario's disturbance kind: its packed vector at ``U_DP``
(:func:`usv_mj.physics.disturbances.packed_disturbance`), whose last word sends
:func:`usv_mj.physics.disturbances.disturbance_at` to the paper's kernel (0) or to the kind's cfunc.

A hull on a free joint (``d.userdata[U_LAYOUT]`` = LAYOUT_FREE, written by
:func:`usv_mj.attach_hydrodynamics`) takes the same terms on the free joint's x, y and yaw dofs
and has heave, roll and pitch held by the callback (:func:`held_free_body_terms`, docs/attach.md);
the plant's planar layout (0) is the path above, unchanged.

Everything the callback needs is read from ``(m, d)``: the parameters live in ``d.userdata``
behind a magic marker (layout ``U_*`` below), so two plants with different ships in one process do
not disturb each other, and models without the marker (a viewer's scene, another library) are left
alone. The native callback is a numba ``cfunc``; it reads mjData fields at byte offsets found once
per process by comparing the addresses of numpy views (``d.qpos.ctypes.data`` ...) with the
pointers stored in the mjData struct (:func:`struct_offsets`).

Errors: a callback cannot raise through MuJoCo (a Python exception there aborts the process), so
both callbacks record a status code in ``d.userdata[U_STATUS]`` (and the Python one keeps the
exception) and the plant raises :class:`HydrodynamicCallbackError` after the step.
"""

from __future__ import annotations

import ctypes
import functools
import math
import threading
import weakref

import mujoco

import numpy as np
from numba import carray, cfunc, njit, types

from usv_mj.physics.sea.dynamics import sea_terms
from usv_mj.physics.sea.layout import N_ENV_PARAMS, N_WAVE_COLS
from usv_mj.physics.mmg import N_MMG_PARAMS, mmg_terms
from usv_mj.physics.ship import MODEL_MMG, N_DIST_WORDS, N_SHIP_PARAMS, P_MODEL, hull_terms

from usv_mj.support.native_mujoco import (MODELS_DIR, _f64_ptr, _i64_ptr, _libmujoco,  # noqa: F401 (re-exported)
                                         call_model_data, check_offsets, mujoco_function_address, struct_offsets)

# --- d.userdata layout --------------------------------------------------------------------------
MAGIC = 6.0221e23 + 1.0e9 * math.pi  # "this mjData belongs to a usv_mj plant"
U_MAGIC = 0
U_STATUS = 1        # 0 ok; STATUS_* below
U_STATUS_TIME = 2   # d.time when the status was set [s]
U_MASS = 3          # rigid mass m [kg]
U_XG = 4            # COM offset x_g [m]
U_MA = 5            # added mass M_A, 3x3 row-major (9)
U_P = U_MA + 9      # ShipParams.as_array() (N_SHIP_PARAMS)
U_DP = U_P + N_SHIP_PARAMS  # the packed d(t), usv_mj.physics.disturbances.packed_disturbance (N_DIST_WORDS)
U_CALLS = U_DP + N_DIST_WORDS  # number of callback evaluations (diagnostic)
U_SCRATCH = U_CALLS + 1  # 15 doubles of scratch space (eta, nu, qfrc, mass_add): no allocation per call
# the sea (docs/sea.md §6): addresses and sizes of the four arrays of usv_mj.physics.sea.Environment.packed,
# stored as doubles (addresses < 2^53 are exact); U_SEA_ON = 0 takes the calm path of today
U_SEA_ON = U_SCRATCH + 15   # 1.0: call sea_terms instead of hull_terms
U_SEA_EP = U_SEA_ON + 1     # address of ep (N_ENV_PARAMS doubles)
U_SEA_WAVES = U_SEA_ON + 2  # address of waves, (N_WAVE_COLS, n) C order
U_SEA_NWAVES = U_SEA_ON + 3  # n: wave components
U_SEA_CG = U_SEA_ON + 4     # address of current_grid, (n_c, 2)
U_SEA_NCG = U_SEA_ON + 5    # n_c
U_SEA_WG = U_SEA_ON + 6     # address of wind_grid, (n_w, 1)
U_SEA_NWG = U_SEA_ON + 7    # n_w
# a free joint held to the plane (usv_mj.plants.attach, docs/attach.md): the hull's joint layout and the hold
U_LAYOUT = U_SEA_ON + 8     # LAYOUT_PLANAR (0: slide x, slide y, hinge yaw; the plant's) or LAYOUT_FREE (1)
U_HOLD = U_LAYOUT + 1       # 10: z0 [m], then (lock inertia, stiffness, damping) for heave [kg, N/m, N s/m],
#                             roll and pitch [kg m^2, N m/rad, N m s/rad] (held_free_body_terms)
U_FREE_SCRATCH = U_HOLD + 10  # 6 doubles: the planar (x, y, psi) and (x_dot, y_dot, r) read off the free joint
# several hulls in one model (a fleet, usv_mj.plants.fleet): one block of this layout per hull, each
# its own parameters; the callback walks them (0 in each: one hull, the plant's layout as it was)
U_NEXT = U_FREE_SCRATCH + 6   # words from this block to the next hull's (0: the last)
U_QADR = U_NEXT + 1           # the hull's first dof in qpos / qvel / qfrc_passive (its x, y, yaw)
U_MADR = U_NEXT + 2           # its first entry in d.M (the 6 of its dense 3x3 lower triangle)
U_CADR = U_NEXT + 3           # its first motor in ctrl (surge, yaw)
N_USERDATA = U_NEXT + 4
LAYOUT_PLANAR = 0.0
LAYOUT_FREE = 1.0
# an MMG hull (usv_mj.physics.mmg; ud[U_P + P_MODEL] = MODEL_MMG) has its N_MMG_PARAMS constants after the
# layout: a plant of such a hull has nuserdata >= N_USERDATA_MMG (the others keep N_USERDATA)
U_MMG = N_USERDATA
N_USERDATA_MMG = U_MMG + N_MMG_PARAMS

STATUS_OK = 0.0
STATUS_BAD_STATE = 1.0   # non-finite qpos/qvel at the callback
STATUS_BAD_FORCE = 2.0   # the hydrodynamic force or added mass came out non-finite
STATUS_EXCEPTION = 3.0   # the Python callback raised (the exception is kept by the plant)
STATUS_MESSAGES = {
    STATUS_BAD_STATE: "non-finite state (qpos or qvel) reached the hydrodynamic callback",
    STATUS_BAD_FORCE: "the hydrodynamic force or added-mass matrix came out non-finite",
    STATUS_EXCEPTION: "the Python hydrodynamic callback raised",
}


class HydrodynamicCallbackError(RuntimeError):
    """The passive-force callback failed during a step (raised by the plant after ``mj_step``)."""


# --- the physics, shared by the native and the Python callback ----------------------------------


@njit(cache=True)
def passive_terms(ud, t, qpos, qvel, ctrl, qfrc, mass_add):
    """Generalized hydrodynamic force and the mass-matrix increment at one RK4 stage.

    Parameters
    ----------
    ud:
        ``d.userdata`` with the layout ``U_*`` (parameters of ship, disturbance and split; with
        ``ud[U_SEA_ON]`` = 1 the addresses and sizes of the sea's packed arrays, docs/sea.md §6).
    t:
        Stage time [s]. ``qpos`` = (x, y, psi) [m, m, rad], ``qvel`` = (x_dot, y_dot, r) (world).
    ctrl:
        ``d.ctrl``: read only for an MMG hull (``ud[U_P + P_MODEL]`` = MODEL_MMG), whose motors have
        no gear and whose inputs are ctrl = (n_P [1/s], delta [rad]): the MMG's hull, propeller and
        rudder force :func:`usv_mj.physics.mmg.mmg_terms` (the analytic plant's, from the same kernel) is
        added to the hull force.
    qfrc:
        Output, 3: J(psi) (f_h' + M_A r [-v, u, 0]) [N, N, N m] (to add to ``qfrc_passive``).
    mass_add:
        Output, 6: J M_A J^T as the dense lower triangle (M00, M10, M11, M20, M21, M22).

    Returns a status code (``STATUS_OK`` or ``STATUS_BAD_*``); on error the outputs are zero.
    """
    for i in range(3):
        qfrc[i] = 0.0
    for i in range(6):
        mass_add[i] = 0.0
    psi = qpos[2]
    if not (math.isfinite(qpos[0]) and math.isfinite(qpos[1]) and math.isfinite(psi)
            and math.isfinite(qvel[0]) and math.isfinite(qvel[1]) and math.isfinite(qvel[2])):
        return STATUS_BAD_STATE
    c, s = math.cos(psi), math.sin(psi)
    eta = ud[U_SCRATCH:U_SCRATCH + 3]  # views into d.userdata: no heap allocation per call
    nu = ud[U_SCRATCH + 3:U_SCRATCH + 6]
    eta[0], eta[1], eta[2] = qpos[0], qpos[1], psi
    u = c * qvel[0] + s * qvel[1]
    v = -s * qvel[0] + c * qvel[1]
    r = qvel[2]
    nu[0], nu[1], nu[2] = u, v, r
    p = ud[U_P:U_P + N_SHIP_PARAMS]
    dp = ud[U_DP:U_DP + N_DIST_WORDS]
    if ud[U_SEA_ON] != 0.0:
        # docs/sea.md §6: M nu_c_dot + tau_env + Delta + d - C(nu_r) nu_r - D(nu_r) nu_r
        ep = carray(_f64_ptr(np.int64(ud[U_SEA_EP])), (N_ENV_PARAMS,))
        waves = carray(_f64_ptr(np.int64(ud[U_SEA_WAVES])), (N_WAVE_COLS, np.int64(ud[U_SEA_NWAVES])))
        cgrid = carray(_f64_ptr(np.int64(ud[U_SEA_CG])), (np.int64(ud[U_SEA_NCG]), 2))
        wgrid = carray(_f64_ptr(np.int64(ud[U_SEA_WG])), (np.int64(ud[U_SEA_NWG]), 1))
        f = sea_terms(p, dp, ep, waves, cgrid, wgrid, t, eta, nu)
    else:
        f = hull_terms(p, dp, t, eta, nu, nu)  # d + Delta - C nu - D nu (docs/model.md §1)
    if p[P_MODEL] == MODEL_MMG:
        if ud.shape[0] < N_USERDATA_MMG or not (math.isfinite(ctrl[0]) and math.isfinite(ctrl[1])):
            return STATUS_BAD_FORCE
        g0, g1, g2 = mmg_terms(ud, U_MMG, u, v, r, ctrl[0], ctrl[1])
        f = (f[0] + g0, f[1] + g1, f[2] + g2)
    m = ud[U_MASS]
    mxg = m * ud[U_XG]
    # + C_RB nu: MuJoCo's rigid body already produces it, so C_A nu = C nu - C_RB nu
    f0 = f[0] - m * v * r - mxg * r * r
    f1 = f[1] + m * u * r
    f2 = f[2] + mxg * u * r
    # + M_A r [-v, u, 0]: the J_dot nu part of -M_A nu_dot
    w0 = -r * v
    w1 = r * u
    a00, a01 = ud[U_MA], ud[U_MA + 1]
    a10, a11 = ud[U_MA + 3], ud[U_MA + 4]
    a20, a21, a22 = ud[U_MA + 6], ud[U_MA + 7], ud[U_MA + 8]
    f0 += a00 * w0 + a01 * w1
    f1 += a10 * w0 + a11 * w1
    f2 += a20 * w0 + a21 * w1
    q0 = c * f0 - s * f1
    q1 = s * f0 + c * f1
    q2 = f2
    # J M_A J^T with J = [[c, -s, 0], [s, c, 0], [0, 0, 1]]: first J M_A (rows), then times J^T
    jm00, jm01 = c * a00 - s * a10, c * a01 - s * a11
    jm10, jm11 = s * a00 + c * a10, s * a01 + c * a11
    m00 = c * jm00 - s * jm01
    m10 = c * jm10 - s * jm11
    m11 = s * jm10 + c * jm11
    m20 = c * a20 - s * a21
    m21 = s * a20 + c * a21
    m22 = a22
    if not (math.isfinite(q0) and math.isfinite(q1) and math.isfinite(q2) and math.isfinite(m00)
            and math.isfinite(m10) and math.isfinite(m11) and math.isfinite(m20) and math.isfinite(m21)
            and math.isfinite(m22)):
        return STATUS_BAD_FORCE
    qfrc[0], qfrc[1], qfrc[2] = q0, q1, q2
    mass_add[0], mass_add[1], mass_add[2] = m00, m10, m11
    mass_add[3], mass_add[4], mass_add[5] = m20, m21, m22
    return STATUS_OK


# --- a free joint held to the plane -------------------------------------------------------------

# d.M of a free joint (dense 6x6 lower triangle, rows at 0, 1, 3, 6, 10, 15): the planar entries
# (x, y, yaw) = dofs (0, 1, 5) in passive_terms' order M00, M10, M11, M20, M21, M22, and the held diagonal
FREE_M_PLANAR = (0, 1, 2, 15, 16, 20)
FREE_M_HELD = (5, 9, 14)  # z, roll (body x), pitch (body y)


@njit(cache=True)
def held_free_body_terms(ud, t, qpos, qvel, qfrc, mass):
    """The hydrodynamics of a hull on a free joint, held to the plane (docs/attach.md).

    ``qpos`` (7: x, y, z, quaternion w, x, y, z), ``qvel`` (6: the world-frame velocity of the body
    origin, then the body-frame angular velocity), ``qfrc`` (6, d.qfrc_passive) and ``mass`` (21,
    d.M, dense) of the free joint. In the plane the free joint's dofs (0, 1, 5) are the planar
    joints' (x, y, yaw): psi from the quaternion, r the body-frame yaw rate, so :func:`passive_terms`
    gives their force and added mass. Heave, roll and pitch are held (``ud[U_HOLD:]``): each gets a
    lock inertia K on its diagonal of d.M and a spring-damper -k e - c e_dot, where e is the height
    above z0 for heave and, for roll and pitch, the body-frame components of the rotation vector
    that levels the hull. Adds to ``qfrc`` and ``mass`` only when every term is finite; returns the
    status (``STATUS_*``).
    """
    w, qx, qy, qz = qpos[3], qpos[4], qpos[5], qpos[6]
    norm2 = w * w + qx * qx + qy * qy + qz * qz
    if not (norm2 > 0.0 and math.isfinite(norm2) and math.isfinite(qpos[2]) and math.isfinite(qvel[2])
            and math.isfinite(qvel[3]) and math.isfinite(qvel[4])):
        return STATUS_BAD_STATE
    s2 = 2.0 / norm2
    plan = ud[U_FREE_SCRATCH:U_FREE_SCRATCH + 3]
    pvel = ud[U_FREE_SCRATCH + 3:U_FREE_SCRATCH + 6]
    plan[0], plan[1] = qpos[0], qpos[1]
    plan[2] = math.atan2(s2 * (w * qz + qx * qy), 1.0 - s2 * (qy * qy + qz * qz))
    pvel[0], pvel[1], pvel[2] = qvel[0], qvel[1], qvel[5]
    qf = ud[U_SCRATCH + 6:U_SCRATCH + 9]
    ma = ud[U_SCRATCH + 9:U_SCRATCH + 15]
    # ctrl is read only for an MMG hull, which the attach call refuses on a free body: pvel stands in
    status = passive_terms(ud, t, plan, pvel, pvel, qf, ma)
    if status != STATUS_OK:
        return status
    # world up in the body frame (the third row of R): the hull is level when it is (0, 0, 1)
    n0 = s2 * (qx * qz - w * qy)
    n1 = s2 * (qy * qz + w * qx)
    n2 = 1.0 - s2 * (qx * qx + qy * qy)
    sin_tilt = math.sqrt(n0 * n0 + n1 * n1)
    per_sin = math.atan2(sin_tilt, n2) / sin_tilt if sin_tilt > 0.0 else 1.0
    h = ud[U_HOLD:U_HOLD + 10]
    f_z = -h[2] * (qpos[2] - h[0]) - h[3] * qvel[2]
    f_roll = -h[5] * per_sin * n1 - h[6] * qvel[3]
    f_pitch = h[8] * per_sin * n0 - h[9] * qvel[4]
    if not (math.isfinite(f_z) and math.isfinite(f_roll) and math.isfinite(f_pitch)):
        return STATUS_BAD_FORCE
    qfrc[0] += qf[0]
    qfrc[1] += qf[1]
    qfrc[5] += qf[2]
    qfrc[2] += f_z
    qfrc[3] += f_roll
    qfrc[4] += f_pitch
    for i in range(6):
        mass[FREE_M_PLANAR[i]] += ma[i]
    mass[FREE_M_HELD[0]] += h[1]
    mass[FREE_M_HELD[1]] += h[4]
    mass[FREE_M_HELD[2]] += h[7]
    return STATUS_OK


# --- native callback ----------------------------------------------------------------------------


@njit(cache=True)
def record_call(ud, status, t):
    """Count one callback evaluation in ``ud[U_CALLS]`` and keep the first failure (``status`` !=
    STATUS_OK) with its time in ``ud[U_STATUS]`` / ``ud[U_STATUS_TIME]``; True when the call
    succeeded (its force and mass may be applied). Every callback path records through it."""
    ud[U_CALLS] += 1.0
    if status == STATUS_OK:
        return True
    if ud[U_STATUS] == 0.0:
        ud[U_STATUS] = status
        ud[U_STATUS_TIME] = t
    return False


_NATIVE = None


def native_callback():
    """The numba ``cfunc`` passive callback (built once per process; see the module docstring)."""
    global _NATIVE
    if _NATIVE is not None:
        return _NATIVE
    off = struct_offsets()
    lib = _libmujoco()
    factor_m = lib.mj_factorM
    factor_m.argtypes = (ctypes.c_int64, ctypes.c_int64)  # (const mjModel*, mjData*) as addresses
    factor_m.restype = None
    o_time, o_qpos, o_qvel = off["time"] // 8, off["qpos"] // 8, off["qvel"] // 8
    o_m, o_frc, o_ud = off["M"] // 8, off["qfrc_passive"] // 8, off["userdata"] // 8
    o_nud = off["nuserdata"] // 8
    o_ctrl = off["ctrl"] // 8
    n_ud, magic = N_USERDATA, MAGIC
    u_scratch = U_SCRATCH
    u_layout = U_LAYOUT
    u_next, u_qadr, u_madr, u_cadr = U_NEXT, U_QADR, U_MADR, U_CADR

    @cfunc(types.void(types.int64, types.int64), error_model="numpy")
    def hydrodynamic_passive(m_addr, d_addr):
        mw = carray(_i64_ptr(m_addr), (o_nud + 1,))
        if mw[o_nud] < n_ud:
            return
        dw = carray(_i64_ptr(d_addr), (o_ud + 1,))
        ud = carray(_f64_ptr(dw[o_ud]), (mw[o_nud],))
        if ud[0] != magic:
            return
        dd = carray(_f64_ptr(d_addr), (o_time + 1,))
        t = dd[o_time]
        if ud[u_layout] != 0.0:  # a free joint held to the plane (held_free_body_terms)
            status = held_free_body_terms(ud, t, carray(_f64_ptr(dw[o_qpos]), (7,)), carray(_f64_ptr(dw[o_qvel]), (6,)),
                                          carray(_f64_ptr(dw[o_frc]), (6,)), carray(_f64_ptr(dw[o_m]), (21,)))
            if record_call(ud, status, t):
                factor_m(m_addr, d_addr)
            return
        added = False
        base = 0
        while True:   # one block per hull (U_NEXT: a fleet's next; 0 in the last, the single hull's)
            blk = ud[base:]
            qa, ma_, ca = np.int64(blk[u_qadr]), np.int64(blk[u_madr]), np.int64(blk[u_cadr])
            qpos = carray(_f64_ptr(dw[o_qpos] + 8 * qa), (3,))
            qvel = carray(_f64_ptr(dw[o_qvel] + 8 * qa), (3,))
            frc = carray(_f64_ptr(dw[o_frc] + 8 * qa), (3,))
            mm = carray(_f64_ptr(dw[o_m] + 8 * ma_), (6,))
            ctrl = carray(_f64_ptr(dw[o_ctrl] + 8 * ca), (2,))
            qf = blk[u_scratch + 6:u_scratch + 9]
            ma = blk[u_scratch + 9:u_scratch + 15]
            if record_call(blk, passive_terms(blk, t, qpos, qvel, ctrl, qf, ma), t):
                for i in range(3):
                    frc[i] += qf[i]
                for i in range(6):
                    mm[i] += ma[i]
                added = True
            nxt = np.int64(blk[u_next])
            if nxt <= 0 or base + nxt + n_ud > ud.shape[0] or ud[base + nxt] != magic:
                break
            base += nxt
        if added:
            factor_m(m_addr, d_addr)

    _NATIVE = hydrodynamic_passive
    return _NATIVE


@njit(cache=True)
def plant_state(qpos, qvel):
    """(x, y, psi, u, v, r) from the joints: qvel holds the world-frame (x_dot, y_dot, r); the body
    velocities are that rotated by -psi (the one place the plant's state is read off MuJoCo)."""
    psi = qpos[2]
    c, s = math.cos(psi), math.sin(psi)
    out = np.empty(6)
    out[0], out[1], out[2] = qpos[0], qpos[1], psi
    out[3] = c * qvel[0] + s * qvel[1]
    out[4] = -s * qvel[0] + c * qvel[1]
    out[5] = qvel[2]
    return out


@njit(cache=True)
def mujoco_kernel(k, x, f_u, f_r, m_addr, d_addr, t0, dt, nsub, o_time, o_qpos, o_qvel, o_ctrl, o_ud, n_words,
                  mj_step_address):
    """:meth:`MuJoCoPlant.step` natively (usv_mj.core.kernels): the k-th step, from t0 + k dt.

    Writes the thrust into ``ctrl``, sets ``d.time``, calls ``mj_step`` ``nsub`` times (at
    ``mj_step_address``) and returns the new state (x, y, psi, u, v, r) and whether the callback
    recorded a failure or MuJoCo reset the data (time not advanced). Field offsets are words
    (:func:`struct_offsets` // 8)."""
    t = t0 + k * dt
    dd = carray(_f64_ptr(d_addr), (o_time + 1,))
    dw = carray(_i64_ptr(d_addr), (n_words,))
    ctrl = carray(_f64_ptr(dw[o_ctrl]), (2,))
    ctrl[0] = f_u
    ctrl[1] = f_r
    dd[o_time] = t
    for _ in range(nsub):
        call_model_data(mj_step_address, m_addr, d_addr)
    ud = carray(_f64_ptr(dw[o_ud]), (N_USERDATA,))
    out = plant_state(carray(_f64_ptr(dw[o_qpos]), (3,)), carray(_f64_ptr(dw[o_qvel]), (3,)))
    failed = ud[U_STATUS] != 0.0 or not dd[o_time] > t
    return out, failed


@functools.cache
def kernel_constants() -> tuple:
    """The trailing arguments of :func:`mujoco_kernel`: (o_time, o_qpos, o_qvel, o_ctrl, o_ud,
    n_words, address of mj_step) for this process's libmujoco (found once per process: the
    compiled loop asks every block)."""
    off = struct_offsets()
    words = tuple(off[name] // 8 for name in ("time", "qpos", "qvel", "ctrl", "userdata"))
    return words + (max(words[1:]) + 1, mujoco_function_address("mj_step"))


# --- which callback MuJoCo's global mjcb_passive holds -------------------------------------------

class _CallbackRegistry:
    """Which plants are alive, and which callback MuJoCo's global ``mjcb_passive`` holds."""

    def __init__(self):
        self.lock = threading.Lock()
        self.live: dict[int, weakref.ref] = {}        # id(plant) -> plant
        self.python: dict[int, weakref.ref] = {}      # mjData address -> python-mode plant
        self.previous = None
        self.installed = None                          # "native" | "python" | None

    def _dispatch(self, m, d):
        """The Python passive callback: never lets an exception reach MuJoCo (it would abort)."""
        ref = self.python.get(d._address)
        plant = ref() if ref is not None else None
        if plant is None:
            native = native_callback()
            native.ctypes(m._address, d._address)
            return
        plant._python_passive(m, d)

    def _update(self):
        want = "python" if self.python else ("native" if self.live else None)
        if want == self.installed:
            return
        if self.installed is None:
            self.previous = mujoco.get_mjcb_passive()
        if want is None:
            mujoco.set_mjcb_passive(self.previous)
            self.previous = None
        elif want == "native":
            mujoco.set_mjcb_passive(native_callback().ctypes)
        else:
            mujoco.set_mjcb_passive(self._dispatch)
        self.installed = want

    def add(self, plant) -> None:
        with self.lock:
            self.live[id(plant)] = weakref.ref(plant)
            if plant.callback == "python":
                self.python[plant.data._address] = weakref.ref(plant)
            self._update()

    def remove(self, plant_id: int, data_address: int) -> None:
        with self.lock:
            self.live.pop(plant_id, None)
            self.python.pop(data_address, None)
            self._update()


CALLBACKS = _CallbackRegistry()


def installed_callback() -> str | None:
    """Which passive callback usv_mj has installed: "native", "python" or None (none of ours)."""
    return CALLBACKS.installed
