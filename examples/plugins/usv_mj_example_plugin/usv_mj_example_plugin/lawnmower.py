"""``lawnmower``: a survey pattern, lanes of ``lane_length`` along +x and back, ``lane_spacing``
apart toward +y, joined by half circles of radius lane_spacing / 2 (so psi_d is continuous and
r_d = +-speed / radius in the turns). Closed form in the arc length s = speed t: lane k = floor(s /
P) with P = lane_length + pi lane_spacing / 2; the pattern goes on lane after lane. The speed is
constant and r_d constant on each lane and half circle, so ``pose`` returns u_dot = r_dot = 0 (the
reference's accelerations, docs/controllers.md; r_d jumps where a lane meets a turn).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from usv_mj.core.registry import TRAJECTORIES
from usv_mj.references.trajectories import Reference


@dataclass(frozen=True)
class LawnmowerOptions:
    """The ``[trajectory]`` keys of ``kind = "lawnmower"``."""

    speed: float = 0.6                       # [m/s] reference surge speed u_d
    start: tuple[float, float] = (0.0, 0.0)  # [m] start of the first lane (x, y)
    lane_length: float = 30.0                # [m] length of a lane
    lane_spacing: float = 8.0                # [m] distance between lanes (twice the turn radius)

    def __post_init__(self) -> None:
        for name in ("speed", "lane_length", "lane_spacing"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0, got {value!r}")


@TRAJECTORIES.register("lawnmower", options=LawnmowerOptions)
class LawnmowerReference(Reference):
    """The pattern of the module docstring; ``pose(t)`` is its closed form."""

    kind = "lawnmower"

    @classmethod
    def from_scenario(cls, options: LawnmowerOptions, scenario, *, duration: float) -> "LawnmowerReference":
        return cls(options)

    def __init__(self, options: LawnmowerOptions):
        super().__init__()
        self.spec = options

    def pose(self, t):
        o = self.spec
        radius = o.lane_spacing / 2
        period = o.lane_length + math.pi * radius
        s = o.speed * t
        k = math.floor(s / period)
        ds = s - k * period
        x0, y0 = o.start[0], o.start[1] + k * o.lane_spacing
        east = k % 2 == 0
        if ds < o.lane_length:  # a lane: east on even lanes, west on odd ones
            return (x0 + ds if east else x0 + o.lane_length - ds), y0, (0.0 if east else math.pi), 0.0, o.speed, 0.0, 0.0
        theta = (ds - o.lane_length) / radius   # the half circle up to the next lane
        cx, cy = (x0 + o.lane_length if east else x0), y0 + radius
        a = -math.pi / 2 + theta if east else -math.pi / 2 - theta
        psi = a + math.pi / 2 if east else a - math.pi / 2
        r = o.speed / radius if east else -o.speed / radius
        return (cx + radius * math.cos(a), cy + radius * math.sin(a), math.remainder(psi, 2 * math.pi), r, o.speed,
                0.0, 0.0)
