"""The paper's 3-DOF ship: mass, Coriolis, damping, uncertainty and disturbance, written once.

Every formula of the hull lives here (docs/model.md §1, paper Eqs. 1-2, 6-7 and 28). The analytic plant, the
MuJoCo passive-force callback and the PPC controller's nominal model all call these functions, so a
change of the physics is a change in this one file. The other vessels (usv_mj.vessels,
docs/vessels.md) are written onto the same packed layout; the two terms they add, C(nu)'s own masses
and the cross-flow drag, are the paper ship's m11, m22, m23 and zero. A ruddered ship of the MMG
standard method (:mod:`usv_mj.physics.mmg`, KVLCC2) sets the model switch ``P_MODEL``: its inputs are then
(n_P, delta) and :func:`derivative_into` adds the MMG's force (:class:`MMGShipParams`; 0, the
switch of every other hull, leaves their numbers as they were).

Conventions
-----------
The README's Conventions: world x east, y north, z up; heading psi counter-clockwise from +x (east);
body x forward, y to port, z up, so positive v is to port and positive r turns to port.

- ``eta = (x, y, psi)``: position (m) and heading (rad) in the world frame.
- ``nu = (u, v, r)``: surge (m/s), sway (m/s, positive to port) and yaw rate (rad/s, positive to port)
  in the body frame.
- Forces are body-frame generalized forces ``(X [N], Y [N], N [N m])``.

The paper writes the same equations in the marine NED frame (x north, y east, z down, body y to
starboard). The mirror y -> -y, psi -> -psi, v -> -v, r -> -r, tau_r -> -tau_r leaves M, C(nu) and
D(nu) below unchanged (m23 and the |v|, |r| damping terms included), so the printed numbers are used
as they stand; only Delta's even sway/yaw terms, d(t)'s sway/yaw components and the sense of the
reference's turn are mirrored (README, Conventions; tests/test_conventions.py).

The kernels are ``numba.njit`` functions over a packed ``float64`` parameter vector (see
:meth:`ShipParams.as_array` and the ``P_*`` indices), so that a native callback can call them with no
Python in the loop. They are plain functions and work from Python too.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numba import njit, vectorize

from usv_mj.physics.mmg import N_MMG_PARAMS, mmg_terms
# d(t): the disturbance kinds and the one dispatch live in usv_mj.physics.disturbances (re-exported here)
from usv_mj.physics.disturbances import (D_AMP, D_KERNEL, D_MAX_WORDS, D_SCALE, D_WCOS, D_WSIN,  # noqa: F401
                                         N_DIST_PARAMS, N_DIST_WORDS, Disturbance, PaperDisturbance,
                                         disturbance_at, disturbance_terms, packed_disturbance)

# --- packed parameter layout --------------------------------------------------------------------
P_M11, P_M22, P_M23, P_M33 = 0, 1, 2, 3
P_D11 = 4  # 3 coefficients: c0 + c1 |u| + c2 u^2
P_D22 = 7  # c0 + c1 |v| + c2 |r|
P_D23 = 10
P_D32 = 13
P_D33 = 16
P_UNCERTAINTY = 19  # scale of Delta (1 = the paper's Delta, 0 = none)
# the masses of C(nu) (c13 = -mc22 v - mc23 r, c23 = mc11 u): m11, m22, m23 unless a vessel says
# otherwise (a linear manoeuvring model whose derivatives hold the added mass's Coriolis: C_RB only)
P_C11, P_C22, P_C23 = 20, 21, 22
# cross-flow drag (Fossen 2021, §6.7; the Otter's): 0.5 rho T C_d [kg/m^2], hull length [m], strips
P_CF, P_CF_L, P_CF_N = 23, 24, 25
# the model switch (0: the force model above, the thrust channels are (tau_u [N], tau_r [N m]);
# 1: the MMG standard method of usv_mj.physics.mmg, the channels are (n_P [1/s], delta [rad]) and the
# force is usv_mj.physics.mmg.mmg_terms, whose parameters follow the N_SHIP_PARAMS words: P_MMG)
P_MODEL = 26
MODEL_FORCES, MODEL_MMG = 0.0, 1.0
N_SHIP_PARAMS = 27
P_MMG = N_SHIP_PARAMS  # MMGShipParams.as_array(): the N_MMG_PARAMS words of usv_mj.physics.mmg after the layout

# the disturbance d(t) (usv_mj.physics.disturbances): the packed vector dp of N_DIST_WORDS words (a kind's
# as_array(), then the dispatch word D_KERNEL), the paper's own words D_SCALE, D_AMP, D_WCOS, D_WSIN


@dataclass(frozen=True)
class ShipParams:
    """Total (rigid-body + added) mass and damping of the paper's ship (docs/model.md §1).

    Attributes
    ----------
    m11, m22, m23, m33:
        Entries of the total mass matrix M [kg, kg, kg m, kg m^2]. m23 = m32 is not printed in the
        paper; it is read off c13 = -m22 v - m23 r (docs/model.md §1).
    d11, d22, d23, d32, d33:
        Damping coefficients ``(c0, c1, c2)``: d11 = c0 + c1|u| + c2 u^2 and
        d_ij = c0 + c1|v| + c2|r| for the others [N s/m, N s^2/m^2, ...].
    uncertainty_scale:
        Multiplies the model uncertainty Delta(eta, nu) = [0.6, 0.2 u^2, sin v + 0.15 r^2] (1 = paper).
    coriolis_masses:
        (mc11, mc22, mc23) [kg, kg, kg m], the masses of C(nu): c13 = -mc22 v - mc23 r, c23 = mc11 u.
        None (default): (m11, m22, m23), i.e. C = C_RB + C_A with the Munk moment. A linear
        manoeuvring model whose damping derivatives already hold the added mass's Coriolis terms
        (Clarke 1983) gives the rigid body's (m, m, m x_g): C = C_RB.
    crossflow:
        (k [kg/m^2], L [m], n) of the cross-flow drag (Fossen 2021, §6.7, as the Otter's
        ``crossFlowDrag``): Y = -k sum_i |v + x_i r| (v + x_i r) dx, N = -k sum_i x_i |.| (.) dx over
        the n + 1 points x_i = -L/2 + i dx, dx = L/n, with k = 0.5 rho T C_d(B/2T). k = 0: none (paper).
    """

    m11: float = 141.85
    m22: float = 191.75
    m23: float = 5.7
    m33: float = 15.6
    d11: tuple[float, float, float] = (45.6, 67.26, 10.0)
    d22: tuple[float, float, float] = (29.54, 73.85, 15.0)
    d23: tuple[float, float, float] = (-2.5, 2.0, 10.71)
    d32: tuple[float, float, float] = (-2.4, -13.0, -0.2)
    d33: tuple[float, float, float] = (5.59, -0.07, 10.71)
    uncertainty_scale: float = 1.0
    coriolis_masses: tuple[float, float, float] | None = None
    crossflow: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("m11", "m22", "m33"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ship.{name} must be a positive mass, got {value!r}")
        if self.m22 * self.m33 - self.m23**2 <= 0:
            raise ValueError(
                f"ship: the mass matrix is not positive definite (m22 m33 - m23^2 = "
                f"{self.m22 * self.m33 - self.m23**2:g} <= 0)"
            )
        for name in ("d11", "d22", "d23", "d32", "d33"):
            value = tuple(getattr(self, name))
            if len(value) != 3 or not all(math.isfinite(c) for c in value):
                raise ValueError(f"ship.{name} must be three finite coefficients, got {value!r}")
        if self.coriolis_masses is not None:
            value = self.coriolis_masses
            if not (isinstance(value, (list, tuple)) and len(value) == 3
                    and all(isinstance(c, (int, float)) and math.isfinite(c) for c in value)):
                raise ValueError(f"ship.coriolis_masses must be three finite masses or none, got {value!r}")
            object.__setattr__(self, "coriolis_masses", tuple(float(c) for c in value))
        cf = self.crossflow
        if not (isinstance(cf, (list, tuple)) and len(cf) == 3
                and all(isinstance(c, (int, float)) and math.isfinite(c) for c in cf)
                and cf[0] >= 0 and (cf[0] == 0 or (cf[1] > 0 and cf[2] >= 1 and cf[2] == int(cf[2])))):
            raise ValueError(f"ship.crossflow must be (k >= 0 kg/m^2, L > 0 m, strips >= 1) or (0, 0, 0), "
                             f"got {cf!r}")
        object.__setattr__(self, "crossflow", tuple(float(c) for c in self.crossflow))

    @property
    def eps(self) -> float:
        """Do & Pan's offset of the controlled point, eps = m23/m22 [m] (:func:`do_pan_offset`)."""
        return do_pan_offset(self.m22, self.m23)

    #: the plant's input channels are the generalized forces (tau_u [N], tau_r [N m]) themselves;
    #: False: the hull makes its force from them (MMGShipParams: n_P and the rudder angle)
    inputs_are_forces = True
    #: the hull's model holds in calm water only (MMGShipParams: the MMG standard method's)
    calm_water_only = False

    def as_array(self) -> np.ndarray:
        """Pack into the float64 vector that the kernels of this module take."""
        p = np.zeros(N_SHIP_PARAMS)
        p[P_M11], p[P_M22], p[P_M23], p[P_M33] = self.m11, self.m22, self.m23, self.m33
        for start, name in ((P_D11, "d11"), (P_D22, "d22"), (P_D23, "d23"), (P_D32, "d32"), (P_D33, "d33")):
            p[start : start + 3] = getattr(self, name)
        p[P_UNCERTAINTY] = self.uncertainty_scale
        p[P_C11], p[P_C22], p[P_C23] = self.coriolis_masses or (self.m11, self.m22, self.m23)
        p[P_CF], p[P_CF_L], p[P_CF_N] = self.crossflow
        return p

    def scaled(self, factor: float) -> "ShipParams":
        """The same hull with every mass, Coriolis mass, damping and cross-flow coefficient times
        ``factor`` (> 0): a controller's nominal model that is wrong by that factor
        (``[vessel] model_mismatch``); 1 gives this very object."""
        if factor == 1.0:
            return self
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"vessel.model_mismatch must be a number > 0, got {factor!r}")
        f = float(factor)
        k, length, n = self.crossflow
        return dataclasses.replace(
            self, m11=f * self.m11, m22=f * self.m22, m23=f * self.m23, m33=f * self.m33,
            **{name: tuple(f * c for c in getattr(self, name)) for name in ("d11", "d22", "d23", "d32", "d33")},
            coriolis_masses=None if self.coriolis_masses is None else tuple(f * c for c in self.coriolis_masses),
            crossflow=(f * k, length, n))

    def mass_matrix(self) -> np.ndarray:
        return mass_matrix(self.as_array())


