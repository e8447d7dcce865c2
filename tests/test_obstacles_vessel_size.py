"""Clearance and the planner use the vessel's own hull (its L, B), not the paper hull's.

Independent numbers: closed forms of the scaled hull (models/usv.xml's shell, x from -0.98 to
1.0 m and y +-0.38 m, scaled by L / 1.98 and B / 0.76: the bow tip, the sides and the stern of the
Otter at L = 2.0 m, B = 1.08 m), and the MuJoCo harbour plant's own collision (the other plant).
"""

import math

import numpy as np
import pytest

from usv_mj import load_scenario
from usv_mj.scenario.obstacles import from_tables
from usv_mj.obstacles.clearance import GeometricClearance, MuJoCoClearance
from usv_mj.plants.harbour import HarbourPlant
from usv_mj.scene.hull import HULL_RADIUS, vessel_collision_geoms, vessel_hull_radius


def test_scaled_hull_closed_forms_on_both_plants():
    otter = load_scenario(preset="paper", overrides={"vessel": {"kind": "otter"}})
    dims = otter.vessel.model.dimensions
    kx, ky = dims.L / 1.98, dims.B / 0.76
    bow, stern, side = 1.0 * kx, -0.98 * kx, 0.38 * ky
    obstacles = from_tables([
        {"center": [5.0, 0.0], "radius": 1.0},                        # 5 - 1 - bow
        {"kind": "box", "center": [0.0, 5.0], "size": [2.0, 2.0]},    # 4 - side
        {"kind": "box", "center": [-4.0, -0.2], "size": [2.0, 8.0]},  # stern - (-3)
    ])
    expected = [4.0 - bow, 4.0 - side, stern + 3.0]
    geometric = GeometricClearance(obstacles, dimensions=dims)
    np.testing.assert_allclose(geometric.update(0.0, np.zeros(6)), expected, atol=1e-9)
    # the paper hull's footprint is unchanged by the new argument
    np.testing.assert_allclose(GeometricClearance(obstacles).update(0.0, np.zeros(6)), [3.0, 3.62, 2.02], atol=1e-9)
    with HarbourPlant(otter.ship, otter.disturbance, obstacles, split=otter.vessel.model.split,
                      dimensions=dims) as plant:
        plant.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        monitor = MuJoCoClearance(plant)
        np.testing.assert_allclose(monitor.update(0.0), expected, atol=1e-5)
        # the far-obstacle bound is a lower bound for the vessel's hull (box corner or the bow)
        radius = max(math.hypot(stern, side), bow)
        assert monitor._bound[0] == pytest.approx(radius + 1.0, abs=1e-6)
    assert vessel_hull_radius(dims) == pytest.approx(radius, abs=1e-6)
    assert vessel_hull_radius(load_scenario(preset="paper").vessel.model.dimensions) is HULL_RADIUS
    geoms = vessel_collision_geoms(dims)
    assert geoms[0][2][:2] == pytest.approx((0.70 * kx, 0.38 * ky), rel=1e-12)


def test_the_planner_keeps_the_vessels_own_distance():
    from usv_mj.references.planner import SafetyEnvelope

    for kind in ("paper", "otter", "cybership2"):
        s = load_scenario(preset="paper", overrides={"vessel": {"kind": kind}})
        env = SafetyEnvelope.from_scenario(s, 0.3)
        d = s.vessel.model.dimensions
        kx, ky = d.L / 1.98, d.B / 0.76
        assert env.hull_radius == pytest.approx(max(math.hypot(0.98 * kx, 0.38 * ky), 1.0 * kx), abs=1e-6)
