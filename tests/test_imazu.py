"""The 22 Imazu situations (usv_mj.scenario.imazu) against the published geometry after scaling.

The published definition (Sawada, Sato & Majima 2021, Table 4, as transcribed in research note
§1.2): the own ship (OS) heads 000 at speed U; every target is on a straight course to the OS's
collision point C, R ahead, and reaches it at T = R / U; the targets' starts as (starboard, ahead)
offsets / R, typed below from the note's table. The placement computes the starts from each target's
course and speed ratio; this file checks them against those offsets, against closed forms (a target
of course c at the OS's speed starts 2 R sin(c/2) away at relative bearing c/2 - 90 deg), and
DCPA = 0, TCPA = R / U for every pair.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.core.errors import ScenarioError
from usv_mj.physics.colregs import SITUATION_NAMES, classify_pair
from usv_mj.physics.encounters import encounter
from usv_mj.scenario.imazu import DUPLICATES, imazu_case, imazu_situation

# research note §1.2, per case: (course_rel_deg, speed_ratio, x_R starboard, y_R ahead) of each target
TABLE4 = {
    1: [(180, 1.0, 0.0000, 2.0000)],
    2: [(270, 1.0, 1.0000, 1.0000)],
    3: [(0, 0.7, 0.0000, 0.3000)],
    4: [(45, 1.0, -0.7071, 0.2929)],
    5: [(180, 1.0, 0.0000, 2.0000), (270, 1.0, 1.0000, 1.0000)],
    6: [(350, 1.0, 0.1736, 0.0152), (315, 1.0, 0.7071, 0.2929)],
    7: [(0, 0.7, 0.0000, 0.3000), (315, 1.0, 0.7071, 0.2929)],
    8: [(180, 1.0, 0.0000, 2.0000), (270, 1.0, 1.0000, 1.0000)],
    9: [(330, 1.0, 0.5000, 0.1340), (270, 1.0, 1.0000, 1.0000)],
    10: [(270, 1.0, 1.0000, 1.0000), (15, 1.0, -0.2588, 0.0341)],
    11: [(90, 1.0, -1.0000, 1.0000), (330, 1.0, 0.5000, 0.1340)],
    12: [(180, 1.0, 0.0000, 2.0000), (315, 1.0, 0.7071, 0.2929), (350, 1.0, 0.1736, 0.0152)],
    13: [(180, 1.0, 0.0000, 2.0000), (10, 1.0, -0.1736, 0.0152), (45, 1.0, -0.7071, 0.2929)],
    14: [(350, 1.0, 0.1736, 0.0152), (315, 1.0, 0.7071, 0.2929), (270, 1.0, 1.0000, 1.0000)],
    15: [(0, 0.7, 0.0000, 0.3000), (315, 1.0, 0.7071, 0.2929), (270, 1.0, 1.0000, 1.0000)],
    16: [(45, 0.7, -0.4950, 0.5050), (90, 1.0, -1.0000, 1.0000), (270, 1.0, 1.0000, 1.0000)],
    17: [(0, 0.7, 0.0000, 0.3000), (10, 1.0, -0.1736, 0.0152), (315, 1.0, 0.7071, 0.2929)],
    18: [(225, 1.0, 0.7071, 1.7071), (345, 1.0, 0.2588, 0.0341), (330, 1.0, 0.5000, 0.1340)],
    19: [(15, 1.0, -0.2588, 0.0341), (345, 1.0, 0.2588, 0.0341), (225, 1.0, 0.7071, 1.7071)],
    20: [(0, 0.7, 0.0000, 0.3000), (345, 1.0, 0.2588, 0.0341), (270, 1.0, 1.0000, 1.0000)],
    21: [(345, 1.0, 0.2588, 0.0341), (15, 1.0, -0.2588, 0.0341), (270, 1.0, 1.0000, 1.0000)],
    22: [(0, 0.7, 0.0000, 0.3000), (315, 1.0, 0.7071, 0.2929), (270, 1.0, 1.0000, 1.0000)],
}
TABLE4_CASE12 = [(315, 1.0, 0.7071, 0.2929), (350, 1.0, 0.1736, 0.0152)]
TABLE_ROUNDING = 0.5e-4 + 1e-12     # the offsets are printed to 4 decimals

L, U = 2.0, 1.0                     # a 2 m hull at 1 m/s: R = 50 L = 100 m, T = 100 s


def body_offsets(sit, vessel):
    """(starboard, ahead) offset of ``vessel`` from the own ship's start, in the own ship's axes [m]."""
    x0, y0, psi0 = sit.own.eta
    dx, dy = vessel.eta[0] - x0, vessel.eta[1] - y0
    return dx * math.sin(psi0) - dy * math.cos(psi0), dx * math.cos(psi0) + dy * math.sin(psi0)


def test_counts_and_variants():
    counts = {c: imazu_case(c).n_targets for c in range(1, 23)}
    assert [c for c, n in counts.items() if n == 1] == [1, 2, 3, 4]
    assert [c for c, n in counts.items() if n == 2] == list(range(5, 12))
    assert [c for c, n in counts.items() if n == 3] == list(range(12, 23))
    # Table 4's case 12 has two targets: the same two as case 6, in the other order
    t4 = imazu_case(12, "table4")
    assert t4.n_targets == 2 and t4.targets == tuple(reversed(imazu_case(6).targets))
    assert all(imazu_case(c, "table4") == imazu_case(c) for c in range(1, 23) if c != 12)
    # the duplicates are kept and named
    assert DUPLICATES == {8: 5, 22: 15}
    assert imazu_case(8).targets == imazu_case(5).targets and imazu_case(22).targets == imazu_case(15).targets


@pytest.mark.parametrize("case", range(1, 23))
def test_placement_matches_table4_after_scaling(case):
    sit = imazu_situation(case, L, U)
    R, T = 50 * L, 50 * L / U
    assert (sit.R_m, sit.T_cpa_s) == (pytest.approx(R), pytest.approx(T))
    assert sit.own.eta == (0.0, 0.0, pytest.approx(math.pi / 2)) and sit.own.speed == U
    assert sit.collision_point == (pytest.approx(0.0, abs=1e-12), pytest.approx(R))
    assert sit.goal == (pytest.approx(0.0, abs=1e-12), pytest.approx(2 * R))
    assert [v.name for v in sit.vessels] == ["own"] + [f"ts{i}" for i in range(1, len(TABLE4[case]) + 1)]
    for vessel, (course, ratio, x_r, y_r) in zip(sit.targets, TABLE4[case], strict=True):
        stbd, ahead = body_offsets(sit, vessel)
        assert abs(stbd / R - x_r) <= TABLE_ROUNDING and abs(ahead / R - y_r) <= TABLE_ROUNDING
        assert vessel.speed == pytest.approx(ratio * U) and vessel.speed_ratio == ratio
        assert vessel.heading_deg == pytest.approx(course % 360.0)
        # course c clockwise from the OS's north: psi = pi/2 - c (mod 2 pi)
        assert math.cos(vessel.eta[2]) == pytest.approx(math.sin(math.radians(course)), abs=1e-12)
        assert math.sin(vessel.eta[2]) == pytest.approx(math.cos(math.radians(course)), abs=1e-12)
        assert vessel.state == vessel.eta + (vessel.speed, 0.0, 0.0)


@pytest.mark.parametrize("case", range(1, 23))
def test_every_target_meets_the_own_ship_at_the_collision_point(case):
    for psi0, origin in ((math.pi / 2, (0.0, 0.0)), (0.3, (120.0, -40.0))):   # north, and any pose
        sit = imazu_situation(case, L, U, psi0=psi0, origin=origin)
        R, T = 50 * L, 50 * L / U
        for vessel in sit.targets:
            g = encounter(sit.own.state, vessel.state)
            assert g.dcpa_m == pytest.approx(0.0, abs=1e-9 * R)
            assert g.tcpa_s == pytest.approx(T, rel=1e-12)
            x, y, psi = vessel.eta
            assert x + vessel.speed * T * math.cos(psi) == pytest.approx(sit.collision_point[0], abs=1e-9 * R)
            assert y + vessel.speed * T * math.sin(psi) == pytest.approx(sit.collision_point[1], abs=1e-9 * R)


@pytest.mark.parametrize("case", range(1, 23))
def test_relative_bearings_and_ranges(case):
    sit = imazu_situation(case, L, U)
    R = sit.R_m
    for vessel, (course, ratio, _, _), published in zip(sit.targets, TABLE4[case], imazu_case(case).targets):
        g = encounter(sit.own.state, vessel.state)
        c = math.radians(course)
        # start = C - ratio R (sin c, cos c) in (starboard, ahead): range and bearing by hand
        stbd, ahead = -ratio * R * math.sin(c), R - ratio * R * math.cos(c)
        assert g.range_m == pytest.approx(math.hypot(stbd, ahead), rel=1e-12)
        assert g.relative_bearing_deg == pytest.approx(math.degrees(math.atan2(stbd, ahead)), abs=1e-9)
        if ratio == 1.0:   # closed form: 2 R sin(c/2) at c/2 - 90 deg
            assert g.range_m == pytest.approx(2 * R * math.sin(c / 2), rel=1e-12)
            assert g.relative_bearing_deg == pytest.approx(course / 2 - 90.0, abs=1e-9)
        # the published columns (bearing to 0.01 deg, range / R to 4 decimals)
        assert g.relative_bearing_deg == pytest.approx(published.bearing_deg, abs=0.005 + 1e-9)
        assert g.range_m / R == pytest.approx(published.range_R, abs=TABLE_ROUNDING)


def test_case_2_on_the_starboard_bow_case_4_on_the_port_bow():
    # whatever the own ship's heading: case 2's target 45 deg to starboard, case 4's 67.5 deg to port
    for psi0 in (math.pi / 2, 0.0, -2.0):
        s2, s4 = imazu_situation(2, L, U, psi0=psi0), imazu_situation(4, L, U, psi0=psi0)
        stbd, ahead = body_offsets(s2, s2.targets[0])
        assert stbd > 0 and ahead > 0 and stbd == pytest.approx(ahead)
        assert encounter(s2.own.state, s2.targets[0].state).relative_bearing_deg == pytest.approx(45.0)
        stbd, ahead = body_offsets(s4, s4.targets[0])
        assert stbd < 0 < ahead
        assert encounter(s4.own.state, s4.targets[0].state).relative_bearing_deg == pytest.approx(-67.5)
    # heading east (psi0 = 0): starboard is south, so case 2's target is south-east of the own ship
    x, y, _ = imazu_situation(2, L, U, psi0=0.0).targets[0].eta
    assert (x, y) == (pytest.approx(100.0), pytest.approx(-100.0))


def test_situations_at_the_start_are_the_published_ones():
    for case in range(1, 23):
        sit = imazu_situation(case, L, U)
        for vessel, published in zip(sit.targets, imazu_case(case).targets):
            assert SITUATION_NAMES[classify_pair(sit.own.state, vessel.state)] == published.situation, (case, vessel.name)
        assert sit.situations == {i: t.situation for i, t in enumerate(imazu_case(case).targets, start=1)}
    assert imazu_situation(5, L, U).situations == {1: "head_on", 2: "crossing_give_way"}


def test_scaling_examples():
    # research note §7 item 2: L = 2 m, U = 1 m/s -> R = 100 m, T = 100 s; L = 5 m, U = 2 m/s -> 250 m, 125 s
    s = imazu_situation(6, 5.0, 2.0)
    assert (s.R_m, s.T_cpa_s) == (250.0, 125.0)
    # the closest start (case 6's first target, 85 deg on the starboard bow) is 2 sin(5 deg) R = 8.7 L
    closest = encounter(s.own.state, s.targets[0].state).range_m
    assert closest / 5.0 == pytest.approx(100 * math.sin(math.radians(5.0)))
    assert imazu_situation(1, 2.0, 1.0, k_R=30.0).R_m == 60.0
    assert imazu_situation(3, 2.0, 1.5).targets[0].speed == pytest.approx(0.7 * 1.5)


def test_bad_inputs_are_named():
    for bad in (0, 23, "3", 3.0, True):
        with pytest.raises(ScenarioError, match="case"):
            imazu_case(bad)
    with pytest.raises(ScenarioError, match="variant"):
        imazu_case(1, "tudrl")
    with pytest.raises(ScenarioError, match="length_m"):
        imazu_situation(1, -2.0, 1.0)
    with pytest.raises(ScenarioError, match="speed_mps"):
        imazu_situation(1, 2.0, float("nan"))
    table = imazu_situation(2, L, U).targets[0].as_table()
    assert table["name"] == "ts1" and table["speed"] == U and np.allclose(table["eta"][:2], [100.0, 100.0])
    assert math.cos(table["eta"][2]) == pytest.approx(-1.0)      # westbound
