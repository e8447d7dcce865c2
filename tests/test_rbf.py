"""The RBF network's activations (Eq. 12) against the formula evaluated by hand in Python.

S_j(Z) = exp(-|Z - c_j 1|^2 / sigma^2). ``rbf_activations3`` sums the distances of all nodes at
once and skips the exponential where it underflows; both must leave every value as the plain
formula gives it, bit for bit (the two loops and the recorded runs depend on it).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.controllers.rbf_network import node_centres, rbf_activations3


def _by_hand(z, centres, sigma):
    out = []
    for c in centres:
        acc = 0.0
        for zi in z:  # the same order of summation as Eq. 12 read left to right
            acc += (zi - c) * (zi - c)
        out.append(math.exp(-acc * (1.0 / (sigma * sigma))))
    return np.array(out)


@pytest.mark.parametrize("widths", [(0.7, 0.7, 1.5), (0.7, 0.9, 1.5), (1.5, 0.7, 0.7), (3.0, 3.0, 3.0),
                                    (0.05, 40.0, 7.0)])
def test_three_widths_equal_the_formula_bit_for_bit(widths):
    rng = np.random.default_rng(7)
    centres = node_centres()
    out3 = np.empty((3, centres.size))
    for scale in (1e-3, 0.3, 1.0, 4.0, 20.0):
        for _ in range(40):
            z = rng.normal(size=9) * scale
            rbf_activations3(z, centres, *widths, out3)
            for row, sigma in enumerate(widths):
                expected = _by_hand(z, centres, sigma)
                assert np.array_equal(out3[row].view(np.int64), expected.view(np.int64))


def test_underflow_edge_keeps_subnormals_and_zeros():
    # one node, z on a line so that |z - c 1|^2 / sigma^2 crosses exp's underflow (-708 .. -745.13)
    centres = np.array([0.0])
    out3 = np.empty((3, 1))
    seen_subnormal = seen_zero = False
    for e in np.linspace(700.0, 760.0, 601):
        z = np.full(9, math.sqrt(e / 9.0))
        rbf_activations3(z, centres, 1.0, 1.0, 1.0, out3)
        expected = _by_hand(z, centres, 1.0)[0]
        assert out3[0, 0] == expected and math.copysign(1.0, out3[0, 0]) == 1.0
        seen_subnormal |= 0.0 < expected < 2.2250738585072014e-308
        seen_zero |= expected == 0.0
    assert seen_subnormal and seen_zero


def test_the_paper_network_peaks_at_the_nearest_centre():
    centres = node_centres(39, 16.0)
    out3 = np.empty((3, 39))
    z = np.full(9, centres[25])  # exactly on node 25: S = 1 there, exp(-9 h^2 / sigma^2) next door
    rbf_activations3(z, centres, 0.7, 0.7, 1.5, out3)
    h = centres[1] - centres[0]
    assert out3[0, 25] == 1.0 and out3[2, 25] == 1.0
    assert out3[0, 24] == pytest.approx(math.exp(-9 * h * h / 0.49), rel=1e-12)
    assert out3[2, 26] == pytest.approx(math.exp(-9 * h * h / 2.25), rel=1e-12)


def test_a_nan_input_gives_nan_activations_as_the_formula_does():
    # a diverged state must not be hidden from the controller: exp(NaN) is NaN, not the underflow's 0
    centres = node_centres()
    out3 = np.empty((3, centres.size))
    z = np.array([math.nan, 0.1, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    rbf_activations3(z, centres, 0.7, 0.9, 1.5, out3)
    assert np.isnan(out3).all() and np.isnan(_by_hand(z, centres, 0.7)).all()
