"""The vector environments (issue 36 item 2): gymnasium.make_vec steps N episodes in one native call, each
equal to a single environment given the same seed and actions; Gymnasium's autoreset conventions;
the dm_env batch and the stable-baselines3 view; the native reward against the Python one."""

from __future__ import annotations

import math
import random
from types import SimpleNamespace

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import usv_mj.envs  # noqa: E402,F401 (registers the ids)
from gymnasium.vector import AutoresetMode  # noqa: E402
from usv_mj.envs import native  # noqa: E402
from usv_mj.envs.tasks import (_GAUSS_SCALE, TRACK_REWARD_HEADING_RAD, TRACK_REWARD_POSITION_M,  # noqa: E402
                               TrackTask, _numpy_exp_is_libm)

SHORT = {"duration": 0.25, "max_distance": 3.2}   # 25 steps; a start 3 m off the reference is lost early


def test_the_native_reward_is_the_python_reward_bit_for_bit():
    """CPython's hypot (not libm's), pow and exp, compiled: the same doubles on 200 000 draws over
    12 decades (and the overflow of the Gaussian's square to 0)."""
    if not _numpy_exp_is_libm():
        pytest.skip("numpy's exp is not libm's on this CPU (the single environment's reward uses numpy's)")
    rp = np.zeros(native.N_REWARD)
    rp[native.R_TWO], rp[native.R_GAUSS_SCALE] = 2.0, _GAUSS_SCALE
    rp[native.R_POSITION], rp[native.R_HEADING] = TRACK_REWARD_POSITION_M, TRACK_REWARD_HEADING_RAD
    r = random.Random(3)
    for _ in range(200_000):
        ex = r.uniform(-1, 1) * 10 ** r.uniform(-9, 3)
        ey = r.choice((0.0, r.uniform(-1, 1) * 10 ** r.uniform(-9, 3)))
        e_psi = r.uniform(-3.5, 3.5)
        assert native.hypot_py(ex, ey) == math.hypot(ex, ey), (ex, ey)
        assert native.track_reward(ex, ey, e_psi, rp) == TrackTask._tracking_reward(
            SimpleNamespace(ex=ex, ey=ey, e_psi=e_psi)), (ex, ey, e_psi)
    assert native.track_reward(1e300, 1e300, 0.0, rp) == TrackTask._tracking_reward(
        SimpleNamespace(ex=1e300, ey=1e300, e_psi=0.0)) == 1.0 / 3.0
    assert native.hypot_py(5e-324, 1e-320) == math.hypot(5e-324, 1e-320)   # subnormal maximum


def _step_singles(singles, over, a):
    """One SyncVectorEnv-style (NEXT_STEP) step of the single environments."""
    out = []
    for i, e in enumerate(singles):
        if over[i]:
            o, _ = e.reset()
            out.append((o, 0.0, False, False, None))
            over[i] = False
        else:
            o, r, te, tr, info = e.step(a[i])
            over[i] = te or tr
            out.append((o, r, te, tr, info["kind"] if (te or tr) else None))
    return out


def test_make_vec_gives_the_native_vector_env_with_its_autoreset_mode():
    env = gymnasium.make_vec("usv_mj/Track-v0", num_envs=2, **SHORT)
    try:
        assert type(env.unwrapped).__name__ == "USVVectorEnv"
        assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        assert env.single_observation_space == gymnasium.make("usv_mj/Track-v0", **SHORT).observation_space
        assert env.observation_space.shape == (2,) + env.single_observation_space.shape
        assert env.action_space.shape == (2, 2)
    finally:
        env.close()


def test_the_vector_env_equals_n_single_envs_step_for_step():
    """MuJoCo plant, 3 episodes seeded 5, 6, 7 against 3 gymnasium.make envs reset with those seeds
    and stepped as SyncVectorEnv steps them (NEXT_STEP): the observations, rewards, terminations and
    truncations are the same bit for bit over 60 steps, through a 'lost' end, two time limits
    and the resets after them."""
    n = 3
    venv = gymnasium.make_vec("usv_mj/Track-v0", num_envs=n, **SHORT)
    singles = [gymnasium.make("usv_mj/Track-v0", **SHORT) for _ in range(n)]
    try:
        obs, _ = venv.reset(seed=5)
        for i, e in enumerate(singles):
            o, _ = e.reset(seed=5 + i)
            assert np.array_equal(obs[i], o)
        rng = np.random.default_rng(0)
        over = [False] * n
        kinds = set()
        for step in range(60):
            a = rng.uniform(-1, 1, size=(n, 2)).astype(np.float32)
            o, r, te, tr, info = venv.step(a)
            for i, (so, sr, ste, stru, kind) in enumerate(_step_singles(singles, over, a)):
                assert np.array_equal(o[i], so) and r[i] == sr and te[i] == ste and tr[i] == stru, (step, i)
                if kind is not None:
                    kinds.add(kind)
                    assert info["_kind"][i] and info["kind"][i] == kind
                    assert info["reason"][i] == singles[i].unwrapped.dm_env.task.info["reason"]
        assert {"lost", "time_limit"} <= kinds
    finally:
        venv.close()
        for e in singles:
            e.close()


