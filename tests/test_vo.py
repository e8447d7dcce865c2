"""Velocity obstacles with COLREGs constraints (controllers/vo.py, issue 35 item 4's second method): the
head-on and the crossings of tests/test_sbmpc.py with ``vo``, and its two predicates by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.controllers.vo import VOGains, breaks_colregs, in_velocity_obstacle, vo_costs
from usv_mj.core.errors import ScenarioError
from usv_mj.record.encounters import SAFETY_DOMAIN_L

from test_fleet import HEAD_ON, NORTH
from test_sbmpc import DT, U, avoiding, centre_range, crossing, crossing_time, first_turn_sign, right_of_start_line, run


def test_head_on_both_alter_to_starboard_and_keep_out_of_the_safety_domain():
    """test_fleet's head-on (15 L apart at 0.6 m/s), both with vo, analytic plant: each turns to
    starboard first, passes port to port to the right of its line, centres more than 3 L apart."""
    sc, rec = run("analytic", [avoiding(v, "vo") for v in HEAD_ON], 36.0)
    length = sc.vessels[0].scenario.vessel.model.dimensions.L
    rng = centre_range(rec)
    k = int(np.argmin(rng))
    assert rec.status == "completed" and rng.min() > SAFETY_DOMAIN_L * length
    for entry in HEAD_ON:
        name, (x0, y0, psi0) = entry["name"], entry["initial"]["eta"]
        r = rec[name]
        assert first_turn_sign(r, psi0) == -1.0, name
        assert r["course_offset"][r["course_offset"] != 0.0][0] < 0.0, name
        assert right_of_start_line(r, x0, y0, psi0)[k] > 0.0, name
        other = rec["target" if name == "own" else "own"]
        lx, ly = other["x"][k] - r["x"][k], other["y"][k] - r["y"][k]
        assert math.cos(r["psi"][k]) * ly - math.sin(r["psi"][k]) * lx > 0.0, name   # the other to port


def test_crossing_from_starboard_gives_way_astern_and_from_port_stands_on():
    """test_sbmpc's crossings with vo: from starboard (target keeping course) the own ship turns to
    starboard and crosses the target's track astern of it; from port (both vo) it keeps (0, 1) while
    the target is farther than 7.5 L and never turns to port, the target giving way astern of it."""
    d, own, target = crossing("starboard", "keep")
    sc, rec = run("analytic", [{**own, "controller": {**own["controller"], "kind": "vo"}}, target], 50.0)
    length = sc.vessels[0].scenario.vessel.model.dimensions.L
    o, t = rec["own"], rec["target"]
    assert first_turn_sign(o, NORTH) == -1.0
    k = crossing_time(o["y"], d)
    assert t["x"][k] < o["x"][k] and centre_range(rec).min() > SAFETY_DOMAIN_L * length

    d, own, target = crossing("port", "sbmpc")
    vessels = [{**v, "controller": {**v["controller"], "kind": "vo"}} for v in (own, target)]
    sc, rec = run("analytic", vessels, 45.0)
    o, t = rec["own"], rec["target"]
    rng = centre_range(rec)
    far = rng > VOGains().stand_on_range_L * length
    assert far[:int(10.0 / DT)].all()
    assert np.all(o["course_offset"][far] == 0.0) and np.all(o["speed_factor"][far] == 1.0)
    assert np.all(o["course_offset"] <= 0.0) and first_turn_sign(t, 0.0) == -1.0
    k = crossing_time(t["x"], 0.0)
    assert o["y"][k] > t["y"][k] and rng.min() > SAFETY_DOMAIN_L * length


def test_the_velocity_obstacle_and_the_colregs_constraint_by_hand():
    """A target 20 m dead ahead coming at 0.6 m/s, r = 10 m, t_max = 60 s. Straight on at 0.6 m/s:
    w = (0, 1.2), the centres meet: inside. A course 40 deg to starboard at 0.6 m/s:
    w = (0.6 sin 40, 0.6 cos 40 + 0.6); the miss distance is 20 |w_x| / |w| = 20 sin(atan2(w_x, w_y)),
    worked out below, against r. Moving away (southbound, slower than the target): not closing.
    The constraint: passing with the target on the own ship's starboard side (a turn to port)
    breaks it, a turn to starboard keeps it, a candidate that moves away never breaks it."""
    assert in_velocity_obstacle(0.0, 20.0, 0.0, 1.2, 10.0, 60.0)
    c = math.radians(40.0)
    wx, wy = U * math.sin(c), U * math.cos(c) + U
    miss = 20.0 * abs(wx) / math.hypot(wx, wy)          # 20 sin(20 deg) = 6.84 m: still inside 10 m
    assert miss == pytest.approx(20.0 * math.sin(math.radians(20.0)))
    assert in_velocity_obstacle(0.0, 20.0, wx, wy, 10.0, 60.0) == (miss < 10.0)
    assert not in_velocity_obstacle(0.0, 20.0, wx, wy, 6.0, 60.0)
    assert not in_velocity_obstacle(0.0, 20.0, 0.0, -0.1, 10.0, 60.0)   # w pointing away: opening
    assert not in_velocity_obstacle(0.0, 20.0, 0.0, 1.2, 10.0, 5.0)     # within 5 s the range only falls to 14 m
    assert breaks_colregs(0.0, 20.0, -wx, wy)        # to port: the target passes on own starboard
    assert not breaks_colregs(0.0, 20.0, wx, wy)     # to starboard
    assert not breaks_colregs(0.0, 20.0, -wx, -0.1)  # moving away
    # the cost: the preferred velocity (dead ahead: neither side, no breach) costs 0 + 1000 (in the cone)
    g = VOGains()
    offsets, factors = g.offsets(), g.factors()
    costs = np.zeros((offsets.size, factors.size))
    vo_costs(0.0, 0.0, 0.0, U, NORTH, U, U, offsets, factors, np.array([[0.0, 20.0, 0.0, -U]]),
             np.array([10.0]), np.array([1.0]), 60.0, 1000.0, 100.0, costs)
    assert costs[0, 0] == pytest.approx(1000.0)
    a = int(np.flatnonzero(np.isclose(offsets, -c))[0])
    assert costs[a, 0] == pytest.approx((2 - 2 * math.cos(c)) * 1.0 + (1000.0 if miss < 10.0 else 0.0))
    best = np.unravel_index(int(np.argmin(costs)), costs.shape)
    assert offsets[best[0]] < 0.0 and costs[best] < 100.0   # the cheapest leaves the cone to starboard


def test_vo_alone_is_its_path_follower_and_its_gains_are_checked():
    base = {"duration": 3.0, "control_period": DT, "baseline": {"enabled": False}, "plant": {"kind": "analytic"},
            "trajectory": {"kind": "line", "start": [0.0, 0.0], "heading_deg": 30.0, "speed": U}}
    recs = [simulate(load_scenario(preset="paper", overrides={**base, "controller": {"kind": k, "crab_compensation": False}}))
            for k in ("vo", "los")]
    assert recs[0].metadata["loop"] == "compiled"
    for c in ("x", "y", "psi", "tau_u", "tau_r"):
        assert np.array_equal(recs[0][c], recs[1][c]), c
    for table, message in (({"n_speeds": 1}, "n_speeds must be an integer >= 2"),
                           ({"heading_span_deg": 200.0}, "heading_span_deg must be in"),
                           ({"t_max_L": 0.0}, "t_max_L must be > 0")):
        with pytest.raises(ScenarioError, match=message):
            load_scenario(preset="paper", overrides={"controller": {"kind": "vo", **table}})
    g = VOGains()
    assert np.degrees(g.offsets())[:5] == pytest.approx([0.0, -5.0, 5.0, -10.0, 10.0]) and g.offsets().size == 49
    assert g.factors() == pytest.approx([1.0, 0.75, 0.5, 0.25, 0.0])
