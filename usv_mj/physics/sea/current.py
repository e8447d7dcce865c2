"""Current (docs/sea.md §4) and the Ornstein-Uhlenbeck grids shared with the wind gusts.

v_c(t) = mean + [OU_x(t), OU_y(t)] in the earth frame (vector form, no angle wrapping). The OU
processes live on a grid with linear interpolation; v_c_dot is the slope of that interpolant. A grid
is generated ahead in chunks, each chunk from its own child SeedSequence (spawn key + chunk index)
and continuing the previous chunk's last value, so a value at time t never depends on how far ahead
the grid was generated (deterministic extension).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from usv_mj.physics.sea.layout import E_CURRENT_DT, E_CURRENT_ON, E_CURRENT_X, E_CURRENT_Y

CURRENT_GRID_STEP = 1.0  # s (docs/sea.md §4)
OU_CHUNK_POINTS = 4096


@njit(cache=True)
def _ou_recursion(z0, phi, noise, out):
    """out[0] = z0, out[i+1] = phi out[i] + sqrt(1 - phi^2) noise[i] (unit-variance OU), per column."""
    root = math.sqrt(1.0 - phi * phi)
    out[0, :] = z0
    for i in range(noise.shape[0] - 1):
        for d in range(out.shape[1]):
            out[i + 1, d] = phi * out[i, d] + root * noise[i, d]


class OrnsteinUhlenbeckGrid:
    """Unit-variance OU samples on a grid (``dims`` independent axes), extended deterministically.

    x_{i+1} = phi x_i + sqrt(1 - phi^2) w_i, phi = exp(-step / time_constant), x_0 ~ N(0, 1)
    (docs/sea.md §4). Multiply by sigma for the physical process.
    """

    def __init__(self, seed_sequence: np.random.SeedSequence, step: float, time_constant: float,
                 dims: int):
        if not (step > 0 and time_constant > 0):
            raise ValueError(f"OU grid: step and time_constant must be > 0, got {step!r}, {time_constant!r}")
        self._ss = seed_sequence
        self.step = float(step)
        self.phi = math.exp(-self.step / float(time_constant))
        self.dims = int(dims)
        self.values = np.zeros((0, self.dims))
        self._chunks = 0

    def _chunk_noise(self, c: int) -> np.ndarray:
        ss = np.random.SeedSequence(entropy=self._ss.entropy, spawn_key=tuple(self._ss.spawn_key) + (c,))
        return np.random.default_rng(ss).standard_normal((OU_CHUNK_POINTS, self.dims))

    def extend_to(self, t_end: float) -> bool:
        """Make the grid cover [0, t_end] (plus one point); True if it grew."""
        need = int(math.ceil(max(t_end, 0.0) / self.step)) + 2
        grew = False
        while self.values.shape[0] < need:
            noise = self._chunk_noise(self._chunks)
            if self._chunks == 0:
                z0 = noise[-1, :].copy()  # x_0 ~ N(0, 1): a draw of its own (the last one of chunk 0)
            else:
                z0 = self.phi * self.values[-1, :] + math.sqrt(1.0 - self.phi**2) * noise[-1, :]
            block = np.empty((OU_CHUNK_POINTS - 1, self.dims))
            _ou_recursion(z0, self.phi, np.ascontiguousarray(noise[:-1]), block)
            self.values = np.ascontiguousarray(np.concatenate([self.values, block]))
            self._chunks += 1
            grew = True
        return grew

    @property
    def t_end(self) -> float:
        return (self.values.shape[0] - 1) * self.step


@njit(cache=True)
def grid_interpolate(grid, col, step, t):
    """Linear interpolation of grid[:, col] at t (grid point i at t = i step) and its slope.

    Before 0 and past the last point the end value is held (slope 0).
    """
    n = grid.shape[0]
    if n == 0:
        return 0.0, 0.0
    if t <= 0.0:
        return grid[0, col], 0.0
    s = t / step
    i = int(math.floor(s))
    if i >= n - 1:
        return grid[n - 1, col], 0.0
    frac = s - i
    g0 = grid[i, col]
    dg = grid[i + 1, col] - g0
    return g0 + dg * frac, dg / step


@njit(cache=True)
def current_at(ep, current_grid, t):
    """Current v_c (earth x, y) [m/s] and its time derivative [m/s^2] at time t (docs/sea.md §4)."""
    if ep[E_CURRENT_ON] == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    dt = ep[E_CURRENT_DT]
    ox, ax = grid_interpolate(current_grid, 0, dt, t)
    oy, ay = grid_interpolate(current_grid, 1, dt, t)
    return ep[E_CURRENT_X] + ox, ep[E_CURRENT_Y] + oy, ax, ay
