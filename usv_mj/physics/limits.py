"""The one check of divergence: the state against ``[limits]`` (:class:`usv_mj.scenario.spec.LimitsSpec`).

A native function, so that the Python loop, the compiled loop (usv_mj.loop.compiled) and the
dm_control tasks' per-step kernel (usv_mj.envs.native) all ask the same question.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def within_limits(x, ex, ey, max_speed, max_yaw_rate, max_distance):
    """True while |u|, |v| < ``max_speed`` [m/s], |r| < ``max_yaw_rate`` [rad/s], the distance to the
    reference |ex| + |ey| < ``max_distance`` [m] and the heading is finite (a NaN fails every test)."""
    return (abs(x[3]) < max_speed and abs(x[4]) < max_speed and abs(x[5]) < max_yaw_rate
            and abs(ex) + abs(ey) < max_distance and math.isfinite(x[2]))
