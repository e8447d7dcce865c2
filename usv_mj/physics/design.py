"""The built-in baselines' default gains for a vessel: pole placement at a bandwidth set by its length
(docs/gains.md has the derivation; Fossen 2021, ch. 15).

The PI and LOS laws (controllers/pi_baseline.py, controllers/los.py) were tuned on the paper's hull
(docs/model.md §1: L = 1.98 m, cruising at U = 0.6 m/s). On another hull the same numbers are the
wrong closed loop: the 80 kg Otter or a 180 kg, 4.9 m catamaran with the gains of a 15.6 kg m^2 yaw
inertia. Here the paper hull's tuned design is written as what it is, closed-loop poles, and placed
again on each hull with its own nominal model:

- the **design point** of a hull (:class:`DesignPoint`): its nominal model's surge mass m11, yaw
  inertia m33, surge damping linearised at the design speed, d_u = d(d11(u) u)/du at U, yaw damping
  d_r = d33(0) (the constant coefficient: straight ahead, v = r = 0), the drag d11(U) U that the surge
  loop holds, its length L and a design speed U: the paper hull's 0.6 m/s at the same Froude number,
  U = U_ref sqrt(L / L_ref);
- the **bandwidth** of every loop scales as U / L (the time a hull takes to run its own length):
  s = (U / L) / (U_ref / L_ref) = sqrt(L_ref / L) (Froude similarity: times scale as sqrt(L / g));
- **surge PI**, closed loop m11 s^2 + (d_u + kp) s + ki: natural frequency omega_u s, damping as
  the reference's, i.e. ki = m11 (omega_u s)^2 and kp = 2 zeta_u (omega_u s) m11 - d_u;
- **heading PID**, closed loop m33 s^3 + (d_r + kd) s^2 + kp s + ki: kp = m33 (omega s)^2,
  kd = 2 zeta (omega s) m33 - d_r, ki = kp (omega s) / T_i (the integral zero moves with the bandwidth);
- every **rate** [1/s] times s, every **length** times lambda = L / L_ref, every **area** times
  lambda^2, every **speed** times U / U_ref, an anti-windup limit so that the integrator's authority
  (ki x limit) keeps its share of the force it must hold.

The reference's omega, zeta and T_i are read off its gains and the paper hull (docs/gains.md
prints them), and the formulas are evaluated in the equivalent form
``gain_ref * (m / m_ref) * s^k + (d_ref * (m / m_ref) * s - d)`` so that on the paper hull every
ratio is exactly 1.0 and each gain is the paper's to the last bit (tests/test_gains.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from usv_mj.physics.ship import ShipParams

#: the paper hull's length [m] (usv_mj.vessels.PAPER_DIMENSIONS.L: models/usv.xml as drawn) and its
#: cruising speed [m/s] (the paper's u_d): the reference design point the built-in gains were tuned at
L_REF = 1.98
U_REF = 0.6
G = 9.81


def surge_damping_slope(d11, u: float) -> float:
    """d(d11(u) u)/du at u [N s/m] for d11(u) = c0 + c1 |u| + c2 u^2 (u >= 0): c0 + 2 c1 u + 3 c2 u^2."""
    c0, c1, c2 = d11
    return c0 + 2.0 * c1 * u + 3.0 * c2 * u * u


def surge_drag(d11, u: float) -> float:
    """The surge drag d11(u) u [N] at u >= 0."""
    c0, c1, c2 = d11
    return (c0 + c1 * u + c2 * u * u) * u


@dataclass(frozen=True)
class DesignPoint:
    """What the gains of a hull are placed from (module docstring): [kg, kg m^2, N s/m, N m s/rad,
    N, m, m/s]."""

    m11: float
    m33: float
    d_u: float
    d_r: float
    drag: float
    L: float
    U: float

    @classmethod
    def of(cls, ship: ShipParams, length: float, speed: float | None = None) -> "DesignPoint":
        """The design point of the nominal model ``ship`` of a hull ``length`` [m] long, at ``speed``
        [m/s] (None: the paper's Froude number, U_REF sqrt(length / L_REF))."""
        if not (math.isfinite(length) and length > 0):
            raise ValueError(f"a design point needs a hull length > 0 m, got {length!r}")
        u = U_REF * math.sqrt(length / L_REF) if speed is None else float(speed)
        if not (math.isfinite(u) and u > 0):
            raise ValueError(f"a design point needs a design speed > 0 m/s, got {speed!r}")
        return cls(float(ship.m11), float(ship.m33), surge_damping_slope(ship.d11, u), float(ship.d33[0]),
                   surge_drag(ship.d11, u), float(length), u)


#: the paper hull's design point: the reference every built-in default was tuned at
REFERENCE = DesignPoint.of(ShipParams(), L_REF, U_REF)


@dataclass(frozen=True)
class Scaling:
    """The ratios that carry the reference's design to ``point`` (module docstring); every one is
    exactly 1.0 on the reference itself."""

    point: DesignPoint
    ref: DesignPoint = REFERENCE

    @property
    def s(self) -> float:
        """Bandwidth ratio (U / L) / (U_ref / L_ref) [-]."""
        return (self.point.U / self.point.L) / (self.ref.U / self.ref.L)

    @property
    def length(self) -> float:
        """lambda = L / L_ref [-]."""
        return self.point.L / self.ref.L

    @property
    def speed(self) -> float:
        """U / U_ref [-]."""
        return self.point.U / self.ref.U

    def rate(self, value: float) -> float:
        """A rate or frequency [1/s] of the reference's design on this hull."""
        return value * self.s

    def surge_pi(self, kp_ref: float, ki_ref: float) -> tuple[float, float]:
        """(kp [N s/m], ki [N/m]) of the surge PI: ki = m11 (omega_u s)^2, kp = 2 zeta_u omega_u s m11 - d_u
        with the reference's omega_u = sqrt(ki_ref / m11_ref), zeta_u = (d_u,ref + kp_ref) / (2 omega_u m11_ref);
        kp is not below 0 (a hull whose own damping is more than the loop wants)."""
        p, r, s = self.point, self.ref, self.s
        rm = p.m11 / r.m11
        return max(0.0, kp_ref * rm * s + (r.d_u * rm * s - p.d_u)), ki_ref * rm * s * s

    def heading_pid(self, kp_ref: float, kd_ref: float, ki_ref: float) -> tuple[float, float, float]:
        """(kp [N m/rad], kd [N m s/rad], ki [N m/(rad s)]) of the heading PID: kp = m33 (omega s)^2,
        kd = 2 zeta omega s m33 - d_r (not below 0), ki = kp omega s / T_i, with the reference's
        omega = sqrt(kp_ref / m33_ref), zeta = (d_r,ref + kd_ref) / (2 omega m33_ref), T_i = kp_ref omega / ki_ref."""
        p, r, s = self.point, self.ref, self.s
        rm = p.m33 / r.m33
        return kp_ref * rm * s * s, max(0.0, kd_ref * rm * s + (r.d_r * rm * s - p.d_r)), ki_ref * rm * s * s * s

    def surge_integral_limit(self, limit_ref: float, ki_ref: float) -> float:
        """The anti-windup limit [m] of the surge integrator whose authority ki x limit [N] is to the
        hull's drag at its design speed what the reference's is to its own:
        limit = limit_ref (drag / drag_ref) / (ki / ki_ref). A hull whose nominal model has no surge
        damping (an MMG hull: its forces are the MMG model's, usv_mj.physics.mmg) scales the authority
        as the loop's own force scale m11 U omega instead."""
        p, r, s = self.point, self.ref, self.s
        ki_ratio = (p.m11 / r.m11) * s * s
        force = p.drag / r.drag if p.drag > 0 else (p.m11 / r.m11) * s * (p.U / r.U)
        return limit_ref * force / ki_ratio

    def heading_integral_limit(self, limit_ref: float) -> float:
        """The anti-windup limit [rad s] of the heading integrator: its authority ki x limit [N m]
        scales as the loop's moment m33 (omega s)^2 x 1 rad, so limit = limit_ref / s."""
        return limit_ref / self.s


__all__ = ["DesignPoint", "Scaling", "REFERENCE", "L_REF", "U_REF", "surge_damping_slope", "surge_drag"]
