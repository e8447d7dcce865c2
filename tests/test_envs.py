"""usv_mj.envs: dm_env conformance, determinism, isolation of the callback, the PPC baseline."""

from __future__ import annotations

import math
import unittest

import numpy as np
import pytest
from dm_env import test_utils

from usv_mj import envs
from usv_mj.plants.mujoco_plant import MuJoCoPlant
from usv_mj.loop.simulate import simulate

SHORT = {"duration": 0.5}  # 50 control steps of 0.01 s: conformance tests end episodes too


def _rollout(env, policy, max_steps=None):
    ts = env.reset()
    states, rewards = [env.physics.state.copy()], []
    while not ts.last() and (max_steps is None or len(rewards) < max_steps):
        ts = env.step(policy(ts))
        states.append(env.physics.state.copy())
        rewards.append(ts.reward)
    return np.array(states), np.array(rewards), ts


class TrackConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return envs.load("track", seed=1, **SHORT)


class TrackUnquantizedConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return envs.load("track", seed=2, quantize=False, **SHORT)


class HarbourConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return envs.load("harbor", seed=3, **SHORT)


class WavesConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return envs.load("track_waves", seed=4, **SHORT)


class FlatConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return envs.load("track", seed=5, environment_kwargs={"flat_observation": True}, **SHORT)


def test_all_tasks_and_bad_input():
    from usv_mj.core.registry import TASKS

    assert envs.ALL_TASKS == TASKS.kinds() and len(set(envs.ALL_TASKS)) == len(envs.ALL_TASKS)
    with pytest.raises(ValueError, match="unknown task 'nope'"):
        envs.load("nope")
    with pytest.raises(ValueError, match="unknown options"):
        envs.load("track", bogus=1)
    env = envs.load("track", seed=0, **SHORT)
    try:
        env.reset()
        with pytest.raises(ValueError, match="finite"):
            env.step(np.array([np.nan, 0.0]))
        with pytest.raises(ValueError, match="shape"):
            env.step(np.zeros(3))
        spec = env.action_spec()
        assert spec.shape == (2,) and np.all(spec.maximum > 0) and np.all(spec.minimum == -spec.maximum)
    finally:
        env.close()


@pytest.mark.parametrize("task", ["track", "harbor"])
def test_same_seed_same_episode_bit_for_bit(task):
    out = []
    for _ in range(2):
        env = envs.load(task, seed=7, duration=1.0)
        try:
            out.append(_rollout(env, envs.RandomPolicy(env, seed=11)))
        finally:
            env.close()
    (s1, r1, _), (s2, r2, _) = out
    assert s1.shape == s2.shape and np.array_equal(s1, s2) and np.array_equal(r1, r2)
    env = envs.load(task, seed=8, duration=1.0)
    try:
        s3, _, _ = _rollout(env, envs.RandomPolicy(env, seed=11))
    finally:
        env.close()
    assert not np.array_equal(s1[0], s3[0])  # another seed, another start (or layout)


def test_two_environments_do_not_disturb_each_other():
    """Interleaving the steps of an environment with a different ship (harsh disturbance) changes
    nothing in the first one's trajectory: the callback reads each mjData's own parameters."""
    def run(interleave):
        a = envs.load("track", seed=5, duration=1.0)
        b = envs.load("track", seed=6, duration=1.0, preset="harsh") if interleave else None
        try:
            pa, pb = envs.RandomPolicy(a, 1), (envs.RandomPolicy(b, 2) if b else None)
            ts = a.reset()
            tb = b.reset() if b else None
            states = []
            while not ts.last():
                ts = a.step(pa(ts))
                if b is not None:
                    tb = b.step(pb(tb)) if not tb.last() else b.reset()
                    if len(states) == 60:  # closing the other one mid-episode leaves a's callback in place
                        b.close()
                        b = None
                states.append(a.physics.state.copy())
            return np.array(states)
        finally:
            a.close()
            if b is not None:
                b.close()
    alone, together = run(False), run(True)
    assert np.array_equal(alone, together)
    # and the harsh ship really is another physics (else the test could not fail)
    a = envs.load("track", seed=5, duration=1.0, preset="harsh")
    try:
        s, _, _ = _rollout(a, envs.RandomPolicy(a, 1))
    finally:
        a.close()
    assert np.max(np.abs(s[1:] - alone)) > 1e-6


def test_close_releases_the_plant():
    from usv_mj.plants import mujoco_callback as mcb

    env = envs.load("track", seed=0, **SHORT)
    ud = env.physics.plant.data.userdata
    assert ud[mcb.U_MAGIC] == mcb.MAGIC
    env.close()
    assert ud[mcb.U_MAGIC] == 0.0
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()


