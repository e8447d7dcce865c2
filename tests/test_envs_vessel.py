"""usv_mj.envs on another vessel (issue 26): the environment's physics, action bounds, actuators,
policy model and pictures are the vessel's, as ``usv-mj run --vessel`` has them.

Independent numbers: the Otter's data file (usv_mj/vessels/data/otter.toml: mass, x_g, I_z, the
propellers' bollard pulls and separation) and models/usv.xml's hull (1.98 m x 0.76 m), worked
through by hand here (the twin allocation's corners, the shaft-speed lag's closed form from rest);
the closed loop of ``usv-mj run`` (``usv_mj.loop.simulate.simulate``) for the same actions."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from usv_mj import envs

OTTER = tomllib.loads((Path(__file__).resolve().parents[1] / "usv_mj" / "vessels" / "data" / "otter.toml")
                      .read_text())
ACT = OTTER["actuators"]
F, R, S = ACT["thruster_forward_n"], ACT["thruster_reverse_n"], ACT["separation_m"]   # N, N, m
T_N = ACT["shaft_time_constant_s"]
DT = 0.01                                                         # the tasks' control period [s]


def test_otter_track_has_the_vessels_rigid_body_and_twin_thruster_bounds():
    env = envs.load("track", seed=0, vessel="otter", duration=0.05)
    try:
        d = OTTER["derivatives"]
        m, x_g, i_z = d["m"], d["x_g"], d["I_z"]
        model = env.physics.model
        hull = model.body("hull").id
        assert model.body_mass[hull] == pytest.approx(m, rel=1e-12)                   # 80 kg, not the paper's
        assert model.body_ipos[hull][0] == pytest.approx(x_g, abs=1e-12)
        assert model.body_inertia[hull][2] == pytest.approx(i_z - m * x_g ** 2, rel=1e-12)  # about the CG
        assert env.task.scenario.vessel.model.rigid_body() == pytest.approx((m, x_g, i_z), rel=1e-12)
        # each channel's own range: both propellers ahead / astern for surge, opposed for yaw
        spec = env.action_spec()
        half = S / 2
        np.testing.assert_allclose(spec.minimum, [-2 * R, -half * (F + R)], rtol=1e-15)
        np.testing.assert_allclose(spec.maximum, [2 * F, half * (F + R)], rtol=1e-15)
        assert spec.maximum.tolist() == pytest.approx([239.364, 73.62405], rel=1e-12)
    finally:
        env.close()
    g = envs.gym_env("track", seed=0, vessel="otter", duration=0.05)
    try:
        assert g.physical_action(np.array([1.0, 1.0], np.float32)).tolist() == pytest.approx([2 * F, half * (F + R)])
        assert g.physical_action(np.array([-1.0, -1.0], np.float32)).tolist() == pytest.approx(
            [-2 * R, -half * (F + R)])
    finally:
        g.close()


def test_the_twin_propellers_allocate_and_lag_as_worked_by_hand():
    """quantize=False: the action reaches the actuators as given. A pure surge command from rest:
    each propeller's shaft n(t) = n_c (1 - e^(-t/T_n)), thrust k n^2, so the first period's mean
    thrust is tau_u (1 - 2 (T_n/h)(1 - e^(-h/T_n)) + (T_n/2h)(1 - e^(-2h/T_n))). Full surge and full
    yaw together lie outside the twin's reachable set: yaw first (the data file's priority), the
    starboard propeller at F and the port one at -R, so tau_u -> F - R and tau_r -> (S/2)(F + R)."""
    env = envs.load("track", seed=0, vessel="otter", duration=2.5, quantize=False)
    try:
        env.reset()
        env.step(np.array([100.0, 0.0]))
        h = DT
        mean = 1 - 2 * (T_N / h) * (1 - math.exp(-h / T_N)) + (T_N / (2 * h)) * (1 - math.exp(-2 * h / T_N))
        assert env.task.last_command.tolist() == [100.0, 0.0]
        assert env.task.last_thrust[0] == pytest.approx(100.0 * mean, rel=1e-9)         # 0.31 % of it
        assert env.physics.plant.data.ctrl[0] == env.task.last_thrust[0]                 # what MuJoCo gets
        assert env.task.last_thrust[1] == pytest.approx(0.0, abs=1e-12)
        env.reset()
        for _ in range(200):                                                             # 2 s = 20 T_n
            ts = env.step(np.array([2 * F, S / 2 * (F + R)]))
        assert not ts.last() or env.task.info["kind"] == "time_limit"
        assert env.task.last_thrust.tolist() == pytest.approx([F - R, S / 2 * (F + R)], rel=1e-6)
        assert env.task.last_saturated.tolist() == [1.0, 0.0]                            # surge was cut
        record = envs.episode_record(env, env.history()[-2:])                           # the video's record
        assert record["q_tau_u"][-1] == 2 * F and record["tau_u"][-1] == 2 * F
        assert record["f_u"][-1] == env.task.last_thrust[0] and record["sat_u"][-1] == 1.0
    finally:
        env.close()


class _Scripted:
    """A controller that plays a fixed list of (tau_u, tau_r), one per control period."""

    name, diagnostic_fields = "scripted", ()

    def __init__(self, actions):
        self.actions = actions

    def reset(self):
        pass

    def __call__(self, t, x, ref):
        k = min(int(round(t / DT)), len(self.actions) - 1)
        return float(self.actions[k, 0]), float(self.actions[k, 1]), np.zeros(0)


def test_an_otter_episode_is_the_runs_closed_loop_for_the_same_actions():
    """The environment integrates what `usv-mj run --vessel otter --plant mujoco` integrates: the
    same actions through the same quantizer, twin allocation and shaft lag give the same states
    and thrusts as simulate() on a fresh plant (actions within each channel's bounds, often outside
    the twin's coupled set, and switching sign so the shafts reverse)."""
    from usv_mj.loop.simulate import simulate

    n = 150
    rng = np.random.RandomState(3)
    actions = np.column_stack([rng.uniform(-2 * R, 2 * F, n), rng.uniform(-S / 2 * (F + R), S / 2 * (F + R), n)])
    env = envs.load("track", seed=1, vessel="otter", duration=n * DT)
    try:
        ts = env.reset()
        states, thrusts = [env.physics.state.copy()], []
        for a in actions:
            ts = env.step(a)
            states.append(env.physics.state.copy())
            thrusts.append(env.task.last_thrust.copy())
        assert ts.last() and env.task.info["kind"] == "time_limit"
        states, thrusts = np.array(states), np.array(thrusts)
        sc = env.task.scenario.with_overrides({"initial": {"eta": [float(v) for v in states[0, :3]],
                                                            "nu": [0.0, 0.0, 0.0]}})
        record = simulate(sc, plant_kind="mujoco", controller=_Scripted(actions), duration=n * DT,
                          reference=env.task.reference)
    finally:
        env.close()
    assert record.status == "completed" and record.n_rows == n + 1
    run_f = np.column_stack([record["f_u"], record["f_r"]])[:n]
    assert np.max(np.abs(run_f - thrusts)) < 1e-9, np.max(np.abs(run_f - thrusts))
    assert np.any(np.abs(run_f[:, 0] - np.array(record["q_tau_u"])[:n]) > 1.0)   # the actuators did act
    err = np.hypot(record["x"] - states[:, 0], record["y"] - states[:, 1])
    print(f"\nOtter env vs simulate(), 150 steps: position {np.max(err):.3g} m, thrust "
          f"{np.max(np.abs(run_f - thrusts)):.3g} N / N m")
    assert np.max(err) < 1e-9, np.max(err)
    assert np.max(np.abs(record["psi"] - states[:, 2])) < 1e-9
    assert np.hypot(*(states[-1, :2] - states[0, :2])) > 0.05                     # it moved


def test_ppc_policy_takes_the_vessels_nominal_model_and_its_options():
    """The policy's nominal model is scenario.nominal_ship (the vessel's hull times model_mismatch,
    as `usv-mj run` gives it); --set vessel.KEY reaches the vessel: m22 = m - Y_vdot of the file."""
    d = OTTER["derivatives"]
    env = envs.load("track", seed=0, vessel="otter", duration=0.05, overrides={"vessel": {"model_mismatch": 1.3}})
    try:
        nominal = envs.PPCPolicy(env).controller.nominal
        assert nominal.m22 == pytest.approx(1.3 * (d["m"] - d["Y_vdot"]), rel=1e-12)          # 211.25 kg
        assert env.task.scenario.ship.m22 == pytest.approx(d["m"] - d["Y_vdot"], rel=1e-12)   # the plant's
    finally:
        env.close()
    env = envs.load("track", seed=0, vessel="otter", duration=0.05, overrides={"vessel": {"m": 90.0}})
    try:
        assert env.physics.model.body_mass[env.physics.model.body("hull").id] == pytest.approx(90.0)
    finally:
        env.close()


def test_a_kvlcc2_episode_is_the_runs_allocated_closed_loop_for_the_same_actions():
    """On the ruddered KVLCC2 the action (a force and a moment) is allocated to n_P and the rudder
    angle at the state, as a force controller's command in `usv-mj run --vessel kvlcc2`: the same
    actions give the same states and plant inputs as simulate() on a fresh plant; the bounds are
    the forward model's reach at 1.179 m/s (usv_mj.physics.mmg.mmg_forces at n_P = 23.7 1/s: the rudder
    amidships for surge, hard over for yaw)."""
    from usv_mj.physics.mmg import mmg_forces
    from usv_mj.loop.simulate import simulate
    from usv_mj.vessels.kvlcc2 import KVLCC2Options, pack

    q = np.array(pack(KVLCC2Options()))
    ahead = mmg_forces(q, 0, 1.179, 0.0, 0.0, 23.7, 0.0)
    hard = mmg_forces(q, 0, 1.179, 0.0, 0.0, 23.7, math.radians(35.0))
    n = 120
    rng = np.random.RandomState(5)
    env = envs.load("track", seed=2, vessel="kvlcc2", duration=n * DT)
    try:
        spec = env.action_spec()
        assert spec.minimum.tolist() == [0.0, pytest.approx(-abs(hard[6]))]
        assert spec.maximum.tolist() == [pytest.approx(ahead[3] + ahead[4]), pytest.approx(abs(hard[6]))]
        actions = np.column_stack([rng.uniform(0.0, spec.maximum[0], n), rng.uniform(spec.minimum[1], spec.maximum[1], n)])
        env.reset()
        states, inputs = [env.physics.state.copy()], []
        for a in actions:
            env.step(a)
            states.append(env.physics.state.copy())
            inputs.append(env.task.last_thrust.copy())
        states, inputs = np.array(states), np.array(inputs)
        sc = env.task.scenario.with_overrides({"initial": {"eta": [float(v) for v in states[0, :3]],
                                                            "nu": [float(v) for v in states[0, 3:]]}})
        record = simulate(sc, plant_kind="mujoco", controller=_Scripted(actions), duration=n * DT,
                          reference=env.task.reference)
    finally:
        env.close()
    run_in = np.column_stack([record["f_u"], record["f_r"]])[:n]
    assert np.max(np.abs(run_in - inputs)) < 1e-9
    assert 0.0 <= inputs[:, 0].min() and inputs[:, 0].max() <= 23.7            # n_P [1/s]
    assert np.abs(inputs[:, 1]).max() <= math.radians(35.0) + 1e-12 and np.ptp(inputs[:, 1]) > 0.01   # delta [rad]
    assert np.max(np.hypot(record["x"] - states[:, 0], record["y"] - states[:, 1])) < 1e-9


def test_bad_vessels_are_refused_in_one_line():
    with pytest.raises(ValueError, match="runs in calm deep water only.*the task 'track_waves' is in a sea: the calm "
                                         "tasks are track, harbor"):
        envs.load("track_waves", vessel="kvlcc2")
    with pytest.raises(ValueError, match="unknown vessel kind 'nosuch'"):
        envs.load("track", vessel="nosuch")
    with pytest.raises(ValueError, match="vessel must be a vessel kind"):
        envs.load("track", vessel=3)
    with pytest.raises(ValueError, match="ship"):   # the paper's [ship] options with another vessel
        envs.load("track", vessel="otter", overrides={"ship": {"m": 30.0}})


def test_env_command_takes_the_vessel_flag_of_run(capsys, tmp_path, monkeypatch):
    import argparse

    from usv_mj.cli.main import build_parser, main

    monkeypatch.chdir(tmp_path)
    assert main(["env", "track", "--vessel", "otter", "--duration", "0.2", "--video", "none",
                 "--set", "vessel.model_mismatch=1.1"]) == 0
    assert "episode 1: return" in capsys.readouterr().out
    for argv, word in ((["--vessel", "nosuch"], "nosuch"), (["--vessel", "kvlcc2", "--set", "vessel.max_propeller_rps=-1"],
                                                            "vessel.max_propeller_rps must be > 0")):
        assert main(["env", "track", *argv, "--duration", "0.2", "--video", "none"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("usv-mj env: error:") and word in err, err
    # the same flag as usv-mj run's: one definition (usv_mj.cli.args.add_vessel_argument)
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = [next(a.help for a in sub.choices[c]._actions if "--vessel" in a.option_strings) for c in ("run", "env")]
    assert helps[0] == helps[1]


def _hull_columns(frame):
    """Column extent [px] of the hull's dark parts (the transom, the bottom's shade: every channel
    below 45) in a chase view, below the heads-up panel and above the legend."""
    part = frame[100:195, 100:].astype(int)
    cols = np.nonzero((part.max(axis=2) < 45).any(axis=0))[0]
    return cols.max() - cols.min() + 1


def test_the_environments_picture_draws_the_vessels_hull():
    """render_frame (and physics.render, the same frame) draws the Otter's hull, through the
    run video's path (render.world.hull_dimensions -> the replay model scaled by scale_hull): seen
    from the chase camera (on the hull, its distance scaled by the length ratio) the hull's width
    in pixels grows by (B_otter / B_paper) / (L_otter / L_paper) = (1.08 / 0.76) / (2.0 / 1.98)."""
    widths = {}
    for vessel in ("paper", "otter"):
        env = envs.load("track", seed=0, vessel=vessel, duration=0.5, start_offset=(0.0, 0.0, 0.0))
        try:
            env.reset()
            frame = env.render_frame(width=320, height=240, camera="chase")
            assert np.array_equal(frame, env.physics.render(240, 320, camera_id="chase"))
            widths[vessel] = _hull_columns(frame)
            hull = env._frames._drawer.key[3]
        finally:
            env.close()
        if vessel == "otter":
            dims = OTTER["dimensions"]
            assert hull == pytest.approx((dims["L"], dims["B"], dims["T"]), rel=1e-12)
        else:
            assert hull is None                                        # the model file's own hull
    expected = (OTTER["dimensions"]["B"] / 0.76) / (OTTER["dimensions"]["L"] / 1.98)
    print(f"\nhull width in the chase view: paper {widths['paper']} px, otter {widths['otter']} px, "
          f"ratio {widths['otter'] / widths['paper']:.3f} (expected {expected:.3f})")
    assert widths["otter"] / widths["paper"] == pytest.approx(expected, rel=0.05)


def test_gymnasium_ids_take_the_vessel():
    import gymnasium

    g = gymnasium.make("usv_mj/Track-v0", vessel="otter", duration=0.05)
    try:
        u = g.unwrapped
        assert u.dm_env.task.scenario.vessel.kind == "otter"
        assert u.physical_action(np.array([1.0, -1.0], np.float32)).tolist() == pytest.approx([2 * F, -S / 2 * (F + R)])
    finally:
        g.close()


def test_a_physics_of_no_environment_draws_its_plants_hull():
    """USVPhysics.render of a bare physics (no environment: a pose on calm water) draws the hull
    its plant simulates: the same width in the chase view as the Otter environment's frame."""
    from usv_mj.builder import make_plant
    from usv_mj.scenario.spec import load_scenario

    env = envs.load("track", seed=0, vessel="otter", duration=0.5, start_offset=(0.0, 0.0, 0.0))
    try:
        env.reset()
        in_env = _hull_columns(env.render_frame(width=320, height=240, camera="chase"))
    finally:
        env.close()
    sc = load_scenario(preset="paper", overrides={"vessel": {"kind": "otter"}, "plant": {"substeps": 10},
                                                  "control_period": DT})
    bare = envs.USVPhysics.from_plant(make_plant(sc, "mujoco"))
    try:
        assert bare.owner is None
        alone = _hull_columns(bare.render(240, 320, camera_id="chase"))
    finally:
        bare.close()
    assert alone == in_env


def test_ppc_keeps_its_lead_over_random_on_the_otter():
    """The reward stays meaningful on a hull of another size and with thrust limits: the PPC
    policy (the Otter's nominal model, its twin propellers' limits) earns several times what
    uniform actions within those limits earn over 10 s."""
    returns = {}
    for name in ("ppc", "random"):
        env = envs.load("track", seed=0, vessel="otter", duration=10.0)
        try:
            policy = envs.PPCPolicy(env) if name == "ppc" else envs.RandomPolicy(env, seed=0)
            ts, total = env.reset(), 0.0
            while not ts.last():
                ts = env.step(policy(ts))
                total += ts.reward
            returns[name] = total
        finally:
            env.close()
    print(f"\nOtter track, 10 s: ppc {returns['ppc']:.1f}, random {returns['random']:.1f} (of at most 1000)")
    assert returns["ppc"] > 3.0 * returns["random"], returns


def test_a_users_vessel_data_file_is_a_vessel_too(tmp_path):
    """vessel= takes a data file as --vessel does (usv_mj.vessels.datafile): a copy of the Otter's
    file under another name gives the Otter's bounds and mass."""
    src = Path(__file__).resolve().parents[1] / "usv_mj" / "vessels" / "data" / "otter.toml"
    boat = tmp_path / "my_boat.toml"
    boat.write_text(src.read_text())
    env = envs.load("track", seed=0, vessel=str(boat), duration=0.05)
    try:
        assert env.action_spec().maximum.tolist() == pytest.approx([2 * F, S / 2 * (F + R)], rel=1e-15)
        assert env.physics.model.body_mass[env.physics.model.body("hull").id] == OTTER["derivatives"]["m"]
    finally:
        env.close()