def test_same_step_autoreset_returns_the_next_episode_and_the_final_observation():
    """SAME_STEP against NEXT_STEP on the same seeds and actions: the step that ends an episode
    returns its final observation in info['final_obs'] and the new episode's first one, which
    NEXT_STEP returns one step later (Gymnasium's conventions for the two modes)."""
    kw = dict(num_envs=2, plant="analytic", duration=0.05)
    nxt = gymnasium.make_vec("usv_mj/Track-v0", autoreset_mode=AutoresetMode.NEXT_STEP, **kw)
    same = gymnasium.make_vec("usv_mj/Track-v0", autoreset_mode="SameStep", **kw)
    try:
        assert same.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
        nxt.reset(seed=1)
        same.reset(seed=1)
        a = np.full((2, 2), 0.3, np.float32)
        for _ in range(4):
            on, rn, ten, trn, _ = nxt.step(a)
            os_, rs, tes, trs, info = same.step(a)
            assert np.array_equal(on, os_) and np.array_equal(rn, rs) and not (trn | trs | ten | tes).any()
            assert "final_obs" not in info
        on, rn, ten, trn, _ = nxt.step(a)     # the 5th step of 0.01 s: the time limit
        os_, rs, tes, trs, info = same.step(a)
        assert trn.all() and trs.all() and info["_final_obs"].all() and np.array_equal(rn, rs)
        assert np.array_equal(np.stack(info["final_obs"]), on)
        assert info["kind"].tolist() == ["time_limit", "time_limit"]
        reset_obs, rn, ten, trn, _ = nxt.step(a)   # NEXT_STEP: the reset, one step later
        assert np.array_equal(reset_obs, os_) and not rn.any() and not (ten | trn).any()
    finally:
        nxt.close()
        same.close()


def test_disabled_autoreset_resets_only_the_masked_envs():
    env = gymnasium.make_vec("usv_mj/Track-v0", num_envs=3, plant="analytic", autoreset_mode=AutoresetMode.DISABLED,
                             duration=0.02)
    try:
        first, _ = env.reset(seed=0)
        a = np.zeros((3, 2), np.float32)
        env.step(a)
        _, _, te, tr, _ = env.step(a)
        assert tr.all()
        with pytest.raises(RuntimeError, match="reset them first"):
            env.step(a)
        obs, _ = env.reset(options={"reset_mask": np.array([True, False, True])})
        env.reset(options={"reset_mask": np.array([False, True, False])})
        env.step(a)   # every episode running again
    finally:
        env.close()


def _replay_analytic(task_env, eta_nu, actions):
    """An analytic episode made of the parts by hand: the control step (ControlStep), the plant's step
    (AnalyticPlant.step), the task's evaluation and reward (StepEvaluator, TrackTask._tracking_reward)."""
    from usv_mj.builder import make_actuators, make_plant, make_quantizers
    from usv_mj.loop.step import ControlStep
    from usv_mj.record.run_record import N_CORE

    t = task_env.dm_env.task
    sc = t.scenario
    plant = make_plant(sc, "analytic")
    plant.reset(*eta_nu, 0.0)
    cs = ControlStep(make_quantizers(sc), make_actuators(sc), t._bounds_t)
    cs.quantize = t.quantize
    ev = native.StepEvaluator(t.reference, t.preview_times)
    row = np.zeros(N_CORE)
    out = []
    for a in actions:
        f_u, f_r = cs(*task_env.physical_action(a), plant.state, row)
        plant.step(f_u, f_r)
        refs, obs, ex, ey, e_psi, div, _, _ = ev.track(plant.state, plant.time, t._params, t._n_obs, False)
        out.append((task_env._observe(t.observation_dict(obs)), TrackTask._tracking_reward(
            SimpleNamespace(ex=ex, ey=ey, e_psi=e_psi))))
    return out


