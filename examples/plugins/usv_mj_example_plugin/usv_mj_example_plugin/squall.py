"""``squall``: a gust in yaw, a disturbance kind d(t) (docs/model.md, "d(t)": write your own).

d(t) = (0, 0, moment) for start <= t < end, else (0, 0, 0), in the body frame [N, N, N m]: a
step of yaw moment that the plants (analytic and MuJoCo, Python and compiled loop) evaluate at
every RK4 stage time, as they do the paper's d(t). A scenario names it::

    [disturbance]
    kind = "squall"        # installed (entry point), or "usv_mj_example_plugin.squall:Squall"
    moment = 20.0
    start = 20.0
    end = 40.0

The contract (usv_mj.physics.disturbances): an options dataclass validated at construction, its
parameters packed by ``as_array()`` (at most 16 float64 words), and the class attribute ``kernel``,
a ``numba.njit`` function ``kernel(dp, t) -> (f_x [N], f_y [N], f_n [N m])`` reading them back
(``dp[0]`` is ``as_array()[0]``). Inheriting :class:`usv_mj.physics.disturbances.Disturbance`
gives ``force(t)`` from the same kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.core.registry import DISTURBANCES
from usv_mj.physics.disturbances import Disturbance

MOMENT, START, END = 0, 1, 2   # the packed words


@njit(cache=True)
def squall_kernel(dp, t):
    """The squall's d(t) [N, N, N m] at time ``t`` [s]: a 3-tuple (no allocation per call)."""
    if dp[START] <= t < dp[END]:
        return 0.0, 0.0, dp[MOMENT]
    return 0.0, 0.0, 0.0


@DISTURBANCES.register("squall")
@dataclass(frozen=True)
class Squall(Disturbance):
    """The ``[disturbance]`` keys of ``kind = "squall"``."""

    moment: float = 20.0   # [N m] yaw moment while the gust blows (positive turns to port)
    start: float = 20.0    # [s] the gust begins
    end: float = 40.0      # [s] the gust ends (start < end)

    kernel = squall_kernel

    def __post_init__(self) -> None:
        for name in ("moment", "start", "end"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"disturbance.{name} must be a finite number, got {getattr(self, name)!r}")
        if not self.start < self.end:
            raise ValueError(f"disturbance.end must be after start ({self.start!r} s), got {self.end!r}")

    def as_array(self) -> np.ndarray:
        out = np.zeros(3)
        out[MOMENT], out[START], out[END] = self.moment, self.start, self.end
        return out
