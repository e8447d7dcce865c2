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



@njit(cache=True)
def rbf_activations3(z, centres, sig_u, sig_v, sig_r, out):
    """:func:`rbf_activations` for three widths at once into the rows of ``out`` (3 x n), bit for bit
    the same values: the distance |z - c_j 1|^2 is computed once per node for the three, and a width
    equal to an earlier one reuses its exponentials (the paper's sigma_u = sigma_v)."""
    inv_u = 1.0 / (sig_u * sig_u)
    inv_v = 1.0 / (sig_v * sig_v)
    inv_r = 1.0 / (sig_r * sig_r)
    v_is_u = sig_v == sig_u
    r_is_u = sig_r == sig_u
    r_is_v = sig_r == sig_v
    for j in range(centres.shape[0]):
        acc = 0.0
        c = centres[j]
        for i in range(z.shape[0]):
            d = z[i] - c
            acc += d * d
        a = math.exp(-acc * inv_u)
        out[0, j] = a
        b = a if v_is_u else math.exp(-acc * inv_v)
        out[1, j] = b
        out[2, j] = a if r_is_u else (b if r_is_v else math.exp(-acc * inv_r))
    return out