def test_observations_match_their_definitions():
    """Body-frame errors and preview against the plant state and the reference, computed here."""
    env = envs.load("track", seed=3, duration=1.0)
    try:
        ts = env.reset()
        for _ in range(20):
            ts = env.step(np.array([5.0, 1.0]))
        x = env.physics.state
        t = env.physics.time()
        assert ts.observation["time"][0] == pytest.approx(0.2, abs=1e-12)
        ref = env.task.reference.sample([t, t + 0.5, t + 1.0, t + 2.0, t + 4.0])
        c, s = math.cos(x[2]), math.sin(x[2])
        rot = np.array([[c, s], [-s, c]])  # R(psi)^T
        np.testing.assert_allclose(ts.observation["position_error"], rot @ (x[:2] - ref[0, :2]), atol=1e-12)
        np.testing.assert_allclose(ts.observation["reference_preview"], (rot @ (ref[1:, :2] - x[:2]).T).T, atol=1e-12)
        np.testing.assert_allclose(ts.observation["velocity"], x[3:], atol=0)
        rho = 16.0 * math.exp(-0.05 * t) + 2.0  # paper preset: rho_xy = 16 exp(-0.05 t) + 2
        assert ts.observation["funnel"][0] == pytest.approx(rho, rel=1e-12)
        assert 0.0 <= ts.reward <= 1.0
        # quantized thrust: 5 N lies on a level of the surge ladder (|Q - tau| <= delta |tau|, Lemma 1)
        q = env.task.info["thrust"]
        assert abs(q[0] - 5.0) <= 0.3 * 5.0 and q[0] != 5.0
    finally:
        env.close()


def _by_definition(task, physics):
    """The observation dict and the reward at the physics' state from the definitions of
    usv_mj.envs.tasks, computed independently of its kernels: the reference's Python evaluate,
    ``math``, the Python angle wrap and dm_control's own ``rewards.tolerance``; the harbor's
    rangefinders through the bindings (mj_kinematics, mj_sensorPos)."""
    import mujoco
    from dm_control.utils import rewards

    def tol(v, lo, hi, margin, sigmoid, at_margin):
        return float(rewards.tolerance(v, bounds=(lo, hi), margin=margin, sigmoid=sigmoid, value_at_margin=at_margin))

    def wrap(a):
        return (a + math.pi) % (2.0 * math.pi) - math.pi

    x = np.nan_to_num(physics.state, nan=0.0, posinf=0.0, neginf=0.0)
    t = physics.time()
    ref = task.reference.evaluate(t).copy()
    c, s = math.cos(x[2]), math.sin(x[2])

    def body(px, py):
        return [c * px + s * py, -s * px + c * py]

    preview = [task.reference.evaluate(t + tau).copy() for tau in task.preview_times]
    obs = {"position_error": body(x[0] - ref[0], x[1] - ref[1]), "heading_error": [wrap(x[2] - ref[2])],
           "heading": [c, s], "velocity": [x[3], x[4], x[5]],
           "velocity_error": [c * ref[3] + s * ref[4] - x[3], -s * ref[3] + c * ref[4] - x[4], ref[5] - x[5]],
           "reference_preview": [body(r[0] - x[0], r[1] - x[1]) for r in preview],
           "funnel": [(f.rho_0 - f.rho_inf) * math.exp(-f.rate * t) + f.rho_inf
                      for f in (task.funnel_xy, task.funnel_psi)],
           "time": [t]}
    reward = (2.0 * tol(math.hypot(x[0] - ref[0], x[1] - ref[1]), 0.0, 0.25, 2.0, "gaussian", 0.1)
              + tol(abs(wrap(x[2] - ref[2])), 0.0, 0.1, 0.5, "gaussian", 0.1)) / 3.0
    if isinstance(task, envs.HarbourTask):
        g, m, d = task.layout.goal, physics.plant.model, physics.plant.data
        obs["goal"] = body(g[0] - x[0], g[1] - x[1]) + [wrap(task.layout.psi_goal - x[2])]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_sensorPos(m, d)
        adr = [m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, f"range_{i}")] for i in range(task.n_rays)]
        r = d.sensordata[adr]
        obs["rangefinder"] = np.where((r < 0) | (r > task.max_range), task.max_range, r)
        r_goal = tol(math.hypot(x[0] - g[0], x[1] - g[1]), 0.0, task.goal_radius, task._start_distance, "linear", 0.0)
        mon = task.monitor       # the least clearance on the bindings, every hull/obstacle pair
        c_min = min(mujoco.mj_geomDistance(m, d, hg, og, mon.distmax, None)
                    for og in mon.obstacle_geoms for hg in mon.hull_geoms)
        r_clear = tol(c_min, task.margin_m, math.inf, task.margin_m, "linear", 0.0)
        reward = r_clear * 0.5 * (r_goal + reward)
    return obs, reward