@dataclass(frozen=True)
class MMGShipParams(ShipParams):
    """A hull whose forces are the MMG standard method's (:mod:`usv_mj.physics.mmg`; usv_mj.vessels.kvlcc2).

    The inherited masses are the MMG's M (m11 = m + m_x, m22 = m + m_y, m23 = x_G m,
    m33 = I_zG + x_G^2 m + J_z); damping, C(nu)'s masses, cross-flow and Delta are zero (the MMG
    force holds them all). ``mmg``: the :data:`usv_mj.physics.mmg.N_MMG_PARAMS` packed constants of the
    MMG block (usv_mj.vessels.kvlcc2.pack). The plants' input channels are (n_P [1/s], delta [rad]).
    """

    mmg: tuple = ()

    inputs_are_forces = False
    calm_water_only = True

    def __post_init__(self) -> None:
        super().__post_init__()
        if len(self.mmg) != N_MMG_PARAMS or not all(math.isfinite(c) for c in self.mmg):
            raise ValueError(f"ship.mmg must be {N_MMG_PARAMS} finite numbers, got {len(self.mmg)}")
        object.__setattr__(self, "mmg", tuple(float(c) for c in self.mmg))

    def as_array(self) -> np.ndarray:
        """The layout's N_SHIP_PARAMS words (P_MODEL = MODEL_MMG) followed by the MMG block (P_MMG)."""
        p = np.zeros(N_SHIP_PARAMS + N_MMG_PARAMS)
        p[:N_SHIP_PARAMS] = super().as_array()
        p[P_MODEL] = MODEL_MMG
        p[P_MMG:] = self.mmg
        return p


