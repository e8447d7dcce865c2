"""``example-pd``: a PD law on the pose error of an underactuated surface vessel, at the compiled speed.

With the body-frame position error (e_x along the hull, e_y to port) of the reference point
(x_d, y_d) and the reference's speed u_d, heading psi_d and yaw rate r_d:

    tau_u = d11(u_d) u_d + kp_surge e_x + kd_surge (u_d - u)                       [N]
    psi_c = psi_d + atan(e_y / lookahead),   e_psi = wrap(psi_c - psi)
    tau_r = kp_yaw e_psi + kd_yaw (r_d - r)                                        [N m]

(d11(u) = c0 + c1 |u| + c2 u^2, the nominal ship's surge damping: the force that holds u_d). The
run is judged by a pose tolerance after a settling time (:class:`usv_mj.record.criteria.PoseTolerance`),
not by the paper's funnel.

**One implementation, two loops** (docs/controllers.md, "The compiled path"): the law is one numba
function, :func:`pd_law`, over arrays (the gains packed in a float64 vector, the nominal surge
damping, the diagnostics buffer). ``__call__`` calls it from Python; ``kernel()`` hands the same
function (through :func:`pd_kernel`, which returns the diagnostics as the compiled loop wants) and
the same arrays to :mod:`usv_mj.loop.compiled`, which inlines it into the generated loop. A run's
record is then the same bit for bit in either loop, and the compiled loop runs it at the speed of
the built-in laws (``python benchmarks/bench_core.py --plugin``). Both functions sit at module
level with ``cache=True``: the generated loop imports them by name, on every Dask worker too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.core.registry import CONTROLLERS
from usv_mj.physics.ship import wrap_angle
from usv_mj.record.criteria import PoseTolerance


@dataclass(frozen=True)
class PDGains:
    """The ``[controller]`` keys of ``kind = "example-pd"`` (the defaults suit the paper's hull)."""

    kp_surge: float = 35.0    # [N/m] surge force per metre of along-track error
    kd_surge: float = 100.0   # [N s/m] surge force per m/s of speed error
    kp_yaw: float = 16.0      # [N m/rad] yaw moment per radian of heading error
    kd_yaw: float = 26.0      # [N m s/rad] yaw moment per rad/s of yaw-rate error
    lookahead: float = 3.0    # [m] distance over which the lateral error is steered out

    def __post_init__(self) -> None:
        for name in ("kp_surge", "kd_surge", "kp_yaw", "kd_yaw", "lookahead"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0, got {value!r}")

    def as_array(self) -> np.ndarray:
        """The gains packed for :func:`pd_law` (G_* below)."""
        return np.array([self.kp_surge, self.kd_surge, self.kp_yaw, self.kd_yaw, self.lookahead])


G_KP_SURGE, G_KD_SURGE, G_KP_YAW, G_KD_YAW, G_LOOKAHEAD = range(5)


@njit(cache=True)
def pd_law(t, x, ref, g, d11, diag):
    """The law of the module docstring at time ``t`` [s], state ``x`` = (x, y, psi, u, v, r) and
    reference ``ref`` (usv_mj.core.layouts.REF_VECTOR_FIELDS: x_d, y_d, psi_d, x_d_dot, y_d_dot, r_d,
    u_d, ...); fills ``diag`` (along-track, cross-track, heading error) and returns (tau_u, tau_r)."""
    psi, u, r = x[2], x[3], x[5]
    x_d, y_d, psi_d, r_d, u_d = ref[0], ref[1], ref[2], ref[5], ref[6]
    c, s = math.cos(psi), math.sin(psi)
    e_x = c * (x_d - x[0]) + s * (y_d - x[1])
    e_y = -s * (x_d - x[0]) + c * (y_d - x[1])
    drag = (d11[0] + d11[1] * abs(u_d) + d11[2] * u_d * u_d) * u_d
    tau_u = drag + g[G_KP_SURGE] * e_x + g[G_KD_SURGE] * (u_d - u)
    e_psi = wrap_angle(psi_d + math.atan(e_y / g[G_LOOKAHEAD]) - psi)
    tau_r = g[G_KP_YAW] * e_psi + g[G_KD_YAW] * (r_d - r)
    diag[0], diag[1], diag[2] = e_x, e_y, e_psi
    return tau_u, tau_r


@njit(cache=True)
def pd_kernel(t, x, ref, g, d11, diag):
    """The compiled loop's kernel (usv_mj.core.kernels: ``fn(t, x, ref, *args) -> (tau_u, tau_r, diag)``)."""
    tau_u, tau_r = pd_law(t, x, ref, g, d11, diag)
    return tau_u, tau_r, diag


@CONTROLLERS.register("example-pd", options=PDGains)
class ExamplePD:
    """The law of the module docstring behind the controller interface (usv_mj.controllers.base)."""

    name = "example-pd"
    diagnostic_fields = ("along_track_error", "cross_track_error", "heading_error")
    criterion = PoseTolerance(settle_time_s=30.0, position_m=2.0, heading_deg=30.0)

    @classmethod
    def from_scenario(cls, gains: PDGains, scenario) -> "ExamplePD":
        return cls(gains, scenario.nominal_ship.d11)

    def __init__(self, gains: PDGains, d11=(0.0, 0.0, 0.0)):
        self.gains = gains
        self._g = gains.as_array()
        self._d11 = np.array([float(c) for c in d11])
        self._diag = np.zeros(len(self.diagnostic_fields))

    def reset(self) -> None:
        self._diag[:] = 0.0

    def kernel(self):
        """(pd_kernel, its arrays) for the compiled loop: the very arrays ``__call__`` uses."""
        from usv_mj.core.kernels import Kernel

        return Kernel(pd_kernel, (self._g, self._d11, self._diag))

    def __call__(self, t, state, reference):
        tau_u, tau_r = pd_law(float(t), np.asarray(state, dtype=np.float64), np.asarray(reference, dtype=np.float64),
                              self._g, self._d11, self._diag)
        return tau_u, tau_r, self._diag
