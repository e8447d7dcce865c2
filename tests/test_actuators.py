"""The actuator model (issue 18) against numbers computed by hand, not by the code under test."""

import math

import numba
import numpy as np
import pytest

from usv_mj import load_scenario, simulate, summarize
from usv_mj.physics.actuators import ActuatorSpec, Actuators, actuator_step
from usv_mj.builder import make_plant
from usv_mj.scenario.spec import ScenarioError

# the paper-limited preset: Fossen's Otter propellers (usv_mj/scenario/presets/paper-limited.toml)
S, F, R = 0.79, 119.7, 66.7
TWIN = ActuatorSpec(kind="twin", separation_m=S, thruster_forward_n=F, thruster_reverse_n=R)


def _apply(spec, q_u, q_r, dt=0.001):
    act = Actuators(spec, dt)
    act.reset()
    return act.apply(q_u, q_r)


# --- allocation and saturation ------------------------------------------------------------------


def test_twin_sign_convention_stronger_starboard_turns_to_port():
    # T_s = 100 N (y = -0.395 m), T_p = 20 N (y = +0.395 m): N = -y F_x summed = 0.395 (100 - 20) > 0
    f_u, f_r, s_u, s_r = _apply(TWIN, 120.0, 0.395 * 80.0)
    assert (f_u, f_r, s_u, s_r) == (120.0, pytest.approx(31.6, abs=1e-12), 0.0, 0.0)


def test_twin_generalized_limits_by_hand():
    lo_u, hi_u, lo_r, hi_r = TWIN.generalized_limits()
    assert (lo_u, hi_u) == (pytest.approx(-133.4), pytest.approx(239.4))
    assert (lo_r, hi_r) == (pytest.approx(-73.628), pytest.approx(73.628))  # 0.395 x 186.4


@pytest.mark.parametrize("q, expected, sat", [
    ((100.0, 10.0), (100.0, 10.0), (0.0, 0.0)),        # T_s = 62.66, T_p = 37.34: inside
    ((300.0, 0.0), (239.4, 0.0), (1.0, 0.0)),          # both thrusters at 119.7
    ((-300.0, 0.0), (-133.4, 0.0), (1.0, 0.0)),        # both at -66.7
    ((200.0, 50.0), (2 * (119.7 - 50 / 0.79), 50.0), (1.0, 0.0)),   # yaw kept, T_s at its limit
    ((0.0, 100.0), (2 * (119.7 - 73.628 / 0.79), 73.628), (1.0, 1.0)),  # yaw at its limit; T_s = F, T_p = -R
    ((0.0, -100.0), (53.0, -73.628), (1.0, 1.0)),
])
def test_twin_yaw_priority_against_a_hand_computation(q, expected, sat):
    f_u, f_r, s_u, s_r = _apply(TWIN, *q)
    assert f_u == pytest.approx(expected[0], abs=1e-9) and f_r == pytest.approx(expected[1], abs=1e-9)
    assert (s_u, s_r) == sat
    # the thrusters are within their limits: T_s = tau_u/2 + tau_r/s, T_p = tau_u/2 - tau_r/s
    for t in (f_u / 2 + f_r / S, f_u / 2 - f_r / S):
        assert -R - 1e-9 <= t <= F + 1e-9


def test_twin_surge_priority_against_a_hand_computation():
    spec = ActuatorSpec(kind="twin", separation_m=S, thruster_forward_n=F, thruster_reverse_n=R, priority="surge")
    f_u, f_r, s_u, s_r = _apply(spec, 200.0, 50.0)
    assert f_u == 200.0 and f_r == pytest.approx(0.79 * (119.7 - 100.0), abs=1e-12)  # 15.563 N m
    assert (s_u, s_r) == (0.0, 1.0)


def test_box_clips_each_channel_on_its_own():
    spec = ActuatorSpec(kind="box", max_surge_n=200.0, max_reverse_n=50.0, max_yaw_nm=30.0)
    assert _apply(spec, 500.0, -40.0) == (200.0, -30.0, 1.0, 1.0)
    assert _apply(spec, -70.0, 10.0) == (-50.0, 10.0, 1.0, 0.0)
    assert _apply(spec, 20.0, 10.0) == (20.0, 10.0, 0.0, 0.0)


# --- dynamics -----------------------------------------------------------------------------------


def test_first_order_lag_against_exp():
    """Step of 100 N, T = 0.2 s, h = 10 ms: the lag's thrust at t_k is 100 (1 - exp(-t_k/T)), and the
    held forces carry the impulse of the continuous lag, 100 (t - T (1 - exp(-t/T)))."""
    T, h, c = 0.2, 0.01, 100.0
    act = Actuators(ActuatorSpec(time_constant_s=T), h)
    act.reset()
    impulse = 0.0
    for k in range(1, 201):
        f_u, f_r, s_u, s_r = act.apply(c, 0.0)
        impulse += f_u * h
        t = k * h
        assert act.state[0] == pytest.approx(c * (1 - math.exp(-t / T)), rel=1e-12, abs=1e-12)
        assert impulse == pytest.approx(c * (t - T * (1 - math.exp(-t / T))), rel=1e-12)
        assert s_u == 0.0 and f_r == 0.0