@pytest.mark.parametrize("task", ["track", "harbor"])
def test_observations_and_rewards_equal_their_definitions_bit_for_bit(task):
    """Every observation entry and every reward of a rollout (actions beyond the bounds clipped,
    the quantizer on) equal the definitions computed independently (``_by_definition``) to the
    last bit; the thrust is the Python quantizer's."""
    from usv_mj.builder import make_quantizers

    env = envs.load(task, seed=4, duration=1.5)
    try:
        rng = np.random.RandomState(9)
        spec = env.observation_spec()
        high = env.action_spec().maximum
        q_u, q_r = make_quantizers(env.task.scenario)
        policy = envs.PPCPolicy(env) if task == "harbor" else None
        ts = env.reset()
        n = 0
        while True:
            want, reward = _by_definition(env.task, env.physics)
            assert list(ts.observation) == list(spec) == list(want)
            for name, value in ts.observation.items():
                assert value.dtype == np.float64 and value.shape == spec[name].shape, name
                assert np.array_equal(value, np.reshape(want[name], value.shape)), (n, name, value, want[name])
            assert ts.first() or ts.reward == reward, (n, ts.reward, reward)
            if ts.last():
                break
            a = policy(ts) if policy is not None else rng.uniform(-1.5, 1.5, size=2) * high
            ts = env.step(a)
            clipped = np.clip(a, -high, high)
            assert np.array_equal(env.task.info["thrust"], [q_u.step(clipped[0]), q_r.step(clipped[1])])
            n += 1
        assert n == 150 and env.task.info["kind"] == "time_limit"
    finally:
        env.close()