def is_mmg(ship) -> bool:
    """True for a hull whose input channels are (n_P, delta) (:class:`MMGShipParams`)."""
    return isinstance(ship, MMGShipParams)


@dataclass(frozen=True)
class RigidBodySplit:
    """How the total mass of :class:`ShipParams` is split between rigid body and added mass.

    MuJoCo carries the rigid body (mass, COM offset, yaw inertia); the passive-force callback carries
    only the added mass M_A and the hydrodynamic forces. The default split (docs/model.md §1) puts everything
    that can be rigid into the rigid body: m = m11 (X_udot = 0), x_g = m23/m (Y_rdot = 0),
    I_z about the joint origin = m33 (N_rdot = 0), and the added mass a22 = m22 - m11 in sway.
    A different split must give the same motion; ``added_mass_fraction_surge`` moves part of m11
    into added mass to check that.

    A vessel that knows its own rigid body (usv_mj.vessels: m, x_g, I_z of its source) gives it as
    ``rigid``; the added mass is then M - M_RB of that body, as its source's M_A.

    Attributes
    ----------
    added_mass_fraction_surge:
        Fraction of m11 that is added mass (X_udot = -fraction m11); 0 by default.
    rigid:
        None (the default split above), or the rigid body (m [kg], x_g [m] ahead of the origin,
        I_z about the origin [kg m^2]).
    """

    added_mass_fraction_surge: float = 0.0
    rigid: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if not 0.0 <= self.added_mass_fraction_surge < 1.0:
            raise ValueError(
                f"split.added_mass_fraction_surge must be in [0, 1), got {self.added_mass_fraction_surge!r}"
            )
        if self.rigid is not None:
            m, x_g, iz = self.rigid
            if not (all(math.isfinite(c) for c in self.rigid) and m > 0 and iz - m * x_g * x_g > 0):
                raise ValueError(f"split.rigid must be (m > 0 kg, x_g m, I_z > m x_g^2 kg m^2), got {self.rigid!r}")
            if self.added_mass_fraction_surge != 0.0:
                raise ValueError("split: give either rigid or added_mass_fraction_surge, not both")

    def rigid_body(self, ship: ShipParams) -> tuple[float, float, float]:
        """Rigid mass m [kg], COM offset x_g [m] ahead of the origin and I_z about the origin [kg m^2]."""
        if self.rigid is not None:
            return tuple(float(c) for c in self.rigid)
        m = ship.m11 * (1.0 - self.added_mass_fraction_surge)
        x_g = ship.m23 / m
        iz_origin = ship.m33
        return m, x_g, iz_origin

    def added_mass(self, ship: ShipParams) -> np.ndarray:
        """Added mass matrix M_A = M - M_RB (body frame, 3x3) [kg, kg m, kg m^2]."""
        m, x_g, iz = self.rigid_body(ship)
        m_rb = np.array([[m, 0.0, 0.0], [0.0, m, m * x_g], [0.0, m * x_g, iz]])
        return mass_matrix(ship.as_array()) - m_rb


