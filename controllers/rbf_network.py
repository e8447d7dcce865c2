"""Gaussian radial-basis-function network of the paper's Eqs. 11-12 (docs/model.md §3 step 7).

S_j(Z) = exp(-|Z - c_j|^2 / sigma^2), with n nodes whose centres are c_j (1, ..., 1) for c_j evenly
spaced on [-span, span] (39 nodes on [-16, 16] in the paper). The network output is W . S(Z).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def node_centres(n_nodes: int = 39, span: float = 16.0) -> np.ndarray:
    """The scalar centre c_j of every node; node j sits at c_j (1, ..., 1)."""
    if n_nodes < 1:
        raise ValueError(f"rbf nodes must be >= 1, got {n_nodes!r}")
    if not span > 0:
        raise ValueError(f"rbf span must be > 0, got {span!r}")
    return np.linspace(-span, span, n_nodes)


@njit(cache=True)
def rbf_activations(z, centres, sigma, out):
    """Fill ``out[j] = exp(-|z - centres[j] * 1|^2 / sigma^2)`` (Eq. 12) and return it."""
    inv = 1.0 / (sigma * sigma)
    for j in range(centres.shape[0]):
        acc = 0.0
        c = centres[j]
        for i in range(z.shape[0]):
            d = z[i] - c
            acc += d * d
        out[j] = math.exp(-acc * inv)
    return out