def test_rate_limit_ramps_at_the_rate():
    act = Actuators(ActuatorSpec(surge_rate_n_s=500.0, yaw_rate_nm_s=100.0), 0.01)
    act.reset()
    out = [act.apply(100.0, -3.0) for _ in range(25)]
    assert [o[0] for o in out] == pytest.approx([min(5.0 * (k + 1), 100.0) for k in range(25)])
    assert [o[1] for o in out] == pytest.approx([-1.0, -2.0, -3.0] + [-3.0] * 22)
    assert [o[2] for o in out] == [1.0] * 19 + [0.0] * 6


def test_the_kernel_compiles_with_numba_and_gives_the_same_numbers():
    @numba.njit
    def step(p, s, u, r):
        return actuator_step(p, s, u, r)

    spec = ActuatorSpec(kind="twin", separation_m=S, thruster_forward_n=F, thruster_reverse_n=R,
                        time_constant_s=0.3, surge_rate_n_s=400.0)
    a, b = Actuators(spec, 0.01), Actuators(spec, 0.01)
    for k in range(50):
        q = (300.0 * math.sin(0.3 * k), 80.0 * math.cos(0.2 * k))
        assert step(a.params, a.state, *q) == b.apply(*q)


def test_spec_validation():
    with pytest.raises(ValueError, match="twin"):
        ActuatorSpec(kind="twin")
    with pytest.raises(ValueError, match="priority"):
        ActuatorSpec(priority="sway")
    with pytest.raises(ScenarioError):
        load_scenario(overrides={"actuators": {"kind": "box", "max_surge_n": -1.0}})


# --- on the plants ------------------------------------------------------------------------------


def _steady_speed_by_hand(force):
    """The root u > 0 of d11(u) u = 10 u^3 + 67.26 u^2 + 45.6 u = force (ship.py's d11). One sign
    change, so one positive root (Descartes), the largest of three real ones here: Viete's
    trigonometric form of the depressed cubic t^3 + p t + q = 0 (u = t - b/(3a)), k = 0."""
    a, b, c, d = 10.0, 67.26, 45.6, -force
    p = (3 * a * c - b * b) / (3 * a * a)
    q = (2 * b ** 3 - 9 * a * b * c + 27 * a * a * d) / (27 * a ** 3)
    assert p < 0 and 4 * p ** 3 + 27 * q * q < 0  # three real roots
    t = 2 * math.sqrt(-p / 3) * math.cos(math.acos(3 * q / (2 * p) * math.sqrt(-3 / p)) / 3)
    return t - b / (3 * a)


@pytest.mark.parametrize("kind", ["analytic", "mujoco"])
def test_saturated_steady_surge_speed_is_the_closed_form(kind):
    """A 1000 N surge command on the twin hull: 2 x 119.7 = 239.4 N reach the hull, and it settles
    where d11(u) u = 239.4 N (no Delta, no d(t))."""
    u_star = _steady_speed_by_hand(239.4)
    assert 1.45 < u_star < 1.46
    sc = load_scenario(preset="paper-limited", overrides={
        "control_period": 0.01, "initial": {"eta": [0.0, 0.0, 0.0]},
        "ship": {"uncertainty_scale": 0.0}, "disturbance": {"scale": 0.0}})
    act = Actuators.from_scenario(sc)
    plant = make_plant(sc, kind)
    try:
        plant.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        for _ in range(4000):
            f_u, f_r, s_u, s_r = act.apply(1000.0, 0.0)
            plant.step(f_u, f_r)
        assert (f_u, f_r, s_u) == (pytest.approx(239.4), 0.0, 1.0)
        x = plant.state
    finally:
        plant.close()
    assert x[3] == pytest.approx(u_star, abs=1e-9)
    assert abs(x[4]) < 1e-12 and abs(x[5]) < 1e-12


def test_mujoco_ctrlrange_is_the_spec_limits():
    sc = load_scenario(preset="paper-limited")
    plant = make_plant(sc, "mujoco")
    try:
        assert list(plant.model.actuator_ctrllimited) == [1, 1]
        assert plant.model.actuator_ctrlrange.ravel().tolist() == pytest.approx(
            [-133.4, 239.4, -73.628, 73.628])
    finally:
        plant.close()
    box = load_scenario(overrides={"actuators": {"kind": "box", "max_surge_n": 300.0, "max_yaw_nm": 40.0}})
    plant = make_plant(box, "mujoco")
    try:
        assert plant.model.actuator_ctrlrange.ravel().tolist() == [-1e10, 300.0, -40.0, 40.0]
    finally:
        plant.close()
    plant = make_plant(load_scenario(preset="paper"), "mujoco")
    try:
        assert list(plant.model.actuator_ctrllimited) == [0, 0]
    finally:
        plant.close()