# --- kernels -----------------------------------------------------------------------------------


@njit(cache=True)
def do_pan_offset(m22, m23):
    """Do & Pan's offset of the controlled point ahead of the origin, eps = m23/m22 [m] (docs/model.md §1).

    The one definition: :attr:`ShipParams.eps`, the controllers' kernels (``eps`` from the nominal
    model's packed vector) and the planner all take it from here."""
    return m23 / m22


@njit(cache=True)
def coriolis_terms(p, nu):
    """c13 = -m22 v - m23 r and c23 = m11 u of C(nu) = C_RB + C_A (docs/model.md §1; c13 uses m22, not m11).

    C is skew-symmetric with only these two free entries: c31 = -c13, c32 = -c23. The masses are
    the packed Coriolis masses (P_C11, P_C22, P_C23: m11, m22, m23 unless the vessel says otherwise)."""
    return -p[P_C22] * nu[1] - p[P_C23] * nu[2], p[P_C11] * nu[0]


@njit(cache=True)
def damping_coefficients(p, nu):
    """d11, d22, d23, d32, d33 at the body velocity nu (docs/model.md §1 table)."""
    au, av, ar = abs(nu[0]), abs(nu[1]), abs(nu[2])
    d11 = p[P_D11] + p[P_D11 + 1] * au + p[P_D11 + 2] * nu[0] * nu[0]
    d22 = p[P_D22] + p[P_D22 + 1] * av + p[P_D22 + 2] * ar
    d23 = p[P_D23] + p[P_D23 + 1] * av + p[P_D23 + 2] * ar
    d32 = p[P_D32] + p[P_D32 + 1] * av + p[P_D32 + 2] * ar
    d33 = p[P_D33] + p[P_D33 + 1] * av + p[P_D33 + 2] * ar
    return d11, d22, d23, d32, d33