def test_gaussian_tolerance_is_dm_controls_numpy_scalars_bit_for_bit():
    """tasks._tol_gaussian (Python floats, libm's pow and exp) equals the Gaussian sigmoid on
    numpy float64 scalars (what it replaced: numpy's ``** 2`` is libm's pow, its exp may be a SIMD
    routine) and dm_control's rewards.tolerance, over random, tiny, huge, overflowing and NaN inputs."""
    import warnings

    from dm_control.utils import rewards

    from usv_mj.envs import tasks

    scale = np.sqrt(-2 * np.log(0.1))

    def numpy_scalars(x, lower, upper, margin):
        if lower <= x <= upper:
            return 1.0
        d = np.float64(lower - x if x < lower else x - upper) / margin
        return float(np.exp(-0.5 * (d * scale) ** 2))

    rng = np.random.default_rng(11)
    xs = np.concatenate([rng.uniform(0.0, 6.0, 20000), np.abs(rng.standard_normal(5000)) * 1e3,
                         10.0 ** rng.uniform(-300, 300, 2000), [0.0, 0.25, 0.1, 1e154, 2e154, 1e300, np.inf, np.nan]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for x in xs.tolist():
            for lower, upper, margin in ((0.0, 0.25, 2.0), (0.0, 0.1, 0.5)):
                got = tasks._tol_gaussian(x, lower, upper, margin)
                want = numpy_scalars(x, lower, upper, margin)
                assert type(got) is float and (got == want or (math.isnan(got) and math.isnan(want))), (x, got, want)
        for x in xs.tolist():    # and dm_control's own, edge cases included
            got = tasks._tol_gaussian(x, 0.0, 0.25, 2.0)
            want = float(rewards.tolerance(x, bounds=(0.0, 0.25), margin=2.0, sigmoid="gaussian", value_at_margin=0.1))
            assert got == want or (math.isnan(got) and math.isnan(want)), (x, got, want)


@pytest.mark.parametrize("task, flat", [("track", False), ("harbor", True)])
def test_the_fused_step_is_the_step_method_by_method(task, flat):
    """USVEnvironment.step's fused path (USVEnvironment._fused_step: the action, the plant's kernel and the
    evaluation in one native call) and dm_control's sequence of before_step, physics.step,
    after_step, get_reward, get_observation give the same time steps, info and state bit for bit,
    through a plant failure (MuJoCo's reset on a huge velocity) and into the next episode."""
    runs = []
    for fused in (True, False):
        env = envs.load(task, seed=2, duration=0.6, flat_observation=flat)
        env._fusable = fused
        calls = []
        real = env._fused_step
        env._fused_step = lambda *a: calls.append(1) or real(*a)
        try:
            policy, rows = envs.PPCPolicy(env), []
            ts = env.reset()
            for i in range(100):
                if i == 20:
                    env.physics.plant.data.qvel[:] = (3e10, -3e10, 1e9)  # MuJoCo resets: the plant fails
                ts = env.step(policy(ts))
                obs = {k: np.array(v) for k, v in ts.observation.items()}
                rows.append((ts.step_type, ts.reward, ts.discount, obs, env.task.info["kind"], env.task.info["reason"],
                             env.physics.failure, env.physics.state.copy(), env.task.last_thrust.copy()))
        finally:
            env.close()
        assert bool(calls) == fused
        runs.append(rows)
    kinds = [r[4] for r in runs[0] if r[0] == 2]  # the ends: the failure, then a time limit
    assert kinds[:2] == ["diverged", "time_limit"] and runs[0][20][6], kinds
    for a, b in zip(*runs):
        assert a[0] == b[0] and a[2] == b[2] and a[4:7] == b[4:7], (a[4:7], b[4:7])
        assert a[1] == b[1] or (a[1] is None and b[1] is None) or (math.isnan(a[1]) and math.isnan(b[1]))
        assert list(a[3]) == list(b[3]) and all(np.array_equal(a[3][k], b[3][k], equal_nan=True) for k in a[3])
        assert np.array_equal(a[7], b[7], equal_nan=True) and np.array_equal(a[8], b[8])


def test_ppc_trajectory_equals_simulate_on_the_mujoco_plant():
    """PPCPolicy in the environment = simulate() with the same scenario, start and reference on a
    fresh MuJoCoPlant (quantizer on): the environment is the plant, not a copy."""
    env = envs.load("track", seed=0, duration=5.0, max_surge_force=1e6, max_yaw_moment=1e6)
    try:
        states, _, _ = _rollout(env, envs.PPCPolicy(env))
        sc = env.task.scenario.with_overrides({"initial": {"eta": [float(v) for v in states[0, :3]],
                                                            "nu": [0.0, 0.0, 0.0]}})
        record = simulate(sc, plant_kind="mujoco", duration=5.0, reference=env.task.reference)
    finally:
        env.close()
    assert record.status == "completed" and record.n_rows == len(states) == 501
    err = np.hypot(record["x"] - states[:, 0], record["y"] - states[:, 1])
    print(f"\nPPC in the environment vs simulate(): max position difference {np.max(err):.3g} m over 5 s, "
          f"distance travelled {np.hypot(*(states[-1, :2] - states[0, :2])):.2f} m")
    assert np.max(err) < 1e-6, np.max(err)
    assert np.max(np.abs(record["psi"] - states[:, 2])) < 1e-6


def test_ppc_earns_clearly_more_than_random_on_track():
    returns = {"ppc": [], "random": []}
    for seed in (0, 1, 2):
        env = envs.load("track", seed=seed, duration=10.0)
        try:
            for name, policy in (("ppc", envs.PPCPolicy(env)), ("random", envs.RandomPolicy(env, seed))):
                _, rewards, _ = _rollout(env, policy)
                returns[name].append(float(np.sum(rewards)))
        finally:
            env.close()
    ppc, rnd = np.mean(returns["ppc"]), np.mean(returns["random"])
    print(f"\ntrack, 10 s episodes (1000 steps), mean return over seeds 0-2: PPC {ppc:.1f} "
          f"{returns['ppc']}, random {rnd:.1f} {returns['random']}")
    assert ppc > 2.0 * rnd and ppc > 500.0


def test_harbour_rangefinders_see_the_piers():
    """A ray's reading equals the distance from the hull origin to the obstacle along it (mj_ray
    on the same model, and a box edge computed by hand for the bow ray)."""
    import mujoco

    env = envs.load("harbor", seed=0, duration=1.0)
    try:
        ts = env.reset()
        plant = env.physics.plant
        r = ts.observation["rangefinder"]
        assert r.shape == (16,) and np.all((r > 0) & (r <= 20.0))
        m, d = plant.model, plant.data
        geomid = np.zeros(1, dtype=np.int32)
        hull = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "hull")
        psi = plant.state[2]
        for i, a in enumerate(env.task.ray_angles):
            vec = np.array([math.cos(psi + a), math.sin(psi + a), 0.0])
            dist = mujoco.mj_ray(m, d, np.array([*plant.state[:2], 0.3]), vec, None, 1, hull, geomid)
            expected = 20.0 if (dist < 0 or dist > 20.0) else dist
            assert r[i] == pytest.approx(expected, abs=1e-9)
        assert np.any(r < 20.0)
    finally:
        env.close()


@pytest.mark.slow
def test_harbour_ppc_with_guidance_reaches_the_goal():
    n, reached, contacts = 10, 0, 0  # 10 layouts of 90 s (~1 min); 20 of 20 when last measured
    env = envs.load("harbor", seed=0)
    try:
        policy = envs.PPCPolicy(env)
        for _ in range(n):
            _rollout(env, policy)
            kind = env.task.info["kind"]
            reached += kind == "goal"
            contacts += kind == "contact"
    finally:
        env.close()
    print(f"\nharbor: PPC + guidance reached the goal without contact in {reached}/{n} layouts "
          f"({contacts} contacts)")
    assert reached >= 0.8 * n


def test_harbour_contact_ends_the_episode_with_its_reason():
    """Full surge thrust at a pier from 2.5 m in front of it: the episode ends on contact (discount
    0, reward 0 since the clearance factor is 0), the reason names the pier."""
    env = envs.load("harbor", seed=0, duration=10.0)
    try:
        env.reset()
        pier = next(o for o in env.task.layout.obstacles if o.name == "pier_south")
        x0 = pier.center[0] - 0.5 * pier.size[0] - 2.5
        env.physics.set_initial_state((x0, pier.center[1], 0.0), (0.0, 0.0, 0.0))
        ts, n = None, 0
        while ts is None or not ts.last():
            ts = env.step(np.array([1000.0, 0.0]))
            n += 1
        info = env.task.info
        assert info["kind"] == "contact" and "pier_south" in info["reason"], info
        assert ts.discount == 0.0 and ts.reward == 0.0
        assert n < 500  # well before the time limit
        assert env.physics.state[0] + 1.0 > pier.center[0] - 0.5 * pier.size[0] - 0.1  # bow at the pier face
    finally:
        env.close()


# --- through the one build, the sea, flat observations -------------------------------------------


def test_plants_come_from_the_build(monkeypatch):
    """Every task's plant is made by usv_mj.build.make_plant (the harbour's with its rangefinders)."""
    import usv_mj.envs.suite as environment   # the built-in tasks' factories

    calls = []
    real = environment.make_plant

    def spy(scenario, kind=None, *args, **kwargs):
        calls.append((kind, len(scenario.obstacles), len(kwargs.get("rangefinders", ()))))
        return real(scenario, kind, *args, **kwargs)

    monkeypatch.setattr(environment, "make_plant", spy)
    for task in ("track", "harbor"):
        envs.load(task, seed=0, **SHORT).close()
    assert calls[0] == ("mujoco", 0, 0)
    assert calls[1][0] == "mujoco" and calls[1][1] >= 5 and calls[1][2] == 16


def test_harbour_in_waves_differs_from_calm_water():
    """harbor_waves: the same layout and start as harbor with the same seed, but the sea moves the hull."""
    out = {}
    for task in ("harbor", "harbor_waves"):
        env = envs.load(task, seed=3, duration=2.0)
        try:
            states, _, _ = _rollout(env, lambda ts: np.array([50.0, 0.0]))
            out[task] = (states, [o.center for o in env.task.layout.obstacles])
        finally:
            env.close()
    (calm, lay_calm), (waves, lay_waves) = out["harbor"], out["harbor_waves"]
    assert lay_calm == lay_waves and np.array_equal(calm[0], waves[0])
    diff = float(np.max(np.abs(calm[-1] - waves[-1])))
    assert diff > 1e-3, diff


def test_flat_observation_is_the_dict_concatenated():
    a = envs.load("harbor", seed=2, **SHORT)
    b = envs.load("harbor", seed=2, flat_observation=True, **SHORT)
    try:
        ta, tb = a.reset(), b.reset()
        for _ in range(5):
            ta, tb = a.step(np.array([100.0, 10.0])), b.step(np.array([100.0, 10.0]))
        flat = tb.observation["observations"]
        assert set(tb.observation) == {"observations"} and flat.shape == b.observation_spec()["observations"].shape
        np.testing.assert_array_equal(flat, np.concatenate([v.ravel() for v in ta.observation.values()]))
        back = b.unflatten(tb.observation)
        for k, v in ta.observation.items():
            np.testing.assert_array_equal(back[k], v)
        with pytest.raises(ValueError, match="environment_kwargs"):
            envs.load("track", environment_kwargs={"n_sub_steps": 3})
    finally:
        a.close()
        b.close()


def test_no_constant_observation_on_track():
    """r_d is constant on the paper's reference for 30 s: it is observed against r (velocity_error)."""
    env = envs.load("track", seed=0, duration=3.0)
    try:
        ts = env.reset()
        obs = [np.concatenate([v.ravel() for v in ts.observation.values()])]
        policy = envs.PPCPolicy(env)
        while not ts.last():
            ts = env.step(policy(ts))
            obs.append(np.concatenate([v.ravel() for v in ts.observation.values()]))
        assert np.all(np.ptp(np.array(obs), axis=0) > 0), np.ptp(np.array(obs), axis=0)
    finally:
        env.close()


def test_action_bounds_follow_the_actuator_limits():
    over = {"actuators": {"kind": "box", "max_surge_n": 200.0, "max_reverse_n": 100.0, "max_yaw_nm": 50.0}}
    env = envs.load("track", seed=0, overrides=over, **SHORT)
    try:
        spec = env.action_spec()
        np.testing.assert_array_equal(spec.minimum, [-100.0, -50.0])
        np.testing.assert_array_equal(spec.maximum, [200.0, 50.0])
        env.reset()
        env.step(np.array([1e4, -1e4]))
        np.testing.assert_array_equal(env.task.info["action"], [200.0, -50.0])
    finally:
        env.close()
    env = envs.load("track", seed=0, **SHORT)  # the paper's ship: unlimited actuators, the 1000 N defaults
    try:
        assert env.action_spec().maximum.tolist() == [1000.0, 1000.0]
    finally:
        env.close()


# --- the Gymnasium view --------------------------------------------------------------------------

@pytest.mark.parametrize("env_id", list(envs.GYM_IDS))
def test_gymnasium_make_and_check_env_without_warnings(env_id):
    gym = pytest.importorskip("gymnasium")
    import warnings

    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, duration=0.5)
    try:
        assert env.action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        space = env.observation_space
        assert isinstance(space, gym.spaces.Box) and len(space.shape) == 1
        assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped, skip_render_check=True)
            obs, info = env.reset(seed=0)   # and through make's wrappers (the passive checker)
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert not caught, [str(w.message) for w in caught]
        assert space.contains(obs) and 0.0 <= reward <= 1.0
    finally:
        env.close()


