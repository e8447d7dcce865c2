"""Encounter geometry (usv_mj.physics.encounters) against hand calculations on constructed geometries.

Every expected number is worked out here from the picture (positions, headings and speeds chosen so
that the closest point of approach can be found by hand), in compass degrees (clockwise from north,
+ = starboard), for states written in usv_mj's frame: x east, y north, psi counter-clockwise from
east, v to port. A vessel heading north has psi = pi/2, south -pi/2, east 0, west pi.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.physics import encounters as enc

NORTH, SOUTH, EAST, WEST = math.pi / 2, -math.pi / 2, 0.0, math.pi


def state(x, y, psi, u, v=0.0, r=0.0):
    return np.array([x, y, psi, u, v, r], dtype=float)


def test_head_on_at_a_known_offset():
    # own at the origin northbound at 2 m/s; the target 400 m north and 30 m east, southbound at 3 m/s.
    # d = (30, 400), w = (0, -3) - (0, 2) = (0, -5): TCPA = -(400 * -5) / 25 = 80 s, and then
    # d + w TCPA = (30, 0): DCPA = 30 m, the lateral offset.
    own, target = state(0, 0, NORTH, 2.0), state(30, 400, SOUTH, 3.0)
    g = enc.encounter(own, target)
    assert g.range_m == pytest.approx(math.sqrt(30 ** 2 + 400 ** 2), rel=1e-12)
    assert g.tcpa_s == pytest.approx(80.0, rel=1e-12)
    assert g.dcpa_m == pytest.approx(30.0, abs=1e-9)
    off = math.degrees(math.atan(30 / 400))        # 4.29 deg to starboard of the bow
    assert g.true_bearing_deg == pytest.approx(off, abs=1e-9)
    assert g.relative_bearing_deg == pytest.approx(off, abs=1e-9)
    # own ship seen from the southbound target: bearing 180 + off, its heading 180 -> off to its starboard
    assert g.contact_angle_deg == pytest.approx(off, abs=1e-9)
    assert g.course_difference_deg == pytest.approx(180.0, abs=1e-9)


def test_crossing_from_starboard_and_from_port():
    # Imazu case 2 at R = 100 m: the target 100 m east and 100 m north, westbound, both at 1 m/s:
    # both reach (0, 100) at t = 100 s.  d = (100, 100), w = (-1, -1): TCPA = 200 / 2 = 100 s, DCPA = 0.
    own = state(0, 0, NORTH, 1.0)
    g = enc.encounter(own, state(100, 100, WEST, 1.0))
    assert (g.range_m, g.tcpa_s) == (pytest.approx(100 * math.sqrt(2)), pytest.approx(100.0))
    assert g.dcpa_m == pytest.approx(0.0, abs=1e-9)
    assert g.true_bearing_deg == pytest.approx(45.0)
    assert g.relative_bearing_deg == pytest.approx(45.0)        # starboard bow
    assert g.contact_angle_deg == pytest.approx(-45.0)          # own ship on the target's port bow
    assert g.course_difference_deg == pytest.approx(270.0)      # 270 - 0
    # the mirror: from port, eastbound
    g = enc.encounter(own, state(-100, 100, EAST, 1.0))
    assert g.true_bearing_deg == pytest.approx(315.0)
    assert g.relative_bearing_deg == pytest.approx(-45.0)
    assert g.contact_angle_deg == pytest.approx(45.0)
    assert g.course_difference_deg == pytest.approx(90.0)
    assert (g.tcpa_s, g.dcpa_m) == (pytest.approx(100.0), pytest.approx(0.0, abs=1e-9))


def test_overtaking_faster_and_slower():
    # own northbound at 2 m/s, a target 50 m ahead northbound at 1 m/s: w = (0, -1), TCPA = 50 s, DCPA 0
    own = state(0, 0, NORTH, 2.0)
    target = state(0, 50, NORTH, 1.0)
    g = enc.encounter(own, target)
    assert (g.relative_bearing_deg, g.contact_angle_deg) == (pytest.approx(0.0), pytest.approx(180.0))
    assert g.tcpa_s == pytest.approx(50.0) and g.dcpa_m == pytest.approx(0.0, abs=1e-9)
    # own slower (0.5 m/s): the target draws away, w = (0, 0.5): TCPA = -(50 * 0.5) / 0.25 = -100 s (the
    # two were together 100 s ago: d + w TCPA = 0)
    g = enc.encounter(state(0, 0, NORTH, 0.5), target)
    assert g.tcpa_s == pytest.approx(-100.0) and g.dcpa_m == pytest.approx(0.0, abs=1e-9)


def test_parallel_tracks_have_tcpa_zero_by_definition():
    # same velocity 20 m abeam: w = 0, every time is the closest: TCPA = 0, DCPA = the range
    own, target = state(0, 0, NORTH, 1.5), state(20, 0, NORTH, 1.5)
    assert enc.cpa(own, target) == (0.0, pytest.approx(20.0))
    # the same heading written another way (psi + 2 pi) leaves |w|^2 at rounding level: still 0
    target = state(20, 0, NORTH + 2 * math.pi, 1.5)
    tcpa, dcpa = enc.cpa(own, target)
    assert tcpa == 0.0 and dcpa == pytest.approx(20.0)
    assert enc.relative_bearing_deg(own, target) == pytest.approx(90.0)   # abeam to starboard


def test_receding_pair_has_negative_tcpa():
    # own northbound, the target 100 m astern southbound, both 1 m/s: d = (0, -100), w = (0, -2):
    # TCPA = -(200) / 4 = -50 s (they passed 50 s ago), DCPA = |d + 50 (0, 2)| = 0
    own, target = state(0, 0, NORTH, 1.0), state(0, -100, SOUTH, 1.0)
    g = enc.encounter(own, target)
    assert g.tcpa_s == pytest.approx(-50.0)
    assert g.dcpa_m == pytest.approx(0.0, abs=1e-9)
    assert g.relative_bearing_deg == 180.0                      # dead astern is +180, never -180
    assert g.contact_angle_deg == pytest.approx(180.0)


def test_relative_bearing_signs_follow_the_bow():
    # heading east (psi = 0): a target due north is on the port beam (-90), due south on starboard (+90)
    own = state(0, 0, EAST, 1.0)
    assert enc.relative_bearing_deg(own, state(0, 10, 0, 0)) == pytest.approx(-90.0)
    assert enc.relative_bearing_deg(own, state(0, -10, 0, 0)) == pytest.approx(90.0)
    assert enc.true_bearing_deg(own, state(0, -10, 0, 0)) == pytest.approx(180.0)
    assert enc.heading_deg(own) == pytest.approx(90.0)


def test_course_over_ground_is_the_velocity_and_heading_the_bow():
    # heading north with u = 1 forward and v = 1 to port (west): velocity R(psi)(u, v) = (-1, 1),
    # so the track runs north-west (course 315) at sqrt(2) m/s while the bow points north (000)
    s = state(0, 0, NORTH, 1.0, 1.0)
    vx, vy = enc.velocity_over_ground(s)
    assert (vx, vy) == (pytest.approx(-1.0), pytest.approx(1.0))
    assert enc.speed_over_ground(s) == pytest.approx(math.sqrt(2))
    assert enc.course_over_ground_deg(s) == pytest.approx(315.0)
    assert enc.heading_deg(s) == pytest.approx(0.0)
    # a target seen from it: the bearing from the bow uses the heading, the course difference the track
    target = state(10, 0, NORTH, 1.0)
    g = enc.encounter(s, target)
    assert g.relative_bearing_deg == pytest.approx(90.0)
    assert g.course_difference_deg == pytest.approx(45.0)      # 000 - 315
    # at rest the course is the heading
    assert enc.course_over_ground_deg(state(0, 0, WEST, 0.0)) == pytest.approx(270.0)


def test_pair_matrix_is_every_ordered_pair():
    states = np.array([state(0, 0, NORTH, 1.0), state(100, 100, WEST, 1.0), state(-40, 30, 0.3, 2.0, -0.2)])
    m = enc.pair_matrix(states)
    assert m.shape == (3, 3, enc.N_GEOMETRY)
    assert np.all(np.isnan(m[np.arange(3), np.arange(3)]))
    for i in range(3):
        for j in range(3):
            if i != j:
                np.testing.assert_allclose(m[i, j], enc.encounter(states[i], states[j]), rtol=1e-12, atol=1e-12)
                # seen from the other side: same range, TCPA, DCPA; beta and alpha swap; courses mirror
                assert m[i, j, enc.G_RANGE] == pytest.approx(m[j, i, enc.G_RANGE])
                assert m[i, j, enc.G_TCPA] == pytest.approx(m[j, i, enc.G_TCPA])
                assert m[i, j, enc.G_DCPA] == pytest.approx(m[j, i, enc.G_DCPA])
                assert m[i, j, enc.G_BETA] == pytest.approx(m[j, i, enc.G_ALPHA])
                assert (m[i, j, enc.G_COURSE_DIFF] + m[j, i, enc.G_COURSE_DIFF]) % 360.0 == pytest.approx(0.0, abs=1e-9)


def test_pair_series_follows_a_record():
    # two constant-velocity tracks sampled every second: the range is |d0 + w t| at each sample
    t = np.arange(0.0, 150.0)
    own = np.column_stack([np.zeros_like(t), 1.0 * t, np.full_like(t, NORTH + 4 * math.pi),   # psi unwrapped
                           np.ones_like(t), np.zeros_like(t), np.zeros_like(t)])
    tgt = np.column_stack([100.0 - t, np.full_like(t, 100.0), np.full_like(t, WEST), np.ones_like(t),
                           np.zeros_like(t), np.zeros_like(t)])
    g = enc.pair_series(own, tgt)
    np.testing.assert_allclose(g[:, enc.G_RANGE], math.sqrt(2) * np.abs(100.0 - t), atol=1e-9)
    np.testing.assert_allclose(g[:, enc.G_TCPA], 100.0 - t, atol=1e-9)     # the same CPA, counted down
    np.testing.assert_allclose(g[:, enc.G_DCPA], 0.0, atol=1e-9)
    np.testing.assert_allclose(g[:100, enc.G_BETA], 45.0, atol=1e-9)
    np.testing.assert_allclose(enc.courses_deg(own), 0.0, atol=1e-9)
    np.testing.assert_allclose(enc.speeds(tgt), 1.0)


def test_angle_wraps():
    assert enc.wrap180(180.0) == 180.0 and enc.wrap180(-180.0) == 180.0
    assert enc.wrap180(190.0) == pytest.approx(-170.0) and enc.wrap180(-1e-16) <= 0.0
    assert enc.wrap360(-1e-16) < 360.0 and enc.wrap360(725.0) == pytest.approx(5.0)


def test_bad_shapes_are_named():
    with pytest.raises(ValueError, match="state"):
        enc.encounter([0, 0, 0], [1, 1, 1, 1, 1, 1])
    with pytest.raises(ValueError, match="states must be"):
        enc.pair_matrix(np.zeros(6))
