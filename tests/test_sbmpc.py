"""Scenario-based MPC collision avoidance (issue 35 item 4, controllers/sbmpc.py): the encounters of the
issue's first "done when" line on both plants, the crossings, and the parts against hand calculations.

The encounters are test_fleet's head-on (two paper hulls, L = 1.98 m, 30 m = 15 L apart at 0.6 m/s,
meeting after about 25 s if nobody gives way) with both vessels running ``sbmpc``, and "no avoidance"
(``los``, the same path follower alone) on the same scenario. Control period 0.02 s (the LOS heading
loop of the paper hull limit-cycles at 0.05 s: kd/m33 = 250/15.6 = 16 1/s against a 20 1/s sampling).
Angles: ENU, psi counter-clockwise from east, so a turn to starboard makes psi smaller.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.controllers.sbmpc import (K_TU, SBMPCGains, behaviour_hazard, control_cost, horizon_steps, pair_flags,
                                      predict_own, virtual_reference)
from usv_mj.core.errors import ScenarioError
from usv_mj.record.criteria import Clearance, criterion_from_dict
from usv_mj.record.encounters import SAFETY_DOMAIN_L

from test_fleet import HEAD_ON, NORTH, fleet

DT = 0.02
U = 0.6


def avoiding(entry: dict, kind: str = "sbmpc", **gains) -> dict:
    """test_fleet's "keep" vessel ``entry`` steered by ``kind`` on the same line (its start, heading and
    speed): sbmpc, or los ("no avoidance", the same path follower alone, crab compensation off as sbmpc's)."""
    x, y, psi = entry["initial"]["eta"]
    speed = entry["initial"]["nu"][0]
    return {"name": entry["name"], "initial": entry["initial"],
            "controller": {"kind": kind, "crab_compensation": False, **gains},
            "trajectory": {"kind": "line", "start": [x, y], "heading_deg": math.degrees(psi), "speed": speed}}


def run(plant: str, vessels: list, duration: float):
    sc = fleet(plant, vessels, duration=duration, control_period=DT)
    return sc, simulate(sc)


def centre_range(rec, a: str = "own", b: str = "target") -> np.ndarray:
    return np.hypot(rec[a]["x"] - rec[b]["x"], rec[a]["y"] - rec[b]["y"])


def right_of_start_line(r, x0: float, y0: float, psi0: float) -> np.ndarray:
    """The vessel's offset to its own right (starboard) of the straight line it started on [m]."""
    return (r["x"] - x0) * math.sin(psi0) - (r["y"] - y0) * math.cos(psi0)


def first_turn_sign(r, psi0: float, threshold_deg: float = 5.0) -> float:
    """The sign of the first heading change beyond ``threshold_deg`` (-1: to starboard, clockwise)."""
    change = np.angle(np.exp(1j * (r["psi"] - psi0)))
    k = int(np.argmax(np.abs(change) > math.radians(threshold_deg)))
    assert abs(change[k]) > math.radians(threshold_deg), "the vessel never turned"
    return float(np.sign(change[k]))


@pytest.fixture(scope="module")
def head_on():
    """Both vessels with sbmpc on both plants (30 s: past the meeting at about 25 s)."""
    vessels = [avoiding(v) for v in HEAD_ON]
    return {plant: run(plant, vessels, 30.0) for plant in ("analytic", "mujoco")}


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_head_on_both_alter_to_starboard_and_keep_out_of_the_safety_domain(head_on, plant):
    """Each vessel's first heading change is clockwise (starboard), its first chosen course offset
    negative (starboard), it ends up to the right of the line it started on, and the two pass port
    to port (at the closest approach each sees the other on its port side); the centres stay more
    than SAFETY_DOMAIN_L = 3 hull lengths apart (3 x 1.98 = 5.94 m), no hull touches."""
    sc, rec = head_on[plant]
    assert rec.status == "completed"
    length = sc.vessels[0].scenario.vessel.model.dimensions.L
    rng = centre_range(rec)
    k = int(np.argmin(rng))
    assert rng.min() > SAFETY_DOMAIN_L * length, (plant, rng.min())
    assert not rec.contact_rows().any()
    for entry in HEAD_ON:
        name, (x0, y0, psi0) = entry["name"], entry["initial"]["eta"]
        r = rec[name]
        assert first_turn_sign(r, psi0) == -1.0, name
        chosen = r["course_offset"][r["course_offset"] != 0.0]
        assert chosen.size and chosen[0] < 0.0, name
        right = right_of_start_line(r, x0, y0, psi0)
        assert right.max() > length and right[k] > 0.0, (name, right.max(), right[k])
        # port to port: the other vessel on this one's left at the closest approach
        other = rec["target" if name == "own" else "own"]
        lx, ly = other["x"][k] - r["x"][k], other["y"][k] - r["y"][k]
        assert math.cos(r["psi"][k]) * ly - math.sin(r["psi"][k]) * lx > 0.0, name
        # the nearest-vessel diagnostics are the range computed here
        assert np.allclose(r["nearest_range"], rng)
        assert rec[name].metadata["criterion"] == {"kind": "clearance", "min_range_m": SAFETY_DOMAIN_L * length,
                                                   "column": "nearest_range"}


def test_head_on_the_plants_agree_and_choose_alike(head_on):
    """The MPC's choices (a discrete set) are the same at every step on both plants, so the tracks
    agree to the closed-loop tolerance of tests/test_compare.py (1e-3 m)."""
    (_, a), (_, m) = head_on["analytic"], head_on["mujoco"]
    for name in ("own", "target"):
        assert np.array_equal(a[name]["course_offset"], m[name]["course_offset"]), name
        assert np.array_equal(a[name]["speed_factor"], m[name]["speed_factor"]), name
        assert np.hypot(a[name]["x"] - m[name]["x"], a[name]["y"] - m[name]["y"]).max() < 1e-3, name


def test_head_on_without_avoidance_collides():
    """"No avoidance" is the path follower alone (los with the same gains) on the same scenario: the
    analytic hulls pass through each other (the range falls below one length). The MuJoCo contact
    and its record and log entries: tests/test_fleet.py::test_head_on_without_avoidance_collides..."""
    sc, rec = run("analytic", [avoiding(v, "los") for v in HEAD_ON], 30.0)
    length = sc.vessels[0].scenario.vessel.model.dimensions.L
    assert centre_range(rec).min() < length


def crossing(side: str, target_steer: str):
    """Own ship northbound from (0, 0); the target 20 m east ("starboard": heading west) or west
    ("port": heading east) of the meeting point (0, 20), crossing at right angles at the same speed:
    both reach (0, 20) at t = 20 / 0.6 = 33 s, 28.3 m = 14.3 L apart at the start. ``target_steer``:
    "keep" (course and speed kept: no avoidance) or "sbmpc"."""
    d = 20.0
    own = avoiding({"name": "own", "initial": {"eta": [0.0, 0.0, NORTH], "nu": [U, 0.0, 0.0]}})
    x, psi = (d, math.pi) if side == "starboard" else (-d, 0.0)
    start = {"name": "target", "initial": {"eta": [x, d, psi], "nu": [U, 0.0, 0.0]}}
    target = {**start, "steer": "keep"} if target_steer == "keep" else avoiding(start)
    return d, own, target


def crossing_time(y_or_x: np.ndarray, level: float) -> int:
    """The first row at which the coordinate reaches ``level`` (it rises through it)."""
    k = int(np.argmax(y_or_x >= level))
    assert y_or_x[k] >= level
    return k


def test_crossing_from_starboard_the_own_ship_gives_way_astern():
    """The target on the starboard bow (bearing 45 deg at 28 m = 14 L, crossing at right angles,
    DCPA 0) keeps course and speed: the own ship (give-way, Rules 15/16) turns to starboard first
    and crosses the target's track (y = 20 m) astern of it, the target already west of the own
    ship there; the centres stay outside the safety domain."""
    d, own, target = crossing("starboard", "keep")
    sc, rec = run("analytic", [own, target], 50.0)
    length = sc.vessels[0].scenario.vessel.model.dimensions.L
    o, t = rec["own"], rec["target"]
    assert first_turn_sign(o, NORTH) == -1.0
    chosen = o["course_offset"][o["course_offset"] != 0.0]
    assert chosen[0] < 0.0
    k = crossing_time(o["y"], d)
    assert t["x"][k] < o["x"][k], (t["x"][k], o["x"][k])   # the target passed ahead: own goes astern
    assert centre_range(rec).min() > SAFETY_DOMAIN_L * length


def test_crossing_from_port_the_own_ship_stands_on():
    """The target on the port bow, both with sbmpc: the own ship (stand-on, Rule 17 a i) keeps its
    course and speed (behaviour (0, 1), on its line) while the target is farther than
    stand_on_range_L = 7.5 L; it never turns to port for it (Rule 17 c); the target (give-way)
    turns to starboard and crosses the own ship's track (x = 0) astern of it."""
    d, own, target = crossing("port", "sbmpc")
    sc, rec = run("analytic", [own, target], 45.0)
    length = sc.vessels[0].scenario.vessel.model.dimensions.L
    o, t = rec["own"], rec["target"]
    rng = centre_range(rec)
    far = rng > SBMPCGains().stand_on_range_L * length
    assert far[:int(10.0 / DT)].all()   # 28 m apart closing at 0.85 m/s at most: farther than 14.85 m for 10 s
    assert np.all(o["course_offset"][far] == 0.0) and np.all(o["speed_factor"][far] == 1.0)
    assert np.abs(right_of_start_line(o, 0.0, 0.0, NORTH)[far]).max() < 0.05   # on its line
    assert np.all(o["course_offset"] <= 0.0)                                   # never to port
    assert first_turn_sign(t, 0.0) == -1.0
    k = crossing_time(t["x"], 0.0)
    assert o["y"][k] > t["y"][k]                                               # the own ship ahead: target astern
    assert rng.min() > SAFETY_DOMAIN_L * length


# --- the parts, by hand ----------------------------------------------------------------------------


def test_without_other_vessels_it_is_its_path_follower_bit_for_bit():
    """A single run of sbmpc is LOS with the same gains, row for row, in the compiled loop (LOS's
    kernel) and in the Python loop; the avoidance's columns keep (0, 1, NaN...) and the clearance
    criterion has no judged step."""
    base = {"duration": 5.0, "control_period": DT, "baseline": {"enabled": False}, "plant": {"kind": "analytic"},
            "trajectory": {"kind": "line", "start": [0.0, 0.0], "heading_deg": 30.0, "speed": U}}
    runs = {}
    for kind in ("sbmpc", "los"):
        sc = load_scenario(preset="paper", overrides={**base, "controller": {"kind": kind, "crab_compensation": False}})
        runs[kind] = [simulate(sc, loop=loop) for loop in ("auto", "python")]
    (s_auto, s_py), (l_auto, _) = runs["sbmpc"], runs["los"]
    assert s_auto.metadata["loop"] == "compiled"
    for c in ("x", "y", "psi", "u", "v", "r", "tau_u", "tau_r", "chi_d", "cross_track_error"):
        assert np.array_equal(s_auto[c], l_auto[c]), c
        assert np.array_equal(s_py[c], l_auto[c]), c
    assert np.all(s_auto["course_offset"] == 0.0) and np.all(s_auto["speed_factor"] == 1.0)
    assert np.isnan(s_auto["nearest_range"]).all() and np.isnan(s_py["avoidance_cost"]).all()
    judged = Clearance(min_range_m=5.94).evaluate(s_auto)
    assert judged["judged_steps"] == 0 and judged["passed"] is None


def test_the_gains_are_checked_with_the_key_named():
    for table, message in (({"speed_factors": [0.5, 0.2, 0.0]}, "must hold 1"),
                           ({"speed_factors": [1.0, 1.5, 0.0]}, r"in \[0, 1\]"),
                           ({"offset_step_deg": 0.0}, "offset_step_deg must be > 0"),
                           ({"max_offset_deg": 200.0}, r"max_offset_deg must be in \(0, 180\]"),
                           ({"horizon_L": -1.0}, "horizon_L must be a finite number >= 0"),
                           ({"phi_ho_deg": 180.0}, "phi_ho_deg must be in"),
                           ({"lookahead": 0.0}, "lookahead must be > 0"),
                           ({"stand_on": 1}, "stand_on must be true or false"),
                           ({"kapa": 1.0}, "did you mean 'kappa'")):
        with pytest.raises(ScenarioError, match=message):
            load_scenario(preset="paper", overrides={"controller": {"kind": "sbmpc", **table}})
    g = SBMPCGains(max_offset_deg=90.0, offset_step_deg=15.0)
    assert np.allclose(np.degrees(g.offsets()), np.arange(-90.0, 91.0, 15.0)) and g.offsets().size == 13
    assert g.los_gains().lookahead == 3.0 and len(g.as_array()) == 17


def test_the_prediction_of_the_own_ship_by_hand():
    """On its path at the path speed, behaviour (0, 1): a straight line at U (x = 0, y = U t). With
    (0, 0) the speed decays as U (1 - a)^j, a = 1 - exp(-dt/T_U), and the ship stays on the path.
    With a course offset of -45 deg the course converges to 90 - 45 = 45 deg (the held line through
    the start)."""
    g = SBMPCGains()
    k, los = g.packed(), g.as_array()
    own = np.array([0.0, 0.0, NORTH, U])
    ref = np.array([0.0, 0.0, NORTH, 0.0, U, 0.0, U])
    m, dt = horizon_steps(1.98, U, k)
    assert (m, dt) == (math.ceil(60.0 * 1.98 / U / 0.5), 0.5)   # T = 60 L/U = 198 s in 0.5 s steps
    out = np.empty((40, 4))
    predict_own(own, ref, 0.0, 1.0, los, k, dt, out)
    tau = dt * np.arange(1, 41)
    assert np.allclose(out[:, 0], 0.0, atol=1e-12) and np.allclose(out[:, 1], U * tau)
    predict_own(own, ref, 0.0, 0.0, los, k, dt, out)
    a = 1.0 - math.exp(-dt / k[K_TU])
    speeds = np.hypot(out[:, 2], out[:, 3])
    assert np.allclose(speeds, U * (1.0 - a) ** np.arange(1, 41))
    assert np.allclose(out[:, 0], 0.0, atol=1e-12)
    predict_own(own, ref, math.radians(-45.0), 1.0, los, k, dt, out)
    assert math.degrees(math.atan2(out[-1, 3], out[-1, 2])) == pytest.approx(45.0, abs=0.5)
    # falling behind the reference point (it moves on at U along the path, the ship at U cos 45 along it),
    # the speed command rises towards U + u_at (LOS's catch-up, step 5): between U and U + 0.3 m/s
    assert U < np.hypot(out[-1, 2], out[-1, 3]) < U + 0.3


def test_the_virtual_reference_makes_los_steer_the_behaviour():
    """At (2, 5) on a northbound path from the origin (cross-track y_e = -2 m: right of it), the
    line of offset -30 deg through (1, 4): LOS's errors against the virtual reference are
    x_e' = 0 and the distance to that line; its speed is P x LOS's speed command."""
    g = SBMPCGains()
    state = np.array([2.0, 5.0, NORTH, U, 0.0, 0.0])
    ref = np.array([0.0, 5.5, NORTH, 0.0, U, 0.0, U])   # the reference point 0.5 m ahead
    angle = NORTH - math.radians(30.0)
    out, pi_p, x_e, y_e = virtual_reference(state, ref, (1.0, 4.0, angle), 0.5, los := g.as_array())
    assert pi_p == pytest.approx(NORTH) and x_e == pytest.approx(-0.5) and y_e == pytest.approx(-2.0)
    c, s = math.cos(angle), math.sin(angle)
    ex, ey = state[0] - out[0], state[1] - out[1]
    assert c * ex + s * ey == pytest.approx(0.0, abs=1e-12)                       # x_e' = 0
    assert -s * ex + c * ey == pytest.approx(-s * (2.0 - 1.0) + c * (5.0 - 4.0))  # y_e' = the line's
    u_c = U + 0.3 * 0.5 / math.sqrt(0.25 + 4.0)   # u_p - u_at x_e / sqrt(x_e^2 + l_at^2)
    assert math.hypot(out[3], out[4]) == pytest.approx(0.5 * u_c)
    assert math.atan2(out[4], out[3]) == pytest.approx(angle) and out[2] == pytest.approx(angle)
    # on the path itself (no line): the point abeam of the vessel at the true cross-track error
    out, *_ = virtual_reference(state, ref, None, 1.0, los)
    assert (out[0], out[1]) == pytest.approx((0.0, 5.0)) and out[4] == pytest.approx(u_c)


def test_the_cost_terms_by_hand():
    """mu: a head-on target 20 m ahead; an own ship that has turned 30 deg to port (course 120 deg)
    sees it to starboard (bearing 90 deg ENU is clockwise of 120 deg) while close: kappa = 10 (+
    kappa_TC = 20, it was dead ahead at t0, not on starboard); the same own ship turned to starboard
    (course 60 deg) sees it to port: 0. The control cost of (-30 deg, 1) after (0, 1): K_chi,stbd
    (pi/6)^2 + K_dchi,stbd (pi/6)^2; of (30 deg, 0.5): the port weights, K_u 0.5, K_du 0.5."""
    g = SBMPCGains()
    k = g.packed()
    length, speed = 1.98, U
    flags = pair_flags(0.0, 0.0, 0.0, U, 0.0, 1.0, 0.0, 20.0, 0.0, -U, 0.0, -1.0, k)
    assert flags == (False, False, False, True, False, False)      # head-on only
    target = np.array([[0.0, 20.0, 0.0, -U, length] + [float(f) for f in flags]])
    for course_deg, expected in ((120.0, 30.0), (60.0, 0.0)):
        c = math.radians(course_deg)
        track = np.array([[0.0, 0.0, U * math.cos(c), U * math.sin(c)]])   # one sample, 20 m apart: no risk
        assert behaviour_hazard(track, target, length, speed, c - NORTH, k, 0.5) == pytest.approx(expected)
    # a risk: 3 m ahead and closing at 1.2 m/s at tau = 0.5 s: hull to hull 3 - 1.98 = 1.02 m < d_safe = 7.92 m
    track = np.array([[0.0, 17.0 - 0.3, 0.0, U]])
    d_h = 3.0 - 1.98
    risk = 0.8 * (2 * U / U) ** 2 * (4 * length / d_h) ** 4 / 0.5
    assert behaviour_hazard(track, target, length, speed, 0.0, k, 0.5) == pytest.approx(risk)
    # 3 m to the target's east, 0.5 m short of abeam: closing, a risk; 0.5 m past abeam: opening, none
    d_h = math.hypot(3.0, 0.5) - 1.98
    for dy, expected in ((-0.5, 0.8 * 4.0 * (4 * length / d_h) ** 4 / 0.5), (0.5, 0.0)):
        track = np.array([[3.0, 19.7 + dy, 0.0, U]])
        assert behaviour_hazard(track, target, length, speed, 0.0, k, 0.5) == pytest.approx(expected)
    th = math.radians(30.0)
    assert control_cost(-th, 1.0, 0.0, 1.0, k) == pytest.approx((1.3 + 0.9) * th * th)
    assert control_cost(th, 0.5, 0.0, 1.0, k) == pytest.approx((1.6 + 1.2) * th * th + 15 * 0.5 + 6 * 0.5)


def test_the_clearance_criterion_by_hand():
    """Judged where a vessel is in sight (finite range): broken below min_range_m; the deepest
    intrusion reported; round trip through its dict."""
    rec = {"t": np.array([0.0, 1.0, 2.0, 3.0]), "nearest_range": np.array([np.nan, 9.0, 5.0, 7.0])}
    c = Clearance(min_range_m=6.0)
    out = c.evaluate(type("R", (dict,), {"metadata": {}, "status": "completed"})(rec))
    assert (out["passed"], out["violations"], out["judged_steps"]) == (False, 1, 3)
    assert out["first_violation_s"] == 2.0 and out["max_intrusion_m"] == pytest.approx(1.0)
    assert criterion_from_dict(c.to_dict()) == c
    with pytest.raises(ScenarioError, match="min_range_m"):
        Clearance(min_range_m=-1.0)


def test_crossing_from_port_an_unresponsive_give_way_vessel_is_avoided_from_stage_3():
    """The same crossing from port, the give-way target keeping course and speed (it never gives
    way): the own ship stands on while the target is farther than 7.5 L (14.85 m: at about
    t = 16 s, the range closing at 0.6 sqrt(2) = 0.85 m/s from 28.3 m), then avoids it (Rule 17 b)
    to starboard, never to port (Rule 17 c), and stays outside the safety domain."""
    d, own, target = crossing("port", "keep")
    sc, rec = run("analytic", [own, target], 40.0)
    length = sc.vessels[0].scenario.vessel.model.dimensions.L
    o = rec["own"]
    rng = centre_range(rec)
    far = rng > SBMPCGains().stand_on_range_L * length
    assert np.all(o["course_offset"][far] == 0.0) and np.all(o["speed_factor"][far] == 1.0)
    acted = o["course_offset"] != 0.0
    assert acted.any() and np.all(o["course_offset"] <= 0.0)
    assert 14.0 < o["t"][np.argmax(acted)] < 20.0        # the first re-plan after the range passed 14.85 m
    assert first_turn_sign(o, NORTH) == -1.0
    assert rng.min() > SAFETY_DOMAIN_L * length


def test_the_example_scenario_is_the_head_on_tested_here():
    """examples/scenarios/head_on_colav.toml (the README's) is this file's head-on: test_fleet's starts,
    sbmpc on both vessels with crab compensation off, the control period of these tests."""
    sc = load_scenario("head_on_colav")
    assert sc.control_period == DT and sc.plant.kind == "mujoco"
    assert [v.name for v in sc.vessels] == [v["name"] for v in HEAD_ON]
    for v, entry in zip(sc.vessels, HEAD_ON):
        assert v.scenario.controller.kind == "sbmpc" and v.scenario.controller.gains.crab_compensation is False
        assert tuple(v.scenario.initial.eta) == pytest.approx(tuple(entry["initial"]["eta"]))
        assert v.scenario.trajectory.speed == entry["initial"]["nu"][0]