def test_gymnasium_first_reset_takes_the_seed():
    """harbor: the first reset(seed=s) gives seed s's layout (the one load(seed=s) gives), whatever
    seed the environment was made with."""
    pytest.importorskip("gymnasium")
    g = envs.gym_env("harbor", seed=0, duration=0.5)
    ref = envs.load("harbor", seed=5, duration=0.5)
    try:
        o_ref = g._observe(ref.reset().observation)
        obs, _ = g.reset(seed=5)
        np.testing.assert_array_equal(obs, o_ref)
        assert [o.center for o in g.dm_env.task.layout.obstacles] == [o.center for o in ref.task.layout.obstacles]
        obs6, _ = g.reset(seed=6)
        assert not np.array_equal(obs6, obs)
        again, _ = g.reset(seed=5)
        np.testing.assert_array_equal(again, obs)
    finally:
        g.close()
        ref.close()


def test_gymnasium_info_says_why_the_episode_ended():
    pytest.importorskip("gymnasium")
    g = envs.gym_env("track", seed=0, duration=0.2)
    try:
        _, info = g.reset(seed=1)
        assert info["kind"] is None and info["reason"] is None and info["time"] == 0.0
        terminated = truncated = False
        n = 0
        while not (terminated or truncated):
            _, _, terminated, truncated, info = g.step(np.zeros(2, np.float32))
            n += 1
        assert truncated and not terminated and n == 20
        assert info["kind"] == "time_limit" and "time limit" in info["reason"]
        # a step after the last one: gymnasium's ResetNeeded, not TypeError: float() ... NoneType (issue 27)
        from gymnasium.error import ResetNeeded

        with pytest.raises(ResetNeeded, match="call reset"):
            g.step(np.zeros(2, np.float32))
        g.reset(seed=1)
        assert g.step(np.zeros(2, np.float32))[1] is not None     # a new episode steps again
    finally:
        g.close()
    # a lost hull: terminated, with the distance in the reason
    g = envs.gym_env("track", seed=0, duration=30.0, max_distance=1.0, start_offset=(0.0, 0.0, 0.0))
    try:
        g.reset(seed=0)
        terminated = truncated = False
        while not (terminated or truncated):
            _, _, terminated, truncated, info = g.step(np.array([-1.0, 1.0], np.float32))
        assert terminated and info["kind"] == "lost" and "max_distance" in info["reason"], info
    finally:
        g.close()