def test_paper_preset_is_unlimited_and_the_plant_gets_q_tau_exactly():
    sc = load_scenario(preset="paper", overrides={"duration": 3.0, "plant": {"kind": "analytic"}})
    assert sc.actuators.unlimited and sc.actuators.kind == "unlimited"
    rec = simulate(sc)
    assert np.array_equal(rec["f_u"], rec["q_tau_u"]) and np.array_equal(rec["f_r"], rec["q_tau_r"])
    assert not rec["sat_u"].any() and not rec["sat_r"].any()
    s = summarize(rec)
    assert s["actuators"]["unlimited"] and s["saturation_episodes"] == {"u": 0, "r": 0}
    assert not [e for e in rec.events if e.kind == "actuator_saturation"]


@pytest.fixture(scope="module")
def limited_pair():
    sc = load_scenario(preset="paper-limited", overrides={"duration": 8.0})
    return {kind: simulate(sc, plant_kind=kind) for kind in ("analytic", "mujoco")}


def test_both_plants_agree_under_saturation(limited_pair):
    a, m = limited_pair["analytic"], limited_pair["mujoco"]
    assert a["sat_u"].mean() > 0.01 and a["sat_r"].mean() > 0.01   # the limits act
    assert np.array_equal(a["sat_u"], m["sat_u"]) and np.array_equal(a["sat_r"], m["sat_r"])
    assert np.max(np.hypot(a["x"] - m["x"], a["y"] - m["y"])) < 1e-9
    lo_u, hi_u, lo_r, hi_r = TWIN.generalized_limits()
    for rec in (a, m):
        assert np.all((rec["f_u"] >= lo_u - 1e-9) & (rec["f_u"] <= hi_u + 1e-9))
        t_s, t_p = rec["f_u"] / 2 + rec["f_r"] / S, rec["f_u"] / 2 - rec["f_r"] / S
        assert np.all((t_s >= -R - 1e-9) & (t_s <= F + 1e-9) & (t_p >= -R - 1e-9) & (t_p <= F + 1e-9))


def test_saturation_episodes_are_events_and_in_the_summary(limited_pair):
    rec = limited_pair["analytic"]
    s = summarize(rec)
    for ch in ("u", "r"):
        starts = [e for e in rec.events if e.kind == "actuator_saturation" and e.values["channel"] == ch
                  and e.values["state"] == "start"]
        ends = [e for e in rec.events if e.kind == "actuator_saturation" and e.values["channel"] == ch
                and e.values["state"] == "end"]
        flag = rec[f"sat_{ch}"] > 0.5
        n_starts = int(np.sum(flag & ~np.concatenate(([False], flag[:-1]))))
        assert len(starts) == n_starts == s["saturation_episodes"][ch] > 0
        assert len(ends) in (n_starts, n_starts - 1)
        assert s["saturated_fraction"][ch] == pytest.approx(flag.mean())
    assert s["actuators"]["kind"] == "twin" and "119.7" in s["actuators"]["description"]


def test_report_says_unlimited_for_paper_and_gives_episodes_when_limited(tmp_path, limited_pair):
    from usv_mj.outputs.report import write_report

    paper = summarize(simulate(load_scenario(preset="paper", overrides={"duration": 1.0, "plant": {"kind": "analytic"}})))
    text = write_report(tmp_path / "a.md", paper).read_text()
    assert "**The actuators are unlimited**" in text
    text = write_report(tmp_path / "b.md", summarize(limited_pair["analytic"])).read_text()
    assert "Actuators: twin" in text and "| surge |" in text


def test_video_bars_draw_the_limits():
    from usv_mj.outputs.render.overlay import BAD, draw_hud

    values = {"t": 1.0, "t_end": 10.0, "speedup": 1.0, "e": (0.1, 0.1, 0.1), "rho": (1.0, 1.0, 1.0),
              "tau_u": 900.0, "q_tau_u": 900.0, "f_u": 239.4, "sat_u": 1.0, "tau_r": 5.0, "q_tau_r": 5.0,
              "f_r": 5.0, "sat_r": 0.0, "tau_u_scale": 299.25, "tau_r_scale": 92.0,
              "tau_u_limits": (-133.4, 239.4), "tau_r_limits": (-73.6, 73.6)}
    with_limits = draw_hud(np.zeros((720, 1280, 3), np.uint8), values, legend=False)
    without = draw_hud(np.zeros((720, 1280, 3), np.uint8), {**values, "tau_u_limits": None, "tau_r_limits": None,
                                                            "sat_u": 0.0}, legend=False)
    red = lambda img: int(np.sum(np.all(img == BAD, axis=-1)))  # noqa: E731
    assert red(with_limits) > red(without)
