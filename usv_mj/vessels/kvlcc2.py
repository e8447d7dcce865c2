"""KVLCC2 by the MMG standard method: kind ``kvlcc2`` (docs/vessels.md, KVLCC2).

The 7 m model (L_pp = 7.00 m, scale 1:45.714 of the 320 m VLCC) of Yasukawa, H. and Yoshimura, Y.
(2015), "Introduction of MMG standard method for ship maneuvering predictions", J. Mar. Sci.
Technol. 20, 37-52: principal particulars, hull derivatives, propeller and rudder interaction
coefficients of its tables. The paper itself was not at hand while this was written: the numbers
below are those of the KVLCC2 L7 parameter set in the tests of the ``shipmmg`` package
(github ShipMMG/shipmmg, ``tests/test_mmg_3dof.py``, fixture ``ship_KVLCC2_L7_model``, which cites
the paper), taken as facts; the ones that are not in that set are marked where they are defined.

The vessel's actuators are its rudder and its propeller: the plants' two input channels carry the
propeller revolutions n_P [1/s] ("tau_u") and the rudder angle delta [rad] ("tau_r", positive to
port in usv_mj's frame, i.e. -delta of the MMG's starboard-positive one). The ``[actuators]`` of
the vessel is a ``box``: |delta| <= ``max_rudder_deg`` and the rudder rate limited to
``rudder_rate_deg_s`` per control period (usv_mj.physics.actuators, exact per period); n_P at most
``max_propeller_rps``. A force controller's (tau_u, tau_r) is allocated to (n_P, delta) first
(usv_mj.physics.mmg.mmg_allocate; docs/vessels.md, Force controllers on KVLCC2).
The forces are :func:`usv_mj.physics.mmg.mmg_terms` on both plants (one kernel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from usv_mj.physics.mmg import (N_MMG_PARAMS, Q_AH, Q_C1, Q_C2M, Q_C2P, Q_DP, Q_EPS, Q_ETA, Q_GRM, Q_GRP, Q_HULL_N,
                        Q_HULL_X, Q_K0, Q_K1, Q_K2, Q_KAPPA, Q_L, Q_LR, Q_MMX, Q_MMY, Q_MXG, Q_NR, Q_NRRR, Q_NV,
                        Q_NVRR, Q_NVVR, Q_NVVV, Q_R0, Q_RHO, Q_RUDDER, Q_TP, Q_TR, Q_WAKE, Q_WP0, Q_XP, Q_XRAH,
                        Q_XB, Q_XRR, Q_XVR, Q_XVV, Q_XVVVV, Q_YR, Q_YRRR, Q_YV, Q_YVRR, Q_YVVR, Q_YVVV,
                        WAKE_EXPONENTIAL, WAKE_YASUKAWA)
from usv_mj.core.registry import VESSELS
from usv_mj.physics.channels import rudder_channels
from usv_mj.physics.ship import MMGShipParams, RigidBodySplit

from usv_mj.vessels import Dimensions, Vessel

WAKE_MODELS = {"exponential": WAKE_EXPONENTIAL, "yasukawa2015": WAKE_YASUKAWA}
SCALE = 45.714          # the 7 m model of the 320 m ship (SIMMAN 2008's KVLCC2 model, L_pp 7.0 m)


@dataclass(frozen=True)
class KVLCC2Options:
    """The MMG parameters of the KVLCC2 7 m model (module docstring); SI units, primes are the
    MMG's nondimensional values (forces by 1/2 rho L d U^2, moments by 1/2 rho L^2 d U^2, masses
    by 1/2 rho L^2 d, J_z by 1/2 rho L^4 d).

    Attributes
    ----------
    rho: water density [kg/m^3] (1025, the shipmmg default; the paper's tank water is not stated here).
    L_pp, B, d: length between perpendiculars, breadth, draught [m].
    displacement: volume [m^3] (m = rho displacement).
    x_G: centre of gravity ahead of midship [m].
    gyration_ratio: I_zG = m (gyration_ratio L_pp)^2.
    m_x_dash, m_y_dash, J_z_dash: added masses (nondimensional).
    R_0_dash, X_vv_dash ... N_rrr_dash: hull derivatives (nondimensional).
    D_p: propeller diameter [m]. k_0, k_1, k_2: K_T(J) = k_0 + k_1 J + k_2 J^2.
    t_P: thrust deduction. w_P0: wake fraction in straight motion. x_P_dash: x'_P of beta_P.
    wake_model: "exponential" (w_P = w_P0 exp(-4 beta_P^2), shipmmg's) or "yasukawa2015"
        (1 - w_P = (1 - w_P0)(1 + (1 - exp(-C_1 |beta_P|))(C_2 - 1))) with C_1, C_2_plus, C_2_minus.
    A_R: rudder area [m^2]. H_R: rudder span [m] (eta = D_p / H_R). f_alpha: rudder lift gradient.
    epsilon, kappa: the rudder inflow's wake ratio and slipstream factor. t_R, a_H, x_H_dash:
        steering resistance deduction, rudder force increase, its point (x_H = x_H_dash L_pp).
    x_R_dash: rudder position (x_R = x_R_dash L_pp). gamma_R_minus, gamma_R_plus: flow straightening
        for beta_R < 0 and > 0. l_R_dash: l'_R of beta_R.
    max_rudder_deg, rudder_rate_deg_s: the steering gear [deg, deg/s].
    max_propeller_rps: the largest n_P a force controller's allocation commands [1/s] (the sources
        state no engine limit: 2x the self-propulsion point at the service speed, a choice; the
        allocation never reverses the propeller, whose MMG model is for ahead revolutions).
    service_speed: the approach speed of the manoeuvres [m/s] (U_0 = 1.179 m/s, Fn 0.142).
    propeller_rps: n_P near the self-propulsion point at it [1/s], where the manoeuvres' search for
        the n_P that holds the speed starts (these coefficients hold 1.179 m/s at 11.85 1/s; the
        17.95 1/s of shipmmg's KVLCC2 tests drives this model faster: docs/vessels.md).
    drift_point_x: x_b [m] ahead of midship of the point whose lateral velocity sets U and beta
        (usv_mj.physics.mmg; 0: the MMG standard's midship; -x_G: shipmmg 0.0.11's v - x_G r).
    """

    rho: float = 1025.0
    L_pp: float = 7.00
    B: float = 1.27
    d: float = 0.46
    displacement: float = 3.27
    x_G: float = 0.25
    gyration_ratio: float = 0.25
    m_x_dash: float = 0.022
    m_y_dash: float = 0.223
    J_z_dash: float = 0.011
    R_0_dash: float = 0.022
    X_vv_dash: float = -0.040
    X_vr_dash: float = 0.002
    X_rr_dash: float = 0.011
    X_vvvv_dash: float = 0.771
    Y_v_dash: float = -0.315
    Y_r_dash: float = 0.083
    Y_vvv_dash: float = -1.607
    Y_vvr_dash: float = 0.379
    Y_vrr_dash: float = -0.391
    Y_rrr_dash: float = 0.008
    N_v_dash: float = -0.137
    N_r_dash: float = -0.049
    N_vvv_dash: float = -0.030
    N_vvr_dash: float = -0.294
    N_vrr_dash: float = 0.055
    N_rrr_dash: float = -0.013
    D_p: float = 0.216
    k_0: float = 0.2931
    k_1: float = -0.2753
    k_2: float = -0.1385
    t_P: float = 0.220
    w_P0: float = 0.40
    x_P_dash: float = -0.690
    wake_model: str = "exponential"
    C_1: float = 2.0          # yasukawa2015 wake only; not in the shipmmg set (docs/vessels.md: a restatement citing the paper)
    C_2_plus: float = 1.6     # idem
    C_2_minus: float = 1.1    # idem
    A_R: float = 0.0539
    H_R: float = 0.345
    f_alpha: float = 2.747
    epsilon: float = 1.09
    kappa: float = 0.50
    t_R: float = 0.387
    a_H: float = 0.312
    x_H_dash: float = -0.464
    x_R_dash: float = -0.500
    gamma_R_minus: float = 0.395
    gamma_R_plus: float = 0.640
    l_R_dash: float = -0.710
    max_rudder_deg: float = 35.0
    rudder_rate_deg_s: float = 15.68  # SIMMAN 2020 case 1.2: 2.32 deg/s full scale, 15.68 deg/s model
    service_speed: float = 1.179
    propeller_rps: float = 11.85
    drift_point_x: float = 0.0
    max_propeller_rps: float = 23.7

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if name == "wake_model":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"vessel.{name} must be a finite number, got {value!r}")
        for name in ("rho", "L_pp", "B", "d", "displacement", "gyration_ratio", "D_p", "A_R", "H_R", "f_alpha",
                     "max_rudder_deg", "rudder_rate_deg_s", "service_speed", "propeller_rps", "epsilon",
                     "max_propeller_rps"):
            if not getattr(self, name) > 0:
                raise ValueError(f"vessel.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("m_x_dash", "m_y_dash", "J_z_dash"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"vessel.{name} must be >= 0, got {getattr(self, name)!r}")
        if self.wake_model not in WAKE_MODELS:
            raise ValueError(f"vessel.wake_model must be one of {', '.join(map(repr, WAKE_MODELS))}, "
                             f"got {self.wake_model!r}")
        if not self.k_0 > 0:   # K_T at J = 0: a propeller that pushes at rest (the allocation divides by it)
            raise ValueError(f"vessel.k_0 must be > 0, got {self.k_0!r}")
        for name in ("t_P", "w_P0", "t_R"):
            if not 0 <= getattr(self, name) < 1:
                raise ValueError(f"vessel.{name} must be in [0, 1), got {getattr(self, name)!r}")
        if not self.max_rudder_deg < 90:
            raise ValueError(f"vessel.max_rudder_deg must be < 90, got {self.max_rudder_deg!r}")

    # --- derived ------------------------------------------------------------------------------

    @property
    def mass(self) -> float:
        """m = rho displacement [kg]."""
        return self.rho * self.displacement

    def added_masses(self) -> tuple[float, float, float]:
        """(m_x [kg], m_y [kg], J_z [kg m^2]) from the primes."""
        q = 0.5 * self.rho * self.L_pp ** 2 * self.d
        return q * self.m_x_dash, q * self.m_y_dash, q * self.L_pp ** 2 * self.J_z_dash

    @property
    def I_zG(self) -> float:
        """Yaw inertia about the centre of gravity [kg m^2]."""
        return self.mass * (self.gyration_ratio * self.L_pp) ** 2


def pack(o: KVLCC2Options) -> tuple:
    """The packed MMG block (usv_mj.physics.mmg.Q_*) of ``o``."""
    q = [0.0] * N_MMG_PARAMS
    m = o.mass
    m_x, m_y, _ = o.added_masses()
    half = 0.5 * o.rho
    q[Q_RHO], q[Q_L] = o.rho, o.L_pp
    q[Q_HULL_X] = half * o.L_pp * o.d
    q[Q_HULL_N] = half * o.L_pp ** 2 * o.d
    for idx, name in ((Q_R0, "R_0_dash"), (Q_XVV, "X_vv_dash"), (Q_XVR, "X_vr_dash"), (Q_XRR, "X_rr_dash"),
                      (Q_XVVVV, "X_vvvv_dash"), (Q_YV, "Y_v_dash"), (Q_YR, "Y_r_dash"), (Q_YVVV, "Y_vvv_dash"),
                      (Q_YVVR, "Y_vvr_dash"), (Q_YVRR, "Y_vrr_dash"), (Q_YRRR, "Y_rrr_dash"), (Q_NV, "N_v_dash"),
                      (Q_NR, "N_r_dash"), (Q_NVVV, "N_vvv_dash"), (Q_NVVR, "N_vvr_dash"), (Q_NVRR, "N_vrr_dash"),
                      (Q_NRRR, "N_rrr_dash"), (Q_DP, "D_p"), (Q_K0, "k_0"), (Q_K1, "k_1"), (Q_K2, "k_2"),
                      (Q_TP, "t_P"), (Q_WP0, "w_P0"), (Q_XP, "x_P_dash"), (Q_C1, "C_1"), (Q_C2P, "C_2_plus"),
                      (Q_C2M, "C_2_minus"), (Q_EPS, "epsilon"), (Q_KAPPA, "kappa"), (Q_TR, "t_R"), (Q_AH, "a_H"),
                      (Q_GRM, "gamma_R_minus"), (Q_GRP, "gamma_R_plus"), (Q_LR, "l_R_dash")):
        q[idx] = float(getattr(o, name))
    q[Q_WAKE] = WAKE_MODELS[o.wake_model]
    q[Q_RUDDER] = half * o.A_R * o.f_alpha
    q[Q_ETA] = o.D_p / o.H_R
    q[Q_XRAH] = (o.x_R_dash + o.a_H * o.x_H_dash) * o.L_pp
    q[Q_MMX], q[Q_MMY], q[Q_MXG] = m + m_x, m + m_y, o.x_G * m
    q[Q_XB] = o.drift_point_x
    return tuple(q)


def hull(o: KVLCC2Options) -> tuple[MMGShipParams, RigidBodySplit]:
    """The packed hull (the MMG's M, the MMG block) and the rigid body MuJoCo carries (m, x_G, I_z
    about midship = I_zG + m x_G^2; the added masses m_x, m_y, J_z are the callback's)."""
    m = o.mass
    m_x, m_y, j_z = o.added_masses()
    iz = o.I_zG + m * o.x_G ** 2
    zero = (0.0, 0.0, 0.0)
    ship = MMGShipParams(m11=m + m_x, m22=m + m_y, m23=o.x_G * m, m33=iz + j_z, d11=zero, d22=zero, d23=zero,
                         d32=zero, d33=zero, uncertainty_scale=0.0, coriolis_masses=zero, crossflow=zero,
                         mmg=pack(o))
    return ship, RigidBodySplit(rigid=(m, o.x_G, iz))


def actuators(o: KVLCC2Options) -> dict:
    """The vessel's ``[actuators]``: the rudder's angle and rate limit on the delta channel, the largest
    n_P on the n_P channel (module docstring); a scenario's ``[actuators]`` keys change them one by
    one (usv_mj.scenario.spec), they do not replace the steering gear."""
    return {"kind": "box", "max_surge_n": o.max_propeller_rps, "max_yaw_nm": math.radians(o.max_rudder_deg),
            "yaw_rate_nm_s": math.radians(o.rudder_rate_deg_s)}


@VESSELS.register("kvlcc2", options=KVLCC2Options)
def kvlcc2_vessel(options, scenario=None) -> Vessel:
    """The KVLCC2 7 m model of ``options`` (None: the defaults of the module docstring's source)."""
    o = options if options is not None else KVLCC2Options()
    ship, split = hull(o)
    manoeuvres = {"approach_speed": o.service_speed, "control_period": 0.01,
                  "turning": {"duration": 200.0}, "zigzag": {"duration": 100.0},
                  # 2 deg steps to +-10 deg, each held 300 s (51 L/U): the steady turn is reached
                  "spiral": {"max_rudder_deg": 10.0, "steps": 5, "hold_s": 300.0}}
    return Vessel("kvlcc2", ship, split, Dimensions(o.L_pp, o.B, o.d), actuators(o),
                  "Yasukawa and Yoshimura (2015), J. Mar. Sci. Technol. 20, 37-52 (MMG standard method), KVLCC2 7 m "
                  "model; numbers as in shipmmg's KVLCC2 L7 test set",
                  ("3 DOF: roll (and the heel in a turn), heave and pitch are left out",
                   "inputs: tau_u is n_P [1/s], tau_r is the rudder angle delta [rad] (positive to port)",
                   f"the wake model is {o.wake_model!r}; calm deep water only (no [sea])"),
                  channels=rudder_channels(ship.mmg), manoeuvre=manoeuvres, scale=SCALE, nominal_rps=o.propeller_rps,
                  limitations={"sea": "the MMG standard method's hull runs in calm deep water only",
                               "stopping": "the MMG standard method models the propeller ahead only (no astern "
                                           "revolutions for the crash stop)"},
                  actuators_merged=True)