def test_ppc_policy_on_the_gymnasium_view_matches_the_dm_env():
    """PPCPolicy(gym env) reads the flat scaled float32 observation and returns normalized actions:
    the episode is the dm_env one within float32 rounding, and earns the same return."""
    gym = pytest.importorskip("gymnasium")
    g = gym.make("usv_mj/Track-v0", duration=3.0)
    d = envs.load("track", seed=4, duration=3.0)
    try:
        policy = envs.PPCPolicy(g)
        obs, _ = g.reset(seed=4)
        ret_g, done, states = 0.0, False, []
        while not done:
            obs, r, te, tr, _ = g.step(policy(obs))
            ret_g += r
            done = te or tr
            states.append(g.unwrapped.dm_env.physics.state.copy())
        ds, rewards, _ = _rollout(d, envs.PPCPolicy(d))
    finally:
        g.close()
        d.close()
    err = float(np.max(np.abs(np.array(states)[:, :2] - ds[1:, :2])))
    assert err < 1e-3, err
    assert ret_g == pytest.approx(float(np.sum(rewards)), rel=1e-3)


def test_gymnasium_render_shows_the_water():
    """render() with the project's renderer and GL choice: an RGB frame of the sea (blue), not black."""
    pytest.importorskip("gymnasium")
    from usv_mj.outputs.render.gl_backend import GLUnavailableError, select_backend

    try:
        select_backend()
    except GLUnavailableError as exc:
        pytest.skip(str(exc).splitlines()[0])
    g = envs.gym_env("track_waves", seed=0, duration=0.5, render_mode="rgb_array", render_size=(160, 120))
    try:
        g.reset(seed=0)
        g.step(np.array([0.5, 0.0], np.float32))
        frame = g.render()
        assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
        r, gr, b = frame[60:, 80:].reshape(-1, 3).mean(axis=0)  # the lower right: water, away from the HUD
        assert b > 60 and b > r + 20, (r, gr, b)
    finally:
        g.close()