@njit(cache=True)
def mass_matrix(p):
    """Total mass matrix M (Eq. 2) [kg, kg m, kg m^2]."""
    out = np.zeros((3, 3))
    out[0, 0] = p[P_M11]
    out[1, 1] = p[P_M22]
    out[1, 2] = p[P_M23]
    out[2, 1] = p[P_M23]
    out[2, 2] = p[P_M33]
    return out


@njit(cache=True)
def coriolis_matrix(p, nu):
    """Total Coriolis-centripetal matrix C(nu) = C_RB + C_A (docs/model.md §1) from :func:`coriolis_terms`."""
    c13, c23 = coriolis_terms(p, nu)
    out = np.zeros((3, 3))
    out[0, 2] = c13
    out[1, 2] = c23
    out[2, 0] = -c13
    out[2, 1] = -c23
    return out


@njit(cache=True)
def damping_matrix(p, nu):
    """Nonlinear damping matrix D(nu) (docs/model.md §1) [N s/m ...]."""
    d11, d22, d23, d32, d33 = damping_coefficients(p, nu)
    out = np.zeros((3, 3))
    out[0, 0] = d11
    out[1, 1] = d22
    out[1, 2] = d23
    out[2, 1] = d32
    out[2, 2] = d33
    return out


@njit(cache=True)
def array3(f):
    """A 3-tuple as a new array (the array-returning faces of the tuple kernels below)."""
    out = np.empty(3)
    out[0], out[1], out[2] = f[0], f[1], f[2]
    return out


# The kernels on the hot path return 3-tuples (values in registers, no heap allocation: an RK4 step
# calls them four times); each has an array-returning face for Python and the tests.

@njit(cache=True)
def uncertainty_terms(p, eta, nu):
    """Model uncertainty Delta(eta, nu) = s [0.6, 0.2 u^2, sin v + 0.15 r^2] (Sec. 4), body frame, a 3-tuple."""
    s = p[P_UNCERTAINTY]
    return s * 0.6, s * 0.2 * nu[0] * nu[0], s * (math.sin(nu[1]) + 0.15 * nu[2] * nu[2])


@njit(cache=True)
def uncertainty_force(p, eta, nu):
    """:func:`uncertainty_terms` as an array."""
    return array3(uncertainty_terms(p, eta, nu))


@njit(cache=True)
def disturbance_force(dp, t):
    """d(t) of the packed vector ``dp`` (:func:`usv_mj.physics.disturbances.disturbance_at`: any
    kind's) as an array, body frame [N, N, N m]."""
    return array3(disturbance_at(dp, t))


@njit(cache=True)
def coriolis_damping_terms(p, nu):
    """C(nu) nu + D(nu) nu in the body frame, written out (no matrix products), a 3-tuple."""
    u, v, r = nu[0], nu[1], nu[2]
    d11, d22, d23, d32, d33 = damping_coefficients(p, nu)
    c13, c23 = coriolis_terms(p, nu)
    f0, f1, f2 = c13 * r + d11 * u, c23 * r + d22 * v + d23 * r, -c13 * u - c23 * v + d32 * v + d33 * r
    if p[P_CF] != 0.0:  # cross-flow drag (the paper's ship has none: its numbers are untouched)
        y, n = crossflow_terms(p, v, r)
        f1 -= y
        f2 -= n
    return f0, f1, f2


