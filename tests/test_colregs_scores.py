"""The safety and COLREGs scores (usv_mj.record.colregs_scores) against worked examples.

The pieces (S_r, S_theta, S_safety, the penalties) at points where their value is read off the
definition; whole encounters on kinematic tracks (straight legs, course and speed changes at sample
times, positions integrated exactly) whose CPA, bearings and stage ranges are worked out here.
Own ship length L = 2 m throughout: R_col, R_nm, R_min, R_pref = 2, 4, 6, 10 m; stages 2, 3, 4 =
50, 15, 8 m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.record import colregs_scores as sc
from usv_mj.scenario.imazu import imazu_situation

L = 2.0
P = sc.ScoreParams()
DT = 0.5


def track(t, x0, y0, legs):
    """States (T, 6) of a vessel from (x0, y0) sailing ``legs``: [(t_start, compass course [deg],
    speed [m/s]), ...], the leg in force at t_k holding over [t_k, t_k+1)."""
    out = np.zeros((t.size, 6))
    x, y = x0, y0
    for k, tk in enumerate(t):
        course, speed = [(c, s) for (t0, c, s) in legs if t0 <= tk][-1]
        psi = math.radians(90.0 - course)
        out[k] = (x, y, psi, speed, 0.0, 0.0)
        if k + 1 < t.size:
            x += speed * math.cos(psi) * (t[k + 1] - tk)
            y += speed * math.sin(psi) * (t[k + 1] - tk)
    return out


# --- the pieces ---------------------------------------------------------------------------------------------


def test_range_score_breakpoints():
    assert sc.range_score(10.0, L) == 1.0 and sc.range_score(50.0, L) == 1.0       # at and beyond R_pref
    assert sc.range_score(6.0, L) == pytest.approx(1 - 0.2)                        # a pass at R_min: 1 - g_min
    assert sc.range_score(8.0, L) == pytest.approx(1 - 0.2 * 2 / 4)                # halfway R_min..R_pref
    assert sc.range_score(5.0, L) == pytest.approx(1 - 0.2 - 0.3 / 2)              # halfway R_nm..R_min
    assert sc.range_score(4.0, L) == pytest.approx(0.5)                            # at R_nm
    assert sc.range_score(3.0, L) == pytest.approx(1 - 0.2 - 0.3 - 0.5 / 2)        # halfway R_col..R_nm
    assert sc.range_score(2.0, L) == pytest.approx(0.0, abs=1e-15)                 # at R_col
    assert sc.range_score(0.0, L) == 0.0                                           # a collision


def test_pose_and_safety_scores():
    assert sc.pose_score(90.0, 90.0) == 1.0 and sc.pose_score(-120.0, 180.0) == 1.0   # abeam / astern
    assert sc.pose_score(0.0, 0.0) == 0.0                                               # bow to bow
    assert sc.pose_score(60.0, 0.0) == pytest.approx(0.25 * (1 - math.cos(math.radians(60))))
    assert sc.pose_score(0.0, -60.0) == pytest.approx(0.75 * 0.5)
    assert sc.safety_score(0.0, 1.0) == 0.0                       # a collision whatever the pose
    assert sc.safety_score(1e-3, 1.0) == 1.0                      # just outside R_col, abeam
    assert sc.safety_score(1.0, 0.0) == 1.0
    assert sc.safety_score(0.8, 0.5) == pytest.approx(0.2 * 0.5 + 0.8)


def test_penalties():
    assert sc.non_apparent_penalty(2.0, 2.0, 30.0) == 1.0 and sc.non_apparent_penalty(30.0, 2.0, 30.0) == 0.0
    assert sc.non_apparent_penalty(-16.0, 2.0, 30.0) == pytest.approx(1 - 0.5 ** 2)
    assert sc.action_penalty(1.0, 2.0, 30.0) == 0.0 and sc.action_penalty(9.0, 2.0, 30.0) == pytest.approx(0.25)
    assert sc.starboard_to_starboard_penalty(-90.0, -90.0) == pytest.approx(0.0)    # port to port
    assert sc.starboard_to_starboard_penalty(90.0, 90.0) == pytest.approx(1.0)      # starboard to starboard
    assert sc.starboard_to_starboard_penalty(0.0, 0.0) == pytest.approx(1 - 0.25 * 0.25)
    assert sc.non_starboard_penalty(5.0) == 1.0 and sc.non_starboard_penalty(35.0) == 0.0
    assert sc.non_starboard_penalty(20.0) == pytest.approx(1 - 0.5 ** 2)


def test_params_are_checked():
    with pytest.raises(ValueError, match="radii"):
        sc.ScoreParams(r_min_L=6.0)
    with pytest.raises(ValueError, match="gamma_min"):
        sc.ScoreParams(gamma_min=0.3)
    with pytest.raises(ValueError, match="apparent_either"):
        sc.ScoreParams(apparent_either=1)
    assert P.radii_m(L) == (2.0, 4.0, 6.0, 10.0)


# --- head-on --------------------------------------------------------------------------------------------------

T_HO = np.arange(0.0, 160.0, DT)
TARGET_HO = track(T_HO, 0.0, 200.0, [(0.0, 180.0, 1.0)])     # southbound from 200 m north at 1 m/s


def test_head_on_collision_scores_zero():
    own = track(T_HO, 0.0, 0.0, [(0.0, 0.0, 1.0)])
    s = sc.score_pair(T_HO, own, TARGET_HO, L)
    # locked head-on where the range 200 - 2t reaches stage 2 (50 m): t = 75 s; they meet at t = 100 s
    assert s.situation == "head_on" and s.role == "give_way"
    assert T_HO[s.entry_index] == 75.0 and s.t_cpa_s == 100.0 and s.r_cpa_m == pytest.approx(0.0, abs=1e-9)
    assert (s.S_r, s.S_safety, s.S16, s.S14) == (0.0, 0.0, 0.0, 0.0)
    assert s.S13 is None and s.S15 is None and s.S17 is None


def test_head_on_port_to_port_after_a_35_degree_starboard_turn():
    # own turns to 035 at t = 80 s (range 40 m: inside stage 2, outside stage 3 = 15 m). From there,
    # d = (0, 40), w = (-sin 35, -1 - cos 35): TCPA = 40 (1 + c) / (2 + 2c) = 20 s, and
    # d + 20 w = (-20 s, 20 (1 - c)): DCPA = 40 sin(17.5 deg), the target bearing 180 + 72.5 - 360 =
    # -72.5 deg (compass 287.5) from own: beta = -72.5 - 35 = -107.5, alpha = 107.5 - 180 = -72.5
    own = track(T_HO, 0.0, 0.0, [(0.0, 0.0, 1.0), (80.0, 35.0, 1.0)])
    s = sc.score_pair(T_HO, own, TARGET_HO, L)
    assert s.situation == "head_on" and s.t_cpa_s == 100.0
    assert s.r_cpa_m == pytest.approx(40 * math.sin(math.radians(17.5)), rel=1e-9)    # 12.0 m > R_pref
    assert s.beta_cpa_deg == pytest.approx(-107.5) and s.alpha_cpa_deg == pytest.approx(-72.5)
    assert s.S_r == 1.0 and s.S_safety == 1.0
    assert s.S_theta == pytest.approx(0.25 * (1 - math.cos(math.radians(72.5))) + 0.75)
    assert (s.P_na_course, s.P_na_speed, s.P_delay, s.P_nsb) == (0.0, 1.0, 0.0, 0.0)
    assert s.S_apparent == pytest.approx(0.5)                       # OE-2023: the speed held costs half
    assert s.S16 == pytest.approx(0.5)
    sin = math.sin(math.radians(-72.5))                             # sin(-72.5) = sin(-107.5)
    p_sts = 1 - ((sin - 1) / 2) ** 4
    assert s.P_sts == pytest.approx(p_sts)
    assert s.S14 == pytest.approx(1 - 0.6 * p_sts)
    # with "course and/or speed" (apparent_either) the apparent turn alone is enough
    e = sc.score_pair(T_HO, own, TARGET_HO, L, params=sc.ScoreParams(apparent_either=True))
    assert e.S_apparent == 1.0 and e.S16 == 1.0 and e.S14 == s.S14


def test_head_on_late_turn_is_delayed():
    # the same turn at t = 95 s, range 10 m, inside stage 3 (15 m): P_delay = (r_entry - r_man) / r_entry
    # = (50 - 10) / 50 = 0.8 (entry at the sample where the range is 50 m)
    own = track(T_HO, 0.0, 0.0, [(0.0, 0.0, 1.0), (95.0, 35.0, 1.0)])
    s = sc.score_pair(T_HO, own, TARGET_HO, L)
    assert s.P_delay == pytest.approx(0.8)
    assert s.S16 == pytest.approx(s.S_safety * s.S_apparent * 0.2)
    # ... and a 10 deg turn (detectable, not apparent): P_na_course = 1 - ((10 - 2) / 28)^2
    own = track(T_HO, 0.0, 0.0, [(0.0, 0.0, 1.0), (80.0, 10.0, 1.0)])
    s = sc.score_pair(T_HO, own, TARGET_HO, L)
    assert s.P_na_course == pytest.approx(1 - (8 / 28) ** 2) and s.P_delay == 0.0
    assert s.P_nsb == pytest.approx(1 - 0.0 ** 2)                   # exactly 10 deg: the limit itself
    assert s.S14 == pytest.approx((1 - 0.4 * s.P_nsb - 0.6 * s.P_sts) * (1 - s.P_na_course))


def test_a_turn_before_stage_two_needs_the_scenarios_situation():
    # turning at t = 10 s (range 180 m, far outside stage 2): by stage 2 the target is 35 deg off the
    # bow, no head-on any more, so the lock finds no situation; the scenario's own (head-on from the
    # start) scores it as the early action it is
    own = track(T_HO, 0.0, 0.0, [(0.0, 0.0, 1.0), (10.0, 35.0, 1.0)])
    s = sc.score_pair(T_HO, own, TARGET_HO, L)
    assert s.situation == "none" and s.S16 is None and s.S_safety == 1.0
    s = sc.score_pair(T_HO, own, TARGET_HO, L, situation="head_on")
    assert s.entry_index == 0 and s.P_na_course == 0.0 and s.P_delay == 0.0 and s.P_nsb == 0.0


# --- crossing ----------------------------------------------------------------------------------------------------

T_CR = np.arange(0.0, 200.0, DT)


def test_stand_on_crossing_from_port():
    # own northbound from the origin; the give-way target from port, eastbound on y = 90 from x = -100,
    # both 1 m/s: d(t) = (t - 100, 90 - t), closest at t = 95: d = (-5, -5), r_cpa = 5 sqrt 2 = 7.07 m.
    # The range reaches 50 m (stage 2) when 2 (t - 95)^2 + 50 = 2500: t = 60, where d = (-40, 30):
    # beta = -53.1 (port), alpha = 36.9 (own on its starboard bow): own stands on.
    target = track(T_CR, -100.0, 90.0, [(0.0, 90.0, 1.0)])
    own = track(T_CR, 0.0, 0.0, [(0.0, 0.0, 1.0)])
    s = sc.score_pair(T_CR, own, target, L)
    # (the range is 50 m exactly at t = 60: rounding decides between that sample and the next)
    assert s.situation == "crossing_stand_on" and s.role == "stand_on" and T_CR[s.entry_index] in (60.0, 60.5)
    assert s.t_cpa_s == 95.0 and s.r_cpa_m == pytest.approx(5 * math.sqrt(2))
    # at CPA the target is south-west of own (beta = -135) and own north-east of the eastbound target
    # (alpha = 45 - 90 = -45)
    assert s.beta_cpa_deg == pytest.approx(-135.0) and s.alpha_cpa_deg == pytest.approx(-45.0)
    s_r = 1 - 0.2 * (10 - 5 * math.sqrt(2)) / (10 - 6)
    s_theta = 0.25 * (1 - math.cos(math.radians(45))) + 0.75
    assert s.S_r == pytest.approx(s_r) and s.S_theta == pytest.approx(s_theta)
    assert s.S_safety == pytest.approx((1 - s_r) * s_theta + s_r)
    assert (s.P_stage2, s.P_stage3, s.P_port_turn) == (0.0, 0.0, 0.0)
    assert s.S17 == s.S15 == s.S_safety and s.S16 is None

    # speeding up 30 % in stage 2 (t = 65 s): P_stage2 = 0.25 x (0.3 - 0.2) / (0.5 - 0.2) = 1/12
    own = track(T_CR, 0.0, 0.0, [(0.0, 0.0, 1.0), (65.0, 0.0, 1.3)])
    s = sc.score_pair(T_CR, own, target, L)
    assert s.P_stage2 == pytest.approx(0.25 / 3) and s.S17 == pytest.approx(s.S_safety * (1 - 0.25 / 3))

    # a 10 deg turn to port in stage 4 (inside 8 m from t = 92.35 s; the turn at t = 93 s) with the
    # give-way vessel on own port side: Rule 17 c, P_port_turn = 1 and S17 = 0
    own = track(T_CR, 0.0, 0.0, [(0.0, 0.0, 1.0), (93.0, 350.0, 1.0)])
    s = sc.score_pair(T_CR, own, target, L)
    assert s.P_port_turn == 1.0 and s.S17 == 0.0 and s.P_stage2 == 0.0 and s.P_stage3 == 0.0


def test_give_way_crossing_behind_and_ahead():
    # Imazu case 2 at R = 100 m: the target from (100, 100) westbound; own northbound, both 1 m/s. The
    # range sqrt(2)(100 - t) reaches 50 m at t = 64.6 (entry at the sample t = 65); own turns at t = 66
    # from (0, 66), the target then at (34, 100).
    target = track(T_CR, 100.0, 100.0, [(0.0, 270.0, 1.0)])
    either = sc.ScoreParams(apparent_either=True)
    # 90 deg to starboard (east on y = 66): the two run reciprocal 34 m apart; CPA when their x agree,
    # t = 83: beta = -90, alpha = -90; own never crosses the target's track (P_ahead = 0): S15 = S16
    own = track(T_CR, 0.0, 0.0, [(0.0, 0.0, 1.0), (66.0, 90.0, 1.0)])
    s = sc.score_pair(T_CR, own, target, L, params=either)
    assert s.situation == "crossing_give_way" and T_CR[s.entry_index] == 65.0
    assert s.t_cpa_s == 83.0 and s.r_cpa_m == pytest.approx(34.0)
    assert s.beta_cpa_deg == pytest.approx(-90.0) and s.alpha_cpa_deg == pytest.approx(-90.0)
    assert (s.S_safety, s.P_delay, s.P_ahead, s.S16, s.S15) == (1.0, 0.0, 0.0, 1.0, 1.0)
    # 30 deg to port (course 330): w = (-1 + 1/2, -sqrt(3)/2), d = (34, 34): TCPA = 34 (1/2 + sqrt(3)/2),
    # d + w TCPA: the target 10.8 m east and 6.2 m south of own, behind own's track: own crossed ahead.
    # Own seen from the westbound target: bearing 300, alpha = +30, in (-25, 165): P_ahead = 1
    own = track(T_CR, 0.0, 0.0, [(0.0, 0.0, 1.0), (66.0, 330.0, 1.0)])
    s = sc.score_pair(T_CR, own, target, L, params=either)
    tcpa = 34 * (0.5 + math.sqrt(3) / 2)
    rel = (34 - 0.5 * tcpa, 34 - math.sqrt(3) / 2 * tcpa)
    assert abs(s.t_cpa_s - (66 + tcpa)) <= DT / 2
    assert s.r_cpa_m == pytest.approx(math.hypot(*rel), abs=0.05)     # sampled every 0.5 s
    assert s.alpha_cpa_deg == pytest.approx(30.0, abs=1.0)
    assert s.S_r == 1.0 and s.P_ahead == 1.0 and s.S16 == 1.0 and s.S15 == pytest.approx(0.5)


# --- overtaking, and every target -----------------------------------------------------------------------------


def test_overtaking_without_action_and_min_over_targets():
    t = np.arange(0.0, 60.0, DT)
    own = track(t, 0.0, 0.0, [(0.0, 0.0, 2.0)])
    slow = track(t, 5.0, 20.0, [(0.0, 0.0, 1.0)])           # 5 m to starboard, 20 m ahead, half the speed
    crossing = track(t, 100.0, 100.0, [(0.0, 270.0, 2.0)])   # meets own at (0, 100) at t = 50 s
    # overtaking, locked at once (range 20.6 m < 50, TCPA 20 s); alongside at t = 20: r_cpa = 5 m,
    # S_r = 1 - 0.2 - 0.3 (6 - 5) / 2 = 0.65, abeam (alpha = -90, beta = 90): S_theta = 1, S_safety = 1;
    # no action at all: S_apparent = 0, so S16 = S13 = 0 for all the safe pass
    s = sc.score_pair(t, own, slow, L)
    assert s.situation == "overtaking" and s.entry_index == 0 and s.t_cpa_s == 20.0
    assert s.r_cpa_m == pytest.approx(5.0) and s.S_r == pytest.approx(0.65) and s.S_safety == pytest.approx(1.0)
    assert (s.alpha_cpa_deg, s.beta_cpa_deg) == (pytest.approx(-90.0), pytest.approx(90.0))
    assert s.P_ahead == 0.0 and s.S16 == 0.0 and s.S13 == 0.0
    states = np.stack([own, slow, crossing], axis=1)
    every = sc.score_encounters(t, states, [L, 2.0, 4.0])
    assert set(every.pairs) == {1, 2}
    assert every.pairs[1] == s
    assert every.pairs[2].situation == "crossing_give_way" and every.pairs[2].r_cpa_m == pytest.approx(0.0, abs=1e-9)
    assert every.minimum["S_safety"] == 0.0 and every.minimum["S_r"] == 0.0    # the collision counts
    assert every.minimum["S13"] == 0.0 and every.minimum["S14"] is None and every.minimum["S17"] is None
    d = every.to_dict()
    assert d["pairs"]["1"]["situation"] == "overtaking" and d["minimum"]["S14"] is None


def test_imazu_without_avoidance_collides_with_every_target():
    # Imazu case 5 (head-on + crossing from starboard) at L = 2 m, U = 1 m/s: R = 100 m, every vessel
    # at (0, 100) at t = 100 s if nobody manoeuvres; scored with the scenario's situations
    sit = imazu_situation(5, L, 1.0)
    t = np.arange(0.0, 200.0 + DT / 2, DT)
    states = np.stack([track(t, v.eta[0], v.eta[1], [(0.0, v.heading_deg, v.speed)]) for v in sit.vessels], axis=1)
    every = sc.score_encounters(t, states, [L] * 3, situations=sit.situations)
    for j, name in ((1, "head_on"), (2, "crossing_give_way")):
        s = every.pairs[j]
        assert s.situation == name and s.entry_index == 0 and s.t_cpa_s == 100.0
        assert s.r_cpa_m == pytest.approx(0.0, abs=1e-9) and s.S_safety == 0.0 and s.S16 == 0.0
    assert every.minimum["S_safety"] == 0.0 and every.minimum["S14"] == 0.0 and every.minimum["S15"] == 0.0
