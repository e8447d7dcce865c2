"""A ship from its main dimensions: the linear manoeuvring derivatives of Clarke, Gedling and Hine (1983).

Kind ``clarke83`` (docs/vessels.md): Clarke, D., Gedling, P. and Hine, G. (1983), "The application
of manoeuvring criteria in hull design using linear theory", Trans. RINA 125, 45-68, the regression
of sway-yaw derivatives on L, B, T and C_b, as T. I. Fossen applies it in MSS ``clarke83.m`` and
PythonVehicleSimulator ``lib/models.py: clarke83`` (Fossen 2021, §7.5.3).

With S = pi (T/L)^2, the nondimensional (prime-system) derivatives are

    Y'_vdot = -S (1 + 0.16 C_b B/T - 5.1 (B/L)^2)      Y'_v = -S (1 + 0.4 C_b B/T)
    Y'_rdot = -S (0.67 B/L - 0.0033 (B/T)^2)           Y'_r = -S (-1/2 + 2.2 B/L - 0.08 B/T)
    N'_vdot = -S (1.1 B/L - 0.041 B/T)                 N'_v = -S (1/2 + 2.4 T/L)
    N'_rdot = -S (1/12 + 0.017 C_b B/T - 0.33 B/L)     N'_r = -S (1/4 + 0.039 B/T - 0.56 B/L)

made dimensional with (1/2) rho L^3 (Y_vdot), L^4 (Y_rdot, N_vdot), L^5 (N_rdot) and
(1/2) rho L^2 U (Y_v), L^3 U (Y_r, N_v), L^4 U (N_r), U the speed of the linearisation [m/s].
Rigid body: m = rho C_b L B T, I_z = m R66^2 + m x_g^2 about the origin. Surge (not Clarke's; as
Fossen's clarke83): X_udot = -0.1 m and X_u = -(m - X_udot) / T_surge.

The model is Fossen's linear manoeuvring model M nu_dot + N(U) nu = tau, whose N(U) "includes
linear damping D and the linearized Coriolis and centripetal matrix C(U)" (clarke83's docstring).
Mapped onto the packed layout (usv_mj.vessels.from_derivatives) with these documented choices:
- C(nu) = 0 (``coriolis = "none"``): N(U) holds it; D = N(U), exactly linear;
- N at the option ``U`` (the kernels' damping does not depend on the speed; Fossen's
  ``shipClarke83`` re-evaluates N at the relative speed U_r every step, and clarke83 evaluates
  it at U + 0.001 m/s to avoid U = 0: here it is the formula at U);
- M's off-diagonal: Clarke's m23 = m x_g - Y_rdot and m32 = m x_g - N_vdot differ; the layout (and
  MuJoCo's joint-space mass matrix) is symmetric, so both become their mean (the skew part
  (N_vdot - Y_rdot)/2 is dropped; :func:`reference_matrices` gives the unsymmetric M as printed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from usv_mj.core.registry import VESSELS

from usv_mj.vessels import Dimensions, Vessel, from_derivatives

RHO = 1025.0  # kg/m^3, as the reference


@dataclass(frozen=True)
class Clarke83Options:
    """Main dimensions and the linearisation of a Clarke (1983) ship (SI units).

    Attributes
    ----------
    L, B, T: length, beam, draught [m].
    Cb: block coefficient (0, 1].
    R66: radius of gyration in yaw about the COM [m] (Fossen: about 0.25 L).
    xg: COM ahead of the body origin [m].
    U: speed of the linearisation [m/s] (the damping is N(U)).
    T_surge: surge time constant [s] (X_u = -(m - X_udot)/T_surge).

    The defaults are a 2 m model of a ship (L/B = 5, B/T = 3.33, C_b = 0.65) at the paper's 0.6 m/s.
    """

    L: float = 2.0
    B: float = 0.4
    T: float = 0.12
    Cb: float = 0.65
    R66: float = 0.5
    xg: float = 0.0
    U: float = 0.6
    T_surge: float = 5.0

    def __post_init__(self) -> None:
        for name in ("L", "B", "T", "R66", "U", "T_surge"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"vessel.{name} must be > 0, got {value!r}")
        if not (math.isfinite(self.Cb) and 0 < self.Cb <= 1):
            raise ValueError(f"vessel.Cb must be in (0, 1], got {self.Cb!r}")
        if not math.isfinite(self.xg):
            raise ValueError(f"vessel.xg must be finite, got {self.xg!r}")


def derivatives(o: Clarke83Options) -> dict:
    """The dimensional derivatives (module docstring) in Fossen's names [SI]."""
    L, B, T, Cb, U = o.L, o.B, o.T, o.Cb, o.U
    m = RHO * Cb * L * B * T
    S = math.pi * (T / L) ** 2
    q = 0.5 * RHO
    X_udot = -0.1 * m
    return {
        "m": m, "x_g": o.xg, "I_z": m * o.R66 ** 2 + m * o.xg ** 2,
        "X_udot": X_udot,
        "Y_vdot": -S * (1 + 0.16 * Cb * B / T - 5.1 * (B / L) ** 2) * q * L ** 3,
        "Y_rdot": -S * (0.67 * B / L - 0.0033 * (B / T) ** 2) * q * L ** 4,
        "N_vdot": -S * (1.1 * B / L - 0.041 * B / T) * q * L ** 4,
        "N_rdot": -S * (1 / 12 + 0.017 * Cb * B / T - 0.33 * B / L) * q * L ** 5,
        "X_u": -(m - X_udot) / o.T_surge,
        "Y_v": -S * (1 + 0.4 * Cb * B / T) * q * L ** 2 * U,
        "Y_r": -S * (-0.5 + 2.2 * B / L - 0.08 * B / T) * q * L ** 3 * U,
        "N_v": -S * (0.5 + 2.4 * T / L) * q * L ** 3 * U,
        "N_r": -S * (0.25 + 0.039 * B / T - 0.56 * B / L) * q * L ** 4 * U,
    }