@njit(cache=True)
def crossflow_terms(p, v, r):
    """The cross-flow drag (Y [N], N [N m]) of :attr:`ShipParams.crossflow`: the strip sum of Fossen
    (2021, §6.7) over n + 1 points x_i = -L/2 + i L/n, each of width dx = L/n,
    Y = -k sum |v + x_i r| (v + x_i r) dx, N = -k sum x_i |v + x_i r| (v + x_i r) dx."""
    k, length, n = p[P_CF], p[P_CF_L], int(p[P_CF_N])
    dx = length / n
    y = 0.0
    m = 0.0
    for i in range(n + 1):
        x = -0.5 * length + i * dx
        w = v + x * r
        q = abs(w) * w
        y -= k * q * dx
        m -= k * x * q * dx
    return y, m


@njit(cache=True)
def hull_terms(p, dp, t, eta, nu, nu_r):
    """d(t) + Delta(eta, nu) - C(nu_r) nu_r - D(nu_r) nu_r, body frame [N, N, N m], a 3-tuple.

    The one force of the hull: ``nu_r`` is the velocity relative to the water (docs/sea.md §1: it enters
    the whole C and all damping), ``nu`` the absolute one (Delta). In calm water nu_r = nu
    (:func:`hydrodynamic_force`); :func:`usv_mj.physics.sea.sea_force` adds the sea's loads to it."""
    c0, c1, c2 = coriolis_damping_terms(p, nu_r)
    d0, d1, d2 = disturbance_at(dp, t)  # the scenario's kind (usv_mj.physics.disturbances)
    u0, u1, u2 = uncertainty_terms(p, eta, nu)
    return d0 + u0 - c0, d1 + u1 - c1, d2 + u2 - c2


@njit(cache=True)
def hydrodynamic_force(p, dp, t, eta, nu):
    """Everything on the hull but the thrust: d(t) + Delta - C(nu) nu - D(nu) nu (Eq. 2), body frame."""
    return array3(hull_terms(p, dp, t, eta, nu, nu))


@njit(cache=True)
def mass_solve_terms(p, f0, f1, f2):
    """M^-1 f for the block-diagonal M of Eq. 2 (closed form), a 3-tuple."""
    det = p[P_M22] * p[P_M33] - p[P_M23] * p[P_M23]
    return f0 / p[P_M11], (p[P_M33] * f1 - p[P_M23] * f2) / det, (p[P_M22] * f2 - p[P_M23] * f1) / det


@njit(cache=True)
def body_acceleration(p, dp, t, eta, nu, tau_u, tau_r):
    """nu_dot = M^-1 ([tau_u, 0, tau_r] + d(t) + Delta - C nu - D nu) (Eq. 2): the velocity part of
    :func:`state_derivative` (the plants' own assembly, so that tests of Eq. 2 test what runs)."""
    x = np.empty(6)
    x[:3] = eta
    x[3:] = nu
    return state_derivative(p, dp, t, x, tau_u, tau_r)[3:]


@njit(cache=True)
def kinematics_terms(psi, u, v, r):
    """eta_dot = J(psi) nu (Eq. 1), a 3-tuple."""
    c, s = math.cos(psi), math.sin(psi)
    return c * u - s * v, s * u + c * v, r


@njit(cache=True)
def derivative_into(out, p, x, f0, f1, f2, tau_u, tau_r):
    """out = d/dt of x = (eta, nu) given the non-thrust body force (f0, f1, f2): (J(psi) nu,
    M^-1 (f + [tau_u, 0, tau_r])) (Eqs. 1-2). The one assembly of the state derivative.

    An MMG hull (``p[P_MODEL]`` = MODEL_MMG, :class:`MMGShipParams`) reads its inputs as (n_P [1/s],
    delta [rad]) and adds :func:`usv_mj.physics.mmg.mmg_terms` instead of the thrust."""
    if p[P_MODEL] == MODEL_MMG:  # the inputs are (n_P, delta): the MMG's forces (usv_mj.physics.mmg)
        g0, g1, g2 = mmg_terms(p, P_MMG, x[3], x[4], x[5], tau_u, tau_r)
        a0, a1, a2 = mass_solve_terms(p, f0 + g0, f1 + g1, f2 + g2)
    else:
        a0, a1, a2 = mass_solve_terms(p, f0 + tau_u, f1, f2 + tau_r)
    out[0], out[1], out[2] = kinematics_terms(x[2], x[3], x[4], x[5])
    out[3], out[4], out[5] = a0, a1, a2
    return out