_PHYSICS_RENDER = r"""
import sys
import numpy as np
from usv_mj import envs
out = sys.argv[1]
env = envs.load("track_waves", seed=0, duration=0.5)
env.reset()
env.step(np.zeros(2))
np.save(out + "/physics.npy", env.physics.render())          # dm_control's defaults: 240 x 320, camera -1
np.save(out + "/chase.npy", env.physics.render(90, 160, camera_id=0))
try:
    env.physics.render(depth=True)
except ValueError as exc:
    open(out + "/depth.txt", "w").write(str(exc))
env.close()
from shimmy.dm_control_compatibility import DmControlCompatibilityV0
g = DmControlCompatibilityV0(envs.load("track", seed=0, duration=0.5), render_mode="rgb_array")
g.reset(seed=0)
np.save(out + "/shimmy.npy", g.render())
g.close()
"""


def _share_of_colour(frame, rgb, max_deg=10.0, min_brightness=0.6):
    """The share of pixels within max_deg of the colour rgb (0..1) in direction and at least
    min_brightness times as bright: the sea as the renderer lights it."""
    px = frame.reshape(-1, 3).astype(float)
    ref = np.asarray(rgb[:3], float) * 255.0
    norm = np.linalg.norm(px, axis=1)
    cos = px @ ref / np.maximum(norm, 1e-9) / np.linalg.norm(ref)
    return float(np.mean((cos > math.cos(math.radians(max_deg))) & (norm > min_brightness * np.linalg.norm(ref))))


