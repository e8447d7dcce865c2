"""A force controller on the ruddered KVLCC2: the allocation of (tau_u, tau_r) to (n_P, delta).

usv_mj.physics.mmg.mmg_allocate inverts the MMG's propeller and rudder forces (closed form per channel, a
secant on the rudder's drag). It is checked against the forward model it inverts (usv_mj.physics.mmg.mmg_forces,
evaluated here at the allocated inputs), against the limits it must respect, and in closed loop:
the LOS controller of examples/scenarios/kvlcc2_los_circle.toml holds the 40 m circle, whose
steady yaw rate is U/R (kinematics), on both plants alike, and the compiled and the Python loop
give the same record.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from usv_mj import load_scenario
from usv_mj.physics.mmg import mmg_allocate, mmg_forces
from usv_mj.loop.simulate import simulate
from usv_mj.vessels.kvlcc2 import KVLCC2Options, pack

ROOT = Path(__file__).resolve().parents[1]
Q = np.array(pack(KVLCC2Options()))
DELTA_MAX = math.radians(35.0)
N_MAX = 23.7


def forward(u, v, r, n_p, delta):
    """(X_P + X_R, N_R) in usv_mj's frame (y to port) from the MMG frame's forces (y to starboard)."""
    f = mmg_forces(Q, 0, u, -v, -r, n_p, -delta)
    return f[3] + f[4], -f[6]


def test_the_allocated_inputs_give_the_commanded_force_and_moment():
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(3000):
        u, v, r = rng.uniform(0.0, 1.6), rng.uniform(-0.2, 0.2), rng.uniform(-0.08, 0.08)
        tau_u, tau_r = rng.uniform(0.0, 80.0), rng.uniform(-80.0, 80.0)
        n_p, delta, sat_u, sat_r = mmg_allocate(Q, 0, u, v, r, tau_u, tau_r, 0.0, N_MAX, DELTA_MAX)
        assert 0.0 <= n_p <= N_MAX and abs(delta) <= DELTA_MAX + 1e-15
        if sat_u or sat_r:
            continue
        x, n = forward(u, v, r, n_p, delta)
        assert x == pytest.approx(tau_u, abs=1e-6 * (1 + tau_u))
        assert n == pytest.approx(tau_r, abs=1e-9 * (1 + abs(tau_r)))
        checked += 1
    assert checked > 2500   # most commands are within reach at these speeds


def test_a_moment_beyond_the_rudder_is_the_hard_over_rudder_and_a_brake_is_no_thrust():
    """A yaw moment the rudder cannot give saturates at +-35 deg, turning the right way (a positive
    moment turns to port: delta > 0 in usv_mj's frame); a negative surge force (the propeller cannot
    pull astern in the MMG's model) is zero thrust, with sat_u set."""
    for tau_r in (1e4, -1e4):
        n_p, delta, sat_u, sat_r = mmg_allocate(Q, 0, 1.179, 0.0, 0.0, 50.0, tau_r, 0.0, N_MAX, DELTA_MAX)
        assert sat_r == 1.0 and delta == pytest.approx(math.copysign(DELTA_MAX, tau_r))
        assert math.copysign(1.0, forward(1.179, 0.0, 0.0, n_p, delta)[1]) == math.copysign(1.0, tau_r)
    n_p, delta, sat_u, sat_r = mmg_allocate(Q, 0, 1.179, 0.0, 0.0, -30.0, 0.0, 0.0, N_MAX, DELTA_MAX)
    f = mmg_forces(Q, 0, 1.179, 0.0, 0.0, n_p, -delta)
    assert sat_u == 1.0 and abs(f[3]) < 1e-9 and n_p > 0   # the zero-thrust revolutions: K_T(J_P) = 0
    n_p, _, sat_u, _ = mmg_allocate(Q, 0, 1.179, 0.0, 0.0, 1e5, 0.0, 0.0, N_MAX, DELTA_MAX)
    assert (n_p, sat_u) == (N_MAX, 1.0)
    n_p, delta, _, sat_r = mmg_allocate(Q, 0, 0.0, 0.0, 0.0, 0.0, 5.0, 0.0, N_MAX, DELTA_MAX)
    assert (n_p, delta, sat_r) == (0.0, 0.0, 1.0)   # at rest, no revolutions: no flow past the rudder


def test_the_self_propulsion_point_is_the_allocation_of_the_hull_resistance():
    """Straight ahead at 1.179 m/s the resistance X_H = -1/2 rho L d U^2 R'_0 (closed form) asks for
    the revolutions that the module states hold the service speed, 11.85 1/s (to 1 %)."""
    o = KVLCC2Options()
    resistance = 0.5 * o.rho * o.L_pp * o.d * 1.179 ** 2 * o.R_0_dash
    n_p, delta, sat_u, sat_r = mmg_allocate(Q, 0, 1.179, 0.0, 0.0, resistance, 0.0, 0.0, N_MAX, DELTA_MAX)
    assert (delta, sat_u, sat_r) == (0.0, 0.0, 0.0)
    assert n_p == pytest.approx(o.propeller_rps, rel=0.01)


@pytest.fixture(scope="module")
def circle_runs():
    s = load_scenario(path=str(ROOT / "examples/scenarios/kvlcc2_los_circle.toml"))
    return s, {plant: simulate(s, plant_kind=plant) for plant in ("analytic", "mujoco")}


def test_los_holds_the_circle_on_both_plants(circle_runs):
    """After 100 s the LOS controller keeps the 40 m circle to 1 m (0.14 L); its yaw rate is then the
    circle's U/R (the speed along it over the radius) to 3 %; the two plants agree to 1e-6 m."""
    s, runs = circle_runs
    a, m = runs["analytic"], runs["mujoco"]
    assert a.metadata["status"] == "completed" and m.metadata["status"] == "completed"
    late = a["t"] >= 100.0
    cte = np.abs(np.hypot(a["x"], a["y"] - 40.0) - 40.0)
    assert cte[late].max() < 1.0
    speed = np.hypot(a["u"], a["v"])[late].mean()
    assert a["r"][late].mean() == pytest.approx(speed / 40.0, rel=0.03)
    assert np.abs(a["f_r"]).max() <= math.radians(35.0) + 1e-12 and a["f_u"].min() >= 0.0
    assert max(np.abs(a[c] - m[c]).max() for c in ("x", "y")) < 1e-6


def test_the_compiled_and_the_python_loop_allocate_alike(circle_runs):
    s, runs = circle_runs
    short = s.with_overrides({"duration": 20.0})
    slow = simulate(short, plant_kind="analytic", loop="python")
    fast = runs["analytic"]
    n = len(slow["t"])
    assert slow.metadata["loop"] == "python" and fast.metadata["loop"] == "compiled"
    for col in ("x", "y", "psi", "u", "v", "r", "f_u", "f_r", "sat_u", "sat_r"):
        assert np.array_equal(fast[col][:n], slow[col]), col


def test_ppc_and_pi_run_on_the_tanker_on_both_plants():
    """The paper's law and the PI baseline drive KVLCC2 (allocated), the plants agreeing."""
    s = load_scenario(path=str(ROOT / "examples/scenarios/kvlcc2_los_circle.toml"),
                      overrides={"duration": 30.0})
    for kind in ("ppc", "pi"):
        a = simulate(s, plant_kind="analytic", controller_kind=kind)
        m = simulate(s, plant_kind="mujoco", controller_kind=kind)
        assert a.metadata["status"] == m.metadata["status"] == "completed"
        assert max(np.abs(a[c] - m[c]).max() for c in ("x", "y")) < 1e-5, kind
        assert np.isfinite(a["f_u"]).all() and a["f_u"].min() >= 0.0


def test_the_video_says_what_the_channels_hold(circle_runs):
    """The record names what its columns carry (usv_mj.physics.channels.RunChannels): a force
    controller's run on KVLCC2 is allocated (tau in N, f in 1/s and rad), so the HUD's force bars get
    no rudder-angle ticks and its text shows n_P [1/s] and delta [deg]; the open-loop manoeuvre's
    command is n_P and delta themselves; the paper hull's are forces."""
    from usv_mj.outputs.render.planner import plan_frames
    from usv_mj.physics.channels import FORCES, PROPELLER, RUDDER_ANGLE, RunChannels

    s, runs = circle_runs
    rec = runs["analytic"]
    run = RunChannels.from_metadata(rec.metadata["channels"])
    assert run.allocated and run.command == FORCES and (run.applied.surge, run.applied.yaw) == (PROPELLER, RUDDER_ANGLE)
    hud = plan_frames(rec, max_frames=2, width=320, height=180).frames[-1].hud
    assert hud["channels"]["allocated"] and hud["tau_r_limits"] is None
    assert hud["channels"]["rows"] == (("tau_u", "n_P", "1/s", 1.0), ("tau_r", "delta", "deg", pytest.approx(57.29578)))
    assert hud["f_u"] == pytest.approx(rec["f_u"][hud_row(rec, hud["t"])])
    opened = simulate(s.with_overrides({"duration": 1.0}), plant_kind="analytic", controller_kind="open_loop")
    run = RunChannels.from_metadata(opened.metadata["channels"])
    assert not run.allocated and (run.command.surge, run.command.yaw) == (PROPELLER, RUDDER_ANGLE)
    paper = simulate(load_scenario(preset="paper", overrides={"duration": 0.01}), plant_kind="analytic")
    run = RunChannels.from_metadata(paper.metadata["channels"])
    assert not run.allocated and run.command == FORCES


def hud_row(record, t):
    return int(np.argmin(np.abs(record["t"] - t)))


def test_the_steering_gear_stays_when_a_scenario_changes_one_actuator_key():
    """A scenario's [actuators] keys change KVLCC2's one by one: a slower rudder keeps the 35 deg
    limit and the n_P cap (replacing the table would leave the rudder unlimited)."""
    s = load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}, "actuators": {"yaw_rate_nm_s": 0.2}})
    assert s.actuators.kind == "box" and s.actuators.yaw_rate_nm_s == 0.2
    assert s.actuators.max_yaw_nm == pytest.approx(DELTA_MAX) and s.actuators.max_surge_n == N_MAX
    from usv_mj.core.errors import ScenarioError

    with pytest.raises(ScenarioError, match=r"actuators.max_yaw_nm = 3.0 is the limit of the vessel 'kvlcc2''s "
                                            r"rudder angle \[rad\] and must be < 1.5708 rad"):
        load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}, "actuators": {"max_yaw_nm": 3.0}})


