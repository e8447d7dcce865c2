"""A conventional PI tracker, the paper's comparison baseline (docs/model.md §6).

- Surge: a PI loop on the surge speed, whose set-point corrects the along-track error:
  e_at = cos(psi_d) e1 + sin(psi_d) e2 (> 0 when the ship is ahead of the reference point),
  u_c = clip(u_d - k_at e_at, u_c_min, u_c_max), tau_u = kp_u (u_c - u) + ki_u integral(u_c - u).
- Heading: a PI loop on the same heading error e3 = wrap(psi - psi_a) as the PPC law (Eq. 15), with
  yaw-rate damping (kd_r r) because the yaw dynamics are a double integrator: without it no PI gain
  is stable. tau_r = -(kp_r e3 + ki_r integral(e3)) - kd_r (r - r_d).

Tuned fairly for the paper's ship (surge time constant about 0.5 s; yaw natural frequency about
3.6 rad/s with damping about 0.7, so that the heading loop rejects the paper preset's yaw
disturbance of up to 20 N m with a torque budget below the PPC law's): the defaults of
:class:`PIGains`. On another hull the gains a scenario does not set are these placed again on its
nominal model at its bandwidth (:meth:`PIGains.for_vessel`, docs/gains.md). Driven through the same
quantizer as the PPC controller. A softer heading loop (40 / 4 / 30) lets e3 leave its funnel:
that says more about the tuning than about PI control, so it is not the baseline. Its
funnel errors are reported with the same transform so the figures can compare them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.record.criteria import FunnelCriterion
from usv_mj.core.registry import CONTROLLERS
from usv_mj.physics.ship import ShipParams

from usv_mj.controllers.base import D_E3, REF_PSI, REF_R, REF_U, TRACKING_FIELDS
from usv_mj.controllers.performance_funnel import PerformanceFunnel, funnels_of
from usv_mj.controllers.tracking_errors import tracking_errors


N_TRACK = len(TRACKING_FIELDS)  # the PI law's own fields follow the tracking errors


@dataclass(frozen=True)
class PIGains:
    """Gains of the PI baseline (units: N/(m/s), N/m, N m/rad, N m s/rad ...).

    Attributes
    ----------
    k_at:
        Along-track correction of the speed set-point [1/s].
    kp_u, ki_u:
        Surge-speed PI [N s/m, N/m].
    kp_r, ki_r, kd_r:
        Heading PI [N m/rad, N m/(rad s)] and yaw-rate damping [N m s/rad].
    u_c_min, u_c_max:
        Limits of the speed set-point [m/s].
    a1:
        Blend width of psi_a (Eq. 15) [m^2], as for the PPC law.
    integral_limit_u, integral_limit_r:
        Anti-windup clamps of the integrators [m, rad s].
    """

    k_at: float = 0.2
    kp_u: float = 200.0
    ki_u: float = 40.0
    kp_r: float = 200.0
    ki_r: float = 20.0
    kd_r: float = 72.0
    u_c_min: float = 0.0
    u_c_max: float = 1.5
    a1: float = 1.0
    integral_limit_u: float = 5.0
    integral_limit_r: float = 5.0

    def __post_init__(self) -> None:
        for name in ("k_at", "kp_u", "ki_u", "kp_r", "ki_r", "kd_r", "a1", "integral_limit_u", "integral_limit_r"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"controller.{name} must be >= 0, got {value!r}")
        if not self.a1 > 0:
            raise ValueError(f"controller.a1 must be > 0, got {self.a1!r}")
        if not self.u_c_max > self.u_c_min:
            raise ValueError("controller.u_c_max must be greater than controller.u_c_min")

    #: the gains :meth:`for_vessel` derives from the vessel (the others keep the defaults above)
    DERIVED = ("k_at", "kp_u", "ki_u", "kp_r", "ki_r", "kd_r", "a1", "integral_limit_u", "integral_limit_r")

    @classmethod
    def for_vessel(cls, scaling) -> dict:
        """The default gains on the hull of ``scaling`` (a :class:`usv_mj.physics.design.Scaling`):
        the defaults above, which are the paper hull's design, placed again on that hull by pole
        placement at its bandwidth (docs/gains.md): the surge PI and the heading PID with its nominal
        m11, m33 and damping, k_at a rate, a1 an area, the anti-windup limits keeping their authority.
        The paper hull gets the defaults exactly."""
        d = cls()
        kp_u, ki_u = scaling.surge_pi(d.kp_u, d.ki_u)
        kp_r, kd_r, ki_r = scaling.heading_pid(d.kp_r, d.kd_r, d.ki_r)
        lam = scaling.length
        return {"k_at": scaling.rate(d.k_at), "kp_u": kp_u, "ki_u": ki_u, "kp_r": kp_r, "ki_r": ki_r, "kd_r": kd_r,
                "a1": d.a1 * lam * lam, "integral_limit_u": scaling.surge_integral_limit(d.integral_limit_u, d.ki_u),
                "integral_limit_r": scaling.heading_integral_limit(d.integral_limit_r)}


@njit(cache=True)
def pi_law(t, x, ref, eps, g, funnel, integ, dt, diag):
    k_at, kp_u, ki_u, kp_r, ki_r, kd_r, u_min, u_max, a1, lim_u, lim_r = (
        g[0], g[1], g[2], g[3], g[4], g[5], g[6], g[7], g[8], g[9], g[10])
    e1, e2, h2, chi, th, e1_dot, e2_dot = tracking_errors(eps, a1, t, x, ref, funnel, diag)
    psi_d = ref[REF_PSI]
    e_at = math.cos(psi_d) * e1 + math.sin(psi_d) * e2
    u_c = ref[REF_U] - k_at * e_at
    u_c = min(max(u_c, u_min), u_max)
    e_u = u_c - x[3]
    e3 = diag[D_E3]
    tau_u = kp_u * e_u + ki_u * integ[0]
    tau_r = -(kp_r * e3 + ki_r * integ[1]) - kd_r * (x[5] - ref[REF_R])
    integ[0] = min(max(integ[0] + dt * e_u, -lim_u), lim_u)
    integ[1] = min(max(integ[1] + dt * e3, -lim_r), lim_r)
    diag[N_TRACK] = -e_u
    diag[N_TRACK + 1] = x[5] - ref[REF_R]
    diag[N_TRACK + 2] = integ[0]
    diag[N_TRACK + 3] = integ[1]
    return tau_u, tau_r


@njit(cache=True)
def pi_kernel(t, x, ref, eps, g, funnel, integ, dt, diag):
    """The compiled loop's kernel of :class:`PIController` (usv_mj.core.kernels): ``__call__`` natively."""
    tau_u, tau_r = pi_law(t, x, ref, eps, g, funnel, integ, dt, diag)
    return tau_u, tau_r, diag