def reference_matrices(o: Clarke83Options) -> tuple[np.ndarray, np.ndarray]:
    """(M, D): M = M_RB + M_A as the reference gives it (unsymmetric) and D = N(U) [SI], 3x3."""
    d = derivatives(o)
    m, xg = d["m"], d["x_g"]
    M = np.array([[m - d["X_udot"], 0.0, 0.0],
                  [0.0, m - d["Y_vdot"], m * xg - d["Y_rdot"]],
                  [0.0, m * xg - d["N_vdot"], d["I_z"] - d["N_rdot"]]])
    D = -np.array([[d["X_u"], 0.0, 0.0], [0.0, d["Y_v"], d["Y_r"]], [0.0, d["N_v"], d["N_r"]]])
    return M, D


@VESSELS.register("clarke83", options=Clarke83Options)
def clarke83_vessel(options, scenario=None) -> Vessel:
    """The Clarke (1983) ship of ``options`` (None: the defaults)."""
    o = options if options is not None else Clarke83Options()
    d = derivatives(o)
    y_rdot, n_vdot = d.pop("Y_rdot"), d.pop("N_vdot")
    mean = 0.5 * (y_rdot + n_vdot)
    ship, split = from_derivatives(**d, Y_rdot=mean, N_vdot=mean, coriolis="none", where="vessel")
    return Vessel("clarke83", ship, split, Dimensions(o.L, o.B, o.T), None,
                  "Clarke, Gedling and Hine (1983), Trans. RINA 125 (Fossen's clarke83)",
                  (f"M's off-diagonal symmetrized: m23 = m32 = m x_g - (Y_rdot + N_vdot)/2 (Y_rdot = {y_rdot:.6g}, "
                   f"N_vdot = {n_vdot:.6g})", "C(nu) = 0: N(U) holds the linearized C(U)",
                   f"N at U = {o.U:g} m/s (the reference re-evaluates it at the relative speed)"))
