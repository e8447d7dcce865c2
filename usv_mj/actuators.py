"""The actuators of the hull: what it can realize of the quantized command (scenario ``[actuators]``).

The loop applies the channel in this order every control period: controller -> hysteresis
quantizer (the transmitted command Q(tau)) -> actuators (the force the thrusters realize, what
the plant receives). ``kind``:

- ``"unlimited"`` (the paper's presets: the paper has no thrust limits): the force is Q(tau);
- ``"box"``: surge force in [-max_reverse_n, max_surge_n] [N], yaw moment in [-max_yaw_nm, max_yaw_nm] [N m];
- ``"twin"``: two fixed thrusters ``separation_m`` apart, each with its own forward and reverse
  limit; the generalized forces are allocated to them and saturated per thruster.

``time_constant_s`` > 0 adds first-order thrust dynamics; ``surge_rate_n_s`` / ``yaw_rate_nm_s``
limit how fast the realized force may change. The model is implemented in :mod:`usv_mj.actuators`
(the same on both plants); on the MuJoCo plant the limits are also the actuators' ``ctrlrange``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

ACTUATOR_KINDS = ("unlimited", "box", "twin")


@dataclass(frozen=True)
class ActuatorSpec:
    """Actuator limits and dynamics (module docstring).

    Attributes
    ----------
    kind: "unlimited" | "box" | "twin".
    max_surge_n: box: largest forward surge force [N].
    max_reverse_n: box: largest astern surge force, a magnitude [N].
    max_yaw_nm: box: largest yaw moment magnitude [N m].
    separation_m: twin: lateral distance between the two thrusters [m].
    thruster_forward_n: twin: largest forward thrust of one thruster [N].
    thruster_reverse_n: twin: largest reverse thrust of one thruster, a magnitude [N].
    time_constant_s: first-order thrust lag [s] (0: none).
    surge_rate_n_s: largest rate of change of the surge force [N/s] (inf: none).
    yaw_rate_nm_s: largest rate of change of the yaw moment [N m/s] (inf: none).
    """

    kind: str = "unlimited"
    max_surge_n: float = math.inf
    max_reverse_n: float = math.inf
    max_yaw_nm: float = math.inf
    separation_m: float = 0.79
    thruster_forward_n: float = math.inf
    thruster_reverse_n: float = math.inf
    time_constant_s: float = 0.0
    surge_rate_n_s: float = math.inf
    yaw_rate_nm_s: float = math.inf

    def __post_init__(self) -> None:
        if self.kind not in ACTUATOR_KINDS:
            raise ValueError(f"kind must be one of {', '.join(ACTUATOR_KINDS)}, got {self.kind!r}")
        for name in ("max_surge_n", "max_reverse_n", "max_yaw_nm", "separation_m", "thruster_forward_n",
                     "thruster_reverse_n", "surge_rate_n_s", "yaw_rate_nm_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0 and not math.isnan(value)):
                raise ValueError(f"{name} must be > 0 (inf: no limit), got {value!r}")
        if not (isinstance(self.time_constant_s, (int, float)) and math.isfinite(self.time_constant_s)
                and self.time_constant_s >= 0):
            raise ValueError(f"time_constant_s must be >= 0 s, got {self.time_constant_s!r}")

    @property
    def unlimited(self) -> bool:
        """True when nothing limits or delays the force (the paper's reading)."""
        return (self.kind == "unlimited" and self.time_constant_s == 0.0
                and math.isinf(self.surge_rate_n_s) and math.isinf(self.yaw_rate_nm_s))

    def generalized_limits(self) -> tuple[float, float, float, float]:
        """(tau_u_min, tau_u_max, tau_r_min, tau_r_max) [N, N, N m, N m] the actuators can realize
        each on its own (twin: both thrusters together for surge, opposed for yaw)."""
        if self.kind == "box":
            return -self.max_reverse_n, self.max_surge_n, -self.max_yaw_nm, self.max_yaw_nm
        if self.kind == "twin":
            f, r, half = self.thruster_forward_n, self.thruster_reverse_n, self.separation_m / 2
            return -2 * r, 2 * f, -half * (f + r), half * (f + r)
        return -math.inf, math.inf, -math.inf, math.inf
