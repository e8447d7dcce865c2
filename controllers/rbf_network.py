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


#: exp(x) rounds to +0.0 below -745.13 (2^-1075): the exponential is skipped there, same value
EXP_UNDERFLOW = -746.0


@njit(cache=True)
def rbf_activations3(z, centres, sig_u, sig_v, sig_r, out):
    """S_j(Z) = exp(-|Z - c_j 1|^2 / sigma^2) (Eq. 12) for three widths at once into the rows of
    ``out`` (3 x n), each as the formula gives it, bit for bit. The distances |z - c_j 1|^2 are
    summed over i in the formula's order, but for all nodes at once (independent sums that vectorise; ``out[2]`` holds them until the last
    pass); a width equal to an earlier one reuses its exponentials (the paper's sigma_u = sigma_v);
    an exponent below :data:`EXP_UNDERFLOW` gives 0.0 without calling exp (most of the paper's
    nodes: its slow underflow path was half the cost of the network)."""
    inv_u = 1.0 / (sig_u * sig_u)
    inv_v = 1.0 / (sig_v * sig_v)
    inv_r = 1.0 / (sig_r * sig_r)
    v_is_u = sig_v == sig_u
    r_is_u = sig_r == sig_u
    r_is_v = sig_r == sig_v
    n = centres.shape[0]
    acc = out[2]
    for j in range(n):
        acc[j] = 0.0
    for i in range(z.shape[0]):
        zi = z[i]
        for j in range(n):
            d = zi - centres[j]
            acc[j] += d * d
    for j in range(n):
        a2 = acc[j]
        e = -a2 * inv_u
        a = math.exp(e) if not e <= EXP_UNDERFLOW else 0.0  # NaN stays NaN
        if v_is_u:
            b = a
        else:
            e = -a2 * inv_v
            b = math.exp(e) if not e <= EXP_UNDERFLOW else 0.0  # NaN stays NaN
        if r_is_u:
            c = a
        elif r_is_v:
            c = b
        else:
            e = -a2 * inv_r
            c = math.exp(e) if not e <= EXP_UNDERFLOW else 0.0  # NaN stays NaN
        out[0, j] = a
        out[1, j] = b
        out[2, j] = c
    return out
