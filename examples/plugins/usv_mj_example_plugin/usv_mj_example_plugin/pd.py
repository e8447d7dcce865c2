"""``example-pd``: a PD law on the pose error of an underactuated surface vessel.

With the body-frame position error (e_x along the hull, e_y to port) of the reference point
(x_d, y_d) and the reference's speed u_d, heading psi_d and yaw rate r_d:

    tau_u = d11(u_d) u_d + kp_surge e_x + kd_surge (u_d - u)                       [N]
    psi_c = psi_d + atan(e_y / lookahead),   e_psi = wrap(psi_c - psi)
    tau_r = kp_yaw e_psi + kd_yaw (r_d - r)                                        [N m]

(d11(u) = c0 + c1 |u| + c2 u^2, the nominal ship's surge damping: the force that holds u_d). The
run is judged by a pose tolerance after a settling time (:class:`usv_mj.record.criteria.PoseTolerance`),
not by the paper's funnel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from usv_mj.record.criteria import PoseTolerance
from usv_mj.core.registry import CONTROLLERS


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


@CONTROLLERS.register("example-pd", options=PDGains)
class ExamplePD:
    """The law of the module docstring behind the controller interface (usv_mj.controllers.base)."""

    name = "example-pd"
    diagnostic_fields = ("along_track_error", "cross_track_error", "heading_error")
    criterion = PoseTolerance(settle_time_s=30.0, position_m=2.0, heading_deg=30.0)

    @classmethod
    def from_scenario(cls, gains: PDGains, scenario) -> "ExamplePD":
        return cls(gains, scenario.ship.d11)

    def __init__(self, gains: PDGains, d11=(0.0, 0.0, 0.0)):
        self.gains = gains
        self._d11 = tuple(float(c) for c in d11)
        self._diag = np.zeros(len(self.diagnostic_fields))

    def reset(self) -> None:
        self._diag[:] = 0.0

    def __call__(self, t, state, reference):
        g = self.gains
        x, y, psi, u, _v, r = state
        x_d, y_d, psi_d, _xd_dot, _yd_dot, r_d, u_d = reference
        c, s = math.cos(psi), math.sin(psi)
        e_x = c * (x_d - x) + s * (y_d - y)
        e_y = -s * (x_d - x) + c * (y_d - y)
        c0, c1, c2 = self._d11
        tau_u = (c0 + c1 * abs(u_d) + c2 * u_d * u_d) * u_d + g.kp_surge * e_x + g.kd_surge * (u_d - u)
        e_psi = math.remainder(psi_d + math.atan(e_y / g.lookahead) - psi, 2 * math.pi)
        tau_r = g.kp_yaw * e_psi + g.kd_yaw * (r_d - r)
        self._diag[0], self._diag[1], self._diag[2] = e_x, e_y, e_psi
        return tau_u, tau_r, self._diag