def test_bad_propeller_numbers_and_rudders_beyond_the_gear_are_refused():
    from usv_mj.core.errors import ScenarioError
    from usv_mj.jobs.manoeuvres import spiral

    for key, value in (("k_0", 0.0), ("t_P", 1.0), ("w_P0", 1.0)):
        with pytest.raises(ScenarioError, match=f"vessel.{key} must be"):
            load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2", key: value}})
    with pytest.raises(ScenarioError, match="manoeuvre.max_rudder_deg = 90.0 deg is beyond the rudder"):
        spiral(load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}}), plant_kind="analytic",
               max_rudder_deg=90.0)


def test_non_finite_commands_are_flagged_not_passed_on():
    n_p, delta, sat_u, sat_r = mmg_allocate(Q, 0, 1.0, 0.0, 0.0, math.inf, -math.inf, 0.0, N_MAX, DELTA_MAX)
    assert (n_p, sat_u, sat_r) == (N_MAX, 1.0, 1.0) and delta == pytest.approx(-DELTA_MAX)
    assert mmg_allocate(Q, 0, 1.0, 0.0, 0.0, math.nan, 0.0, 0.0, N_MAX, DELTA_MAX) == (0.0, 0.0, 1.0, 1.0)


def test_the_gymnasium_view_takes_a_braking_force_as_no_thrust():
    """KVLCC2's least surge force is 0: a negative one normalizes to 0 (no division by the 0 bound,
    which made it full ahead), and the negative half of the action is 0 N."""
    import warnings

    from usv_mj.envs.gymnasium_env import USVGymEnv

    env = USVGymEnv("track", seed=0, vessel="kvlcc2", duration=0.1)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            a = env.normalized_action([-5.0, 0.0])
        assert a.tolist() == [0.0, 0.0] and env.physical_action([-0.7, 0.0]).tolist() == [0.0, 0.0]
        assert env.physical_action([1.0, -1.0]).tolist() == pytest.approx([env._high[0], env._low[1]])
    finally:
        env.close()
