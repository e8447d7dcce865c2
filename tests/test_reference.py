"""Reference trajectories: SPEC §4 checkpoints and the geometry of the other paths."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from usv_mj.references.trajectories import CircleReference, LineReference, PaperReference, WaypointReference


@pytest.mark.parametrize("t, expected", [(110, (66.000, 0.000, 0.0)), (200, (119.804, -3.582, -0.1805)),
                                         (300, (174.515, -26.770, -0.6580))])
def test_paper_checkpoints_of_spec_section_4(t, expected):
    ref = PaperReference(duration=300)
    x, y, psi = ref.evaluate(t)[:3]
    assert x == pytest.approx(expected[0], abs=1e-3)
    assert y == pytest.approx(expected[1], abs=1e-3)
    assert psi == pytest.approx(expected[2], abs=1e-4)


def test_paper_reference_equals_an_independent_integration():
    def rhs(t, s):
        r = 0.0 if t < 110 else -0.006 * math.sin(math.pi * (t - 100) / 500)
        return [0.6 * math.cos(s[2]), 0.6 * math.sin(s[2]), r]

    sol = solve_ivp(rhs, (0, 300), [0, 0, 0], method="DOP853", rtol=1e-12, atol=1e-12,
                    t_eval=[37.3, 110.0, 151.23, 250.0, 299.9], max_step=1.0)
    ref = PaperReference(duration=300)
    for k, t in enumerate(sol.t):
        out = ref.evaluate(t)
        assert out[:3] == pytest.approx(sol.y[:, k], abs=1e-7)
        assert out[5] == pytest.approx(rhs(t, sol.y[:, k])[2], abs=1e-15)


def test_line_circle_and_waypoints_are_consistent_unicycle_paths():
    for ref in (LineReference((1, 2), 30.0, 0.5), CircleReference((0, 10), 10.0, 0.6),
                WaypointReference([[0, 0], [20, 0], [20, 15], [0, 30]], 0.6, 4.0)):
        t = np.linspace(0.0, 80.0, 4001)
        s = ref.sample(t)
        # velocity of the position is u_d (cos psi_d, sin psi_d), and psi_dot = r_d
        vx = np.gradient(s[:, 0], t)
        vy = np.gradient(s[:, 1], t)
        inner = slice(5, -5)
        assert np.allclose(vx[inner], s[inner, 3], atol=2e-3)
        assert np.allclose(vy[inner], s[inner, 4], atol=2e-3)
        speed = np.hypot(s[:, 3], s[:, 4])
        assert np.allclose(speed, s[:, 6])
        psi = np.unwrap(s[:, 2])
        assert np.max(np.abs(np.diff(psi))) < 0.01  # heading is continuous


def test_circle_stays_on_its_circle_and_waypoints_pass_near_their_corners():
    c = CircleReference((3, 4), 7.0, 0.6)
    s = c.sample(np.linspace(0, 100, 50))
    assert np.allclose(np.hypot(s[:, 0] - 3, s[:, 1] - 4), 7.0)
    w = WaypointReference([[0, 0], [20, 0], [20, 20]], 1.0, 3.0)
    s = w.sample(np.linspace(0, 60, 6001))
    d = np.min(np.hypot(s[:, 0] - 20, s[:, 1] - 0))
    assert d == pytest.approx(3.0 * (1 / math.cos(math.pi / 4) - 1), abs=1e-3)  # fillet distance to the corner
    with pytest.raises(ValueError, match="turn_radius"):
        WaypointReference([[0, 0], [2, 0], [2, 2]], 1.0, 5.0)