def test_the_analytic_vector_env_is_the_parts_stepped_by_hand():
    venv = gymnasium.make_vec("usv_mj/Track-v0", num_envs=4, plant="analytic", duration=1.0)
    try:
        venv.reset(seed=11)
        x0 = venv.unwrapped.batch.X.copy()
        rng = np.random.default_rng(2)
        actions = rng.uniform(-1, 1, size=(20, 4, 2)).astype(np.float32)
        got = [venv.step(a)[:2] for a in actions]
        single = venv.unwrapped.single
        for i in range(4):
            want = _replay_analytic(single, (x0[i, :3], x0[i, 3:]), actions[:, i])
            for k, (o, r) in enumerate(want):
                assert np.array_equal(got[k][0][i], o) and got[k][1][i] == r, (i, k)
    finally:
        venv.close()


def test_the_single_view_still_passes_gymnasium_check_env():
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make("usv_mj/Track-v0", duration=0.5)
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


def test_the_dm_env_batch_follows_dm_env_steps():
    """load_batch: FIRST, MID ..., LAST (discount 1 at the time limit), then FIRST again with the
    action unused, as a dm_env environment restarts after a LAST step."""
    from usv_mj.envs import load_batch

    b = load_batch("track", num_envs=2, seed=0, plant="analytic", duration=0.03)
    try:
        ts = b.reset()
        assert ts.step_type.tolist() == [0, 0] and np.isnan(ts.reward).all()
        assert ts.observation["position_error"].shape == (2, 2)
        thrust = np.full((2, 2), 50.0)
        kinds = [b.step(thrust).step_type.tolist() for _ in range(4)]
        assert kinds == [[1, 1], [1, 1], [2, 2], [0, 0]]
        ts = b.step(thrust)
        assert ts.step_type.tolist() == [1, 1] and np.isfinite(ts.reward).all()
    finally:
        b.close()


def test_the_stable_baselines3_view_resets_in_the_same_step():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_checker import check_env  # noqa: F401 (the package is there)

    from usv_mj.envs.sb3_vec import USVSB3VecEnv

    venv = USVSB3VecEnv("track", num_envs=2, plant="analytic", duration=0.03)
    try:
        venv.seed(3)
        obs = venv.reset()
        assert obs.shape == (2,) + venv.observation_space.shape and obs.dtype == np.float32
        for _ in range(2):
            venv.step_async(np.zeros((2, 2), np.float32))
            obs, rew, dones, infos = venv.step_wait()
            assert not dones.any()
        venv.step_async(np.zeros((2, 2), np.float32))
        obs, rew, dones, infos = venv.step_wait()
        assert dones.all() and rew.dtype == np.float32
        assert all(info["TimeLimit.truncated"] and info["terminal_observation"].shape == obs.shape[1:] for info in infos)
        assert not np.array_equal(obs, np.stack([info["terminal_observation"] for info in infos]))
    finally:
        venv.close()


def test_the_harbour_tasks_are_a_sync_vector_env_of_single_views():
    """Not batched natively (a model per layout, obstacles moved in Python): make_vec gives
    Gymnasium's SyncVectorEnv of USVGymEnv, env i seeded seed + i, with its autoreset mode."""
    env = gymnasium.make_vec("usv_mj/Harbor-v0", num_envs=2, seed=4, duration=0.05)
    try:
        assert type(env.unwrapped).__name__ == "SyncVectorEnv"
        assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        obs, _ = env.reset()
        single = gymnasium.make("usv_mj/Harbor-v0", seed=5, duration=0.05)
        try:
            assert np.array_equal(obs[1], single.reset()[0])
        finally:
            single.close()
        env.step(np.zeros((2, 2), np.float32))
    finally:
        env.close()


def test_the_training_script_lets_the_batch_threads_sleep_between_steps():
    """examples/rl/train_ppo.py sets OMP_WAIT_POLICY=passive before numba loads OpenMP (its idle threads
    spun through PPO's update: 65 against 494 steps/s on the shared machine), and keeps a user's own."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "rl" / "train_ppo.py"
    probe = ("import os, runpy, sys; runpy.run_path(sys.argv[1], run_name='probe'); "
             "print(os.environ.get('OMP_WAIT_POLICY'), 'numba' in sys.modules, 'torch' in sys.modules)")
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    for given, expected in ((None, "passive"), ("active", "active")):
        run_env = env if given is None else {**env, "OMP_WAIT_POLICY": given}
        out = subprocess.run([sys.executable, "-c", probe, str(script)], env=run_env, capture_output=True,
                             text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        assert out.stdout.split() == [expected, "False", "False"]   # set before numba or torch is loaded