@njit(cache=True)
def kinematics(eta, nu):
    """eta_dot = J(psi) nu (Eq. 1), an array."""
    return array3(kinematics_terms(eta[2], nu[0], nu[1], nu[2]))


@njit(cache=True)
def state_derivative(p, dp, t, x, tau_u, tau_r):
    """d/dt of the 6-vector x = (eta, nu) under the thrust (tau_u, tau_r), calm water."""
    f0, f1, f2 = hull_terms(p, dp, t, x[:3], x[3:], x[3:])
    return derivative_into(np.empty(6), p, x, f0, f1, f2, tau_u, tau_r)


@njit(cache=True)
def nominal_terms(p, nu):
    """phi_u, phi_v, phi_r of Eq. 28: the known part of the velocity dynamics (docs/model.md §1), in Do &
    Pan's coordinates (u, v_bar = v + eps r, r), from the one C and D:

    with f = -C(nu) nu - D(nu) nu and a = M^-1 f (no thrust, d or Delta),
    phi_u = a_u = f_u/m11, phi_v = a_v + eps a_r = f_v/m22 (row 2 of M over m22), phi_r = a_r.
    Written out these are the printed phi_u = (m22 v r + m23 r^2 - d11 u)/m11,
    phi_v = -(m11 u r + d22 v + d23 r)/m22 and phi_r = [(m11 m22 - m22^2) u v + (m11 - m22) m23 u r
    - m22 (d33 r + d32 v) + m23 (d23 r + d22 v)] / (m22 m33 - m23^2).
    """
    c0, c1, c2 = coriolis_damping_terms(p, nu)
    a0, _, a2 = mass_solve_terms(p, -c0, -c1, -c2)
    return a0, -c1 / p[P_M22], a2


def kinetic_energy(ship: ShipParams, nu) -> float:
    """T = 1/2 nu^T M nu [J]."""
    nu = np.asarray(nu, dtype=float)
    return 0.5 * float(nu @ ship.mass_matrix() @ nu)


@vectorize(cache=True)
def wrap_angle(a):
    """Wrap an angle (or array of angles) to [-pi, pi): the one angle wrap of usv_mj.

    A numba ufunc: takes scalars, lists and arrays from Python and is callable from ``njit`` kernels
    (the controllers' e3, the planner, the reference). Compiled for an input type when first called
    with it (a float64 loop for the float64 angles of every caller), not when this module is
    imported: importing the physics does not start numba's compiler (``usv-mj --help``, a bad input)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi



def sway_yaw_linearization(ship: ShipParams, u0: float) -> np.ndarray:
    """The linearized sway-yaw dynamics at the straight run nu0 = (u0, 0, 0): d/dt (v, r) = A (v, r),
    A = -M_sy^-1 N(u0) (docs/model.md §8), a 2x2 array [1/s, m/s, ...].

    M_sy is the sway-yaw block of M; N(u0) the Jacobian of C(nu) nu + D(nu) nu (the hull's own
    :func:`coriolis_damping_terms`) with respect to (v, r) at nu0, by central differences (the
    terms are polynomial in v and r but for |v| v-like terms, whose derivative at 0 is 0: the error
    is c1 h, about 1e-5 N s/m). Written out: N = [[d22_0, m11 u0 + d23_0],
    [(m22 - m11) u0 + d32_0, m23 u0 + d33_0]] (d_ij_0 the constant coefficients; (m22 - m11) u0 is
    the Munk moment). Neither Delta nor d(t) enters. A positive real eigenvalue of A: the straight
    run is directionally unstable (with no yaw moment a small yaw rate grows as exp(lambda t))."""
    p = ship.as_array()
    h = 1e-7
    n = np.empty((2, 2))
    for j in range(2):
        e = np.zeros(3)
        e[1 + j] = h
        hi = np.array(coriolis_damping_terms(p, np.array([u0, 0.0, 0.0]) + e))
        lo = np.array(coriolis_damping_terms(p, np.array([u0, 0.0, 0.0]) - e))
        n[:, j] = (hi - lo)[1:] / (2 * h)
    return -np.linalg.solve(mass_matrix(p)[1:, 1:], n)
