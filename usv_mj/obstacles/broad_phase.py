"""The per-step broad phase of the clearance monitors: a uniform grid over the standing obstacles.

A step's clearance work must scale with the obstacles within reach of the hull, not with all of
them (usv_mj.obstacles.clearance, module docstring). :class:`StandingGrid` is built once per run
from the standing obstacles' bounding circles; :func:`grid_candidates` (native) lists the obstacles
of the cells that a square about the hull overlaps. The grid may return an obstacle out of reach
(the exact test follows), never miss one in reach (the boxes are padded; tests/test_obstacle_scale.py
checks it against brute force). Uniform grids for a broad phase: Ericson (2005), Real-Time
Collision Detection, section 7.1.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


class StandingGrid:
    """A uniform grid over standing obstacles' bounding boxes (the broad phase; module docstring).

    ``centers`` (n, 2) [m], ``radii`` (n,) [m] bounding radii, ``reach`` [m] the half side of the
    square a query covers (cells are about that size, so a query looks at 2 x 2 to 3 x 3 cells;
    larger when the scene is so spread that the cells would outnumber ``MAX_CELLS_PER_OBSTACLE``
    per obstacle). ``index``: the obstacles' own indices (their positions in the monitor's arrays).
    The boxes are padded by ``PAD`` so that a rounding at a cell edge can add a candidate, never
    lose one. :attr:`args` are :func:`grid_candidates`'s grid arguments."""

    MAX_CELLS_PER_OBSTACLE = 16
    PAD = 1e-6  # [m]

    def __init__(self, centers, radii, reach: float, index=None):
        centers = np.asarray(centers, dtype=float).reshape(-1, 2)
        radii = np.asarray(radii, dtype=float).reshape(-1)
        n = len(radii)
        index = np.arange(n, dtype=np.int64) if index is None else np.asarray(index, dtype=np.int64)
        pad = self.PAD + 1e-12 * (float(np.max(np.abs(centers))) if n else 0.0)
        lo = centers - (radii + pad)[:, None] if n else np.zeros((0, 2))
        hi = centers + (radii + pad)[:, None] if n else np.zeros((0, 2))
        x0, y0 = (lo.min(axis=0) if n else (0.0, 0.0))
        x1, y1 = (hi.max(axis=0) if n else (1.0, 1.0))
        h = max(float(reach), 1e-3)
        limit = self.MAX_CELLS_PER_OBSTACLE * max(n, 64)
        while math.ceil((x1 - x0) / h + 1) * math.ceil((y1 - y0) / h + 1) > limit:
            h *= 2.0
        nx, ny = int((x1 - x0) // h) + 1, int((y1 - y0) // h) + 1
        ix0 = np.clip(np.floor((lo[:, 0] - x0) / h).astype(np.int64), 0, nx - 1)
        ix1 = np.clip(np.floor((hi[:, 0] - x0) / h).astype(np.int64), 0, nx - 1)
        iy0 = np.clip(np.floor((lo[:, 1] - y0) / h).astype(np.int64), 0, ny - 1)
        iy1 = np.clip(np.floor((hi[:, 1] - y0) / h).astype(np.int64), 0, ny - 1)
        cells, items = [], []
        for j in range(n):
            for ix in range(ix0[j], ix1[j] + 1):
                for iy in range(iy0[j], iy1[j] + 1):
                    cells.append(ix * ny + iy)
                    items.append(index[j])
        cells = np.asarray(cells, dtype=np.int64)
        order = np.argsort(cells, kind="stable")
        self.items = np.asarray(items, dtype=np.int64)[order]
        self.start = np.searchsorted(cells[order], np.arange(nx * ny + 1)).astype(np.int64)
        self.geometry = np.array([x0, y0, h, float(reach) + pad])
        self.shape = np.array([nx, ny], dtype=np.int64)
        self.args = (self.geometry, self.shape, self.start, self.items)


@njit(cache=True)
def grid_candidates(geometry, shape, start, items, x, y, seen, stamp, out):
    """The obstacles of :class:`StandingGrid` cells that the square of half side ``geometry[3]``
    about (x, y) overlaps, each once (``seen`` (n,) int64 and ``stamp`` (1,) int64: scratch), into
    ``out``; returns how many."""
    x0, y0, h, reach = geometry[0], geometry[1], geometry[2], geometry[3]
    nx, ny = shape[0], shape[1]
    fx0, fx1 = np.floor((x - reach - x0) / h), np.floor((x + reach - x0) / h)
    fy0, fy1 = np.floor((y - reach - y0) / h), np.floor((y + reach - y0) / h)
    if not (fx1 >= 0.0 and fx0 < nx and fy1 >= 0.0 and fy0 < ny):  # also a NaN pose: no candidate
        return 0
    ix0, ix1 = int(max(fx0, 0.0)), int(min(fx1, nx - 1.0))
    iy0, iy1 = int(max(fy0, 0.0)), int(min(fy1, ny - 1.0))
    stamp[0] += 1
    s = stamp[0]
    count = 0
    for ix in range(ix0, ix1 + 1):
        for iy in range(iy0, iy1 + 1):
            c = ix * ny + iy
            for j in range(start[c], start[c + 1]):
                i = items[j]
                if seen[i] != s:
                    seen[i] = s
                    out[count] = i
                    count += 1
    return count


