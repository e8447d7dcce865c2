"""COLREGs classification and its lock (usv_mj.physics.colregs) against hand-worked geometries.

States in usv_mj's frame (x east, y north, psi counter-clockwise from east); the expected
situation is read off the picture and the sector limits of the module (a13 = 45, a14 = 13,
a15 = 0, the stern sector beyond 112.5 deg), never off the code's output.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.physics import colregs as cr
from usv_mj.physics.encounters import G_BETA, G_RANGE

NORTH, SOUTH, EAST, WEST = math.pi / 2, -math.pi / 2, 0.0, math.pi
CP = cr.ColregsParams().as_array()


def state(x, y, psi, u, v=0.0, r=0.0):
    return np.array([x, y, psi, u, v, r], dtype=float)


def both(own, target):
    """The situation seen from each vessel."""
    return cr.classify_pair(own, target), cr.classify_pair(target, own)


# --- classification of constructed geometries -----------------------------------------------------------


def test_head_on_at_an_offset_and_its_edge():
    own = state(0, 0, NORTH, 1.0)
    # 30 m off at 400 m: beta = alpha = atan(30/400) = 4.3 deg < 13: head-on for both, both give way
    assert both(own, state(30, 400, SOUTH, 1.0)) == (cr.HEAD_ON, cr.HEAD_ON)
    assert cr.role_of(cr.HEAD_ON) == "give_way"
    # offset 100 m at 400 m: beta = alpha = 14.04 deg > 13, target on own starboard bow, own on the
    # target's starboard bow too (alpha > 0): no crossing row matches either (both see the other on
    # starboard: that is a starboard-to-starboard passing, not a crossing)
    assert math.degrees(math.atan(100 / 400)) > 13.0
    assert both(own, state(100, 400, SOUTH, 1.0)) == (cr.NONE, cr.NONE)
    # the head-on limit itself: 12.9 deg in, 13.1 deg out (the target's course reciprocal)
    assert cr.classify(12.9, 12.9, 1.0, 1.0, CP) == cr.HEAD_ON
    assert cr.classify(13.1, -13.1, 1.0, 1.0, CP) == cr.CROSSING_GIVE_WAY


def test_crossing_from_starboard_and_from_port():
    own = state(0, 0, NORTH, 1.0)
    # target on the starboard bow (beta 45), own on its port bow (alpha -45): own gives way, it stands on
    assert both(own, state(100, 100, WEST, 1.0)) == (cr.CROSSING_GIVE_WAY, cr.CROSSING_STAND_ON)
    # the mirror from port
    assert both(own, state(-100, 100, EAST, 1.0)) == (cr.CROSSING_STAND_ON, cr.CROSSING_GIVE_WAY)
    assert cr.role_of(cr.CROSSING_GIVE_WAY) == "give_way" and cr.role_of(cr.CROSSING_STAND_ON) == "stand_on"
    # a target 100 deg on the starboard side still crosses (beta < 112.5); 115 deg is abaft the sector
    assert cr.classify(100.0, -30.0, 1.0, 1.0, CP) == cr.CROSSING_GIVE_WAY
    assert cr.classify(115.0, -30.0, 1.0, 1.0, CP) == cr.NONE


def test_overtaking_needs_the_overtaker_to_be_faster():
    ahead = state(0, 50, NORTH, 1.0)
    # own 2 m/s from 50 m astern (the target sees it at 180 deg, within 45 deg of own bow): overtaking
    assert both(state(0, 0, NORTH, 2.0), ahead) == (cr.OVERTAKING, cr.OVERTAKEN)
    assert cr.role_of(cr.OVERTAKING) == "give_way" and cr.role_of(cr.OVERTAKEN) == "stand_on"
    # own slower: no overtaking either way (the target draws ahead; no rule applies)
    assert both(state(0, 0, NORTH, 0.5), ahead) == (cr.NONE, cr.NONE)
    # equal speeds: neither is faster
    assert both(state(0, 0, NORTH, 1.0), ahead) == (cr.NONE, cr.NONE)
    # coming up 30 deg off the stern of the target (alpha = 150), target 30 deg off own bow
    # (|beta| = 30 < 45): still overtaking; 50 deg off own bow is not
    assert cr.classify(30.0, 150.0, 2.0, 1.0, CP) == cr.OVERTAKING
    assert cr.classify(50.0, 150.0, 2.0, 1.0, CP) == cr.NONE
    # the stern sector edge 112.5 deg (own seen 5 deg on the faster target's starboard bow)
    assert cr.classify(112.6, 5.0, 1.0, 2.0, CP) == cr.OVERTAKEN
    assert cr.classify(112.4, 5.0, 1.0, 2.0, CP) == cr.NONE
    # ... and 5 deg on its port bow, just forward of the sector: a crossing from starboard (alpha <= 0)
    assert cr.classify(112.4, -5.0, 1.0, 2.0, CP) == cr.CROSSING_GIVE_WAY


def test_the_classifier_is_symmetric_between_the_two_vessels():
    # swapping the vessels swaps beta and alpha: the situation from the target is the mirror one
    rng = np.random.default_rng(35)
    seen = set()
    for _ in range(3000):
        a = state(*rng.uniform(-100, 100, 2), rng.uniform(-4, 4), rng.uniform(0, 3), rng.uniform(-0.3, 0.3))
        b = state(*rng.uniform(-100, 100, 2), rng.uniform(-4, 4), rng.uniform(0, 3), rng.uniform(-0.3, 0.3))
        ab, ba = both(a, b)
        assert ba == cr.mirror(ab)
        seen.add(ab)
    assert seen == set(range(6))    # every situation was met


def test_tam_bucknall_table():
    TB = cr.tam_bucknall
    assert TB(0.0, 180.0) == cr.HEAD_ON                 # dead ahead, reciprocal
    assert TB(60.0, 170.0) == cr.HEAD_ON                # forward of the beam, within 180 +- 22.5
    assert TB(100.0, 180.0) == cr.NONE                  # bearing region 3 (90-112.5), reciprocal
    assert TB(45.0, 270.0) == cr.CROSSING_GIVE_WAY      # Imazu 2
    assert TB(-45.0, 90.0) == cr.CROSSING_STAND_ON      # Imazu 11's first target
    assert TB(0.0, 0.0) == cr.OVERTAKING                # ahead on the same course (no speed test)
    assert TB(180.0, 0.0) == cr.OVERTAKEN
    assert TB(-67.5, 45.0) == cr.OVERTAKING             # Imazu 4: course difference 45 < 67.5 -> region 1
    # region edges are closed below: 22.5 is region 2, 337.5 region 1; course 67.5 is region 2
    assert TB(22.5, 60.0) == cr.OVERTAKING and TB(22.5, 67.5) == cr.NONE and TB(-22.5, 67.5) == cr.CROSSING_STAND_ON
    # the Woerner classifier calls Imazu 4 a crossing from port (own stands on)
    own, target = state(0, 0, NORTH, 1.0), state(-70.71, 29.29, NORTH - math.radians(45.0), 1.0)
    assert cr.classify_pair(own, target) == cr.CROSSING_STAND_ON
    assert cr.classify_pair_tam_bucknall(own, target) == cr.OVERTAKING


def test_params_are_checked():
    with pytest.raises(ValueError, match="stage"):
        cr.ColregsParams(stage2_L=5.0, stage3_L=7.5)
    with pytest.raises(ValueError, match="a14_deg"):
        cr.ColregsParams(a14_deg=0.0)
    with pytest.raises(ValueError, match="release_factor"):
        cr.ColregsParams(release_factor=0.9)
    p = cr.ColregsParams()
    assert (p.a13_deg, p.a14_deg, p.a15_deg, p.stern_deg) == (45.0, 13.0, 0.0, 112.5)
    assert p.stage_ranges_m(2.0) == (50.0, 15.0, 8.0)


# --- the lock --------------------------------------------------------------------------------------------


def straight(t, x0, y0, psi, speed):
    """(T, 6) states of a vessel on a straight line at constant speed."""
    return np.column_stack([x0 + speed * math.cos(psi) * t, y0 + speed * math.sin(psi) * t, np.full_like(t, psi),
                            np.full_like(t, speed), np.zeros_like(t), np.zeros_like(t)])


def test_head_on_locks_at_stage_two_and_releases_when_passed():
    # L = 2 m: stage 2 = 25 L = 50 m.  Own northbound at 1 m/s from the origin, the target 5 m east and
    # 200 m north, southbound at 1 m/s: the range is sqrt(25 + (200 - 2t)^2).
    t = np.arange(0.0, 150.0)
    states = np.stack([straight(t, 0, 0, NORTH, 1.0), straight(t, 5, 200, SOUTH, 1.0)], axis=1)
    sit = cr.situation_series(states, [2.0, 2.0])
    # entry: range <= 50 <=> 200 - 2t <= sqrt(2500 - 25) = 49.75 <=> t >= 75.12: the sample t = 76
    t_in = (200 - math.sqrt(2500 - 25)) / 2
    first = int(np.argmax(sit[:, 0, 1] != cr.NONE))
    assert t[first] == math.ceil(t_in) == 76
    # passed: each sees the other more than 112.5 deg off the bow: atan2(5, y) > 112.5 deg with
    # y = 200 - 2t, i.e. y < -5 tan(22.5 deg) = -2.07, t > 101.04: the sample t = 102
    t_out = (200 + 5 * math.tan(math.radians(22.5))) / 2
    locked = np.flatnonzero(sit[:, 0, 1] == cr.HEAD_ON)
    assert (t[locked[0]], t[locked[-1]]) == (76.0, math.floor(t_out))
    assert np.all(sit[locked[-1] + 1:, 0, 1] == cr.NONE)      # released, and TCPA < 0 now: not again
    np.testing.assert_array_equal(sit[:, 1, 0], sit[:, 0, 1])  # head-on from both sides


def test_overtaking_holds_until_the_range_opens():
    # own northbound at 2 m/s, the target 3 m east and 20 m ahead at 1 m/s; L = 2: stage 2 = 50 m,
    # release beyond 1.05 x 50 = 52.5 m. In range and closing at t = 0 (TCPA = 20 s): locked at once.
    t = np.arange(0.0, 100.0)
    states = np.stack([straight(t, 0, 0, NORTH, 2.0), straight(t, 3, 20, NORTH, 1.0)], axis=1)
    sit = cr.situation_series(states, [2.0, 2.0])
    assert sit[0, 0, 1] == cr.OVERTAKING and sit[0, 1, 0] == cr.OVERTAKEN
    # own passes (t > 20) and sees the target astern, but the target sees own ahead: held; the range
    # sqrt(9 + (t - 20)^2) passes 50 m at t = 69.9 (held in the band) and 52.5 m at t = 72.41
    t_release = 20 + math.sqrt(52.5 ** 2 - 9)
    held = np.flatnonzero(sit[:, 0, 1] == cr.OVERTAKING)
    assert held[0] == 0 and t[held[-1]] == math.floor(t_release) == 72
    assert math.sqrt(9 + (70 - 20) ** 2) > 50.0 and sit[70, 0, 1] == cr.OVERTAKING
    assert np.all(sit[73:, 0, 1] == cr.NONE)


def test_entry_gates_tcpa_and_dcpa():
    t = np.arange(0.0, 60.0)
    # receding inside stage 2 (TCPA < 0 throughout): never locked
    states = np.stack([straight(t, 0, 0, NORTH, 1.0), straight(t, 0, -10, SOUTH, 1.0)], axis=1)
    assert np.all(cr.situation_series(states, [2.0, 2.0]) == cr.NONE)
    # a head-on 5 m (2.5 L) off with a DCPA gate of 1 L: never locked; with 3 L: locked
    t = np.arange(0.0, 100.0)
    states = np.stack([straight(t, 0, 0, NORTH, 1.0), straight(t, 5, 120, SOUTH, 1.0)], axis=1)
    assert np.all(cr.situation_series(states, [2.0, 2.0], cr.ColregsParams(dcpa_gate_L=1.0)) == cr.NONE)
    assert np.any(cr.situation_series(states, [2.0, 2.0], cr.ColregsParams(dcpa_gate_L=3.0)) == cr.HEAD_ON)


def test_tracker_steps_every_pair_and_uses_the_larger_length():
    # three vessels: own (L = 2) northbound; a 4 m target at (90, 90) westbound, crossing from starboard
    # (stage 2 for this pair: 25 x 4 = 100 m, from the larger length; its range sqrt(2) 90 = 127.3 m at
    # the start); a 2 m target at (-60, 60) eastbound, crossing from port (stage 2: 50 m; range 84.9 m)
    t = np.arange(0.0, 30.0)
    states = np.stack([straight(t, 0, 0, NORTH, 1.0), straight(t, 90, 90, WEST, 1.0),
                       straight(t, -60, 60, EAST, 1.0)], axis=1)
    tracker = cr.ColregsTracker([2.0, 4.0, 2.0])
    series = cr.situation_series(states, [2.0, 4.0, 2.0])
    for k in range(t.size):
        sit = tracker.step(states[k])
        np.testing.assert_array_equal(sit, series[k])
        for i in range(3):
            for j in range(3):
                assert sit[j, i] == cr.mirror(sit[i, j])
        assert tracker.geometry[0, 1, G_RANGE] == pytest.approx(math.sqrt(2) * (90 - t[k]))
        assert tracker.geometry[0, 1, G_BETA] == pytest.approx(45.0)
    # the 4 m pair locks once sqrt(2)(90 - t) <= 100, t >= 19.29: at t = 20; the 2 m pair with range
    # sqrt(2)(60 - t) <= 50 only from t = 24.65: at t = 25
    first_01 = int(np.argmax(series[:, 0, 1] != cr.NONE))
    first_02 = int(np.argmax(series[:, 0, 2] != cr.NONE))
    assert t[first_01] == math.ceil(90 - 100 / math.sqrt(2)) == 20
    assert t[first_02] == math.ceil(60 - 50 / math.sqrt(2)) == 25
    assert series[-1, 0, 1] == cr.CROSSING_GIVE_WAY and series[-1, 0, 2] == cr.CROSSING_STAND_ON
    # the two targets, westbound on y = 90 and eastbound on y = 60, pass port to port 30 m apart: in
    # their stage 2 (100 m) each sees the other more than atan(30 / 100) = 16.7 deg off the bow on its
    # port side, wider than the head-on 13 deg, and no crossing row has both on port: no rule
    assert math.degrees(math.atan(30 / 100)) > 13.0
    assert series[-1, 1, 2] == cr.NONE