@CONTROLLERS.register("pi", gains=PIGains)
class PIController:
    """The PI baseline of docs/model.md §6 behind the controller interface (see the module docstring)."""

    name = "pi"
    diagnostic_fields = TRACKING_FIELDS + ("u_e", "r_e", "integral_u", "integral_r")
    #: from the paper's start pose it drives paper-limited's thrusters into their limits (usv-mj compare)
    reaches_actuator_limits = True
    # e_i* = ln((1 + z_i) / (1 - z_i)) are numbers; integral_u of u_c - u, integral_r of e3
    diagnostic_units = {"e1s": "-", "e2s": "-", "e3s": "-", "psi_a": "rad", "u_e": "m/s", "r_e": "rad/s",
                        "integral_u": "m", "integral_r": "rad s"}
    # judged by the PPC law's funnel, as the paper compares the two (its funnel errors, same transform);
    # beside another controller the main job judges it by that controller's criterion instead
    criterion = FunnelCriterion()

    @classmethod
    def from_scenario(cls, gains: PIGains, scenario) -> "PIController":
        """The baseline for ``scenario``: its nominal ship (the vessel's times
        ``[vessel] model_mismatch``: ``scenario.nominal_ship``), funnels (for the errors) and control period."""
        fxy, fpsi = funnels_of(scenario)
        return cls(gains, scenario.nominal_ship, fxy, fpsi, scenario.control_period)

    def __init__(self, gains: PIGains, nominal: ShipParams, funnel_xy: PerformanceFunnel,
                 funnel_psi: PerformanceFunnel, control_period: float):
        self.gains = gains
        self._eps = nominal.eps
        self._g = np.array([gains.k_at, gains.kp_u, gains.ki_u, gains.kp_r, gains.ki_r, gains.kd_r,
                            gains.u_c_min, gains.u_c_max, gains.a1, gains.integral_limit_u,
                            gains.integral_limit_r])
        self._funnel = np.array([funnel_xy.rho_0, funnel_xy.rho_inf, funnel_xy.rate,
                                 funnel_psi.rho_0, funnel_psi.rho_inf, funnel_psi.rate])
        self.dt = float(control_period)
        self._integ = np.zeros(2)
        self._diag = np.zeros(len(PIController.diagnostic_fields))   # what pi_law writes, whatever a subclass declares

    def reset(self) -> None:
        self._integ[:] = 0.0
        self._diag[:] = 0.0

    def kernel(self):
        """(pi_kernel, its arrays) for the compiled loop."""
        from usv_mj.core.kernels import Kernel

        return Kernel(pi_kernel, (self._eps, self._g, self._funnel, self._integ, self.dt, self._diag),
                      n_diag=len(self._diag))

    def __call__(self, t, state, reference):
        tau_u, tau_r = pi_law(float(t), state, reference, self._eps, self._g, self._funnel,
                              self._integ, self.dt, self._diag)
        return tau_u, tau_r, self._diag