def test_physics_render_shows_the_water_headless_without_mujoco_gl(tmp_path):
    """dm_control's physics.render() (what shimmy and dm_control's tools call) draws through the
    project's renderer with the GL choice of usv-mj run, in a process that has no MUJOCO_GL (as a
    user's would): the sea of track_waves (the renderer's wave-surface colour) and, through shimmy's
    DmControlCompatibilityV0, the calm water of track (the water texture of models/scene.xml)."""
    import os
    import subprocess
    import sys
    import xml.etree.ElementTree as ET
    from pathlib import Path

    pytest.importorskip("shimmy")
    from usv_mj.outputs.render.gl_backend import GLUnavailableError, select_backend

    try:
        select_backend()
    except GLUnavailableError as exc:
        pytest.skip(str(exc).splitlines()[0])
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    proc = subprocess.run([sys.executable, "-c", _PHYSICS_RENDER, str(tmp_path)], env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    from usv_mj.outputs.render.replay import SEA_RGBA

    frame = np.load(tmp_path / "physics.npy")
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert _share_of_colour(frame, SEA_RGBA) > 0.5
    assert np.load(tmp_path / "chase.npy").shape == (90, 160, 3)
    assert "depth=True is not supported" in (tmp_path / "depth.txt").read_text()
    scene = ET.parse(Path(__file__).resolve().parents[1] / "models" / "scene.xml")
    water = next(t for t in scene.iter("texture") if t.get("name") == "water")
    calm = np.load(tmp_path / "shimmy.npy")
    assert calm.shape == (240, 320, 3) and calm.dtype == np.uint8
    rgb1 = [float(v) for v in water.get("rgb1").split()]
    # the overlays (the HUD panel, the legend, the scale bar, the translucent funnel box) cover about
    # half the frame: the water fills the strip above the funnel box right of the HUD, and shows
    # through everywhere else (a frame without it, black or sky, scores about 0 on both)
    assert _share_of_colour(calm[:40, 170:], rgb1) > 0.95
    assert _share_of_colour(calm, rgb1) > 0.35


def test_stable_baselines3_ppo_takes_the_gymnasium_view_as_is():
    """No wrapper: PPO("MlpPolicy", gymnasium.make(id)) builds and runs (stable-baselines3 optional)."""
    gym = pytest.importorskip("gymnasium")
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make("usv_mj/Track-v0", duration=0.5)
    try:
        model = sb3.PPO("MlpPolicy", env, n_steps=64, batch_size=32, n_epochs=1, device="cpu", verbose=0, seed=0)
        model.learn(64)
        action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
        assert env.action_space.contains(action)
    finally:
        env.close()


_CLOSE_SEQUENCE = r"""
import numpy as np
import gymnasium
from usv_mj import envs
for task in ("usv_mj/Track-v0", "usv_mj/TrackWaves-v0", "usv_mj/Harbor-v0"):
    g = gymnasium.make(task, render_mode="rgb_array", render_size=(64, 48))
    g.reset(seed=0)
    assert g.render().shape == (48, 64, 3)
    g.close()
e = envs.load("track", seed=0, duration=0.5)
e.reset()
e.physics.render(48, 64)
e.close()
left_open = envs.load("track", seed=1, duration=0.5)   # closed by the interpreter's exit
left_open.reset()
left_open.physics.render(48, 64)
print("rendered")
"""


def test_closing_rendering_environments_in_sequence_prints_nothing_at_exit():
    """Issue 28: with MUJOCO_GL unset, closing environments one after another (and one left open
    at exit) never prints 'Exception ignored in atexit callback' (_close_open_renderers)."""
    import os
    import subprocess
    import sys

    pytest.importorskip("gymnasium")
    from usv_mj.outputs.render.gl_backend import GLUnavailableError, select_backend

    try:
        select_backend()
    except GLUnavailableError as exc:
        pytest.skip(str(exc).splitlines()[0])
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    for _ in range(2):
        proc = subprocess.run([sys.executable, "-c", _CLOSE_SEQUENCE], env=env, capture_output=True, text=True,
                              timeout=600)
        assert proc.returncode == 0 and "rendered" in proc.stdout, proc.stderr[-3000:]
        assert "Exception ignored" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr[-3000:]


def test_the_exit_hook_frees_every_renderer_even_when_one_fails():
    """The at-exit hook goes on past a renderer whose close fails (a GL context already gone)."""
    from usv_mj.outputs.render import replay

    closed = []

    class Broken:
        def close(self):
            raise RuntimeError("EGL_BAD_DISPLAY")

    class Fine:
        def close(self):
            closed.append(self)

    objs = [Broken(), Fine(), Broken(), Fine()]
    for o in objs:
        replay._OPEN.add(o)
    try:
        replay._close_open_renderers()           # raises nothing
    finally:
        for o in objs:
            replay._OPEN.discard(o)
    assert len(closed) == 2


def test_env_command_skips_the_video_with_none(tmp_path, capsys, monkeypatch):
    """`usv-mj env ... --video none` (the skip value its --help names) runs the episode and writes nothing."""
    from usv_mj.cli.main import main

    monkeypatch.chdir(tmp_path)
    assert main(["env", "track", "--policy", "ppc", "--duration", "0.5", "--video", "none"]) == 0
    out = capsys.readouterr().out
    assert "episode 1: return" in out and "video:" not in out
    assert list(tmp_path.iterdir()) == []


def test_a_missing_gymnasium_is_named_with_its_pip_command(monkeypatch):
    """Without the [gym] extra the Gymnasium view says so in one line, with the pip command."""
    import importlib
    import sys

    from usv_mj.core.errors import MissingExtra

    monkeypatch.setitem(sys.modules, "gymnasium", None)          # as if not installed
    monkeypatch.delitem(sys.modules, "usv_mj.envs.gymnasium_env", raising=False)
    with pytest.raises(MissingExtra) as info:
        importlib.import_module("usv_mj.envs.gymnasium_env")
    text = str(info.value)
    assert "\n" not in text and 'pip install "usv_mj[gym]"' in text and "gymnasium" in text
    assert isinstance(info.value, ImportError)
