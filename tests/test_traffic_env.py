"""Learning in traffic (issue 35 item 6): usv_mj/Encounter-v0 (the own ship among other vessels, a
gymnasium.Env) and the PettingZoo ParallelEnv in which every vessel is an agent (usv_mj.envs.traffic)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
pettingzoo_test = pytest.importorskip("pettingzoo.test")

import usv_mj.envs  # noqa: E402,F401  (registers the ids)
from usv_mj import load_scenario, simulate  # noqa: E402
from usv_mj.envs.encounter_env import EncounterEnv  # noqa: E402
from usv_mj.envs.traffic import N_OWN, N_TARGET, TARGET_FIELDS  # noqa: E402
from usv_mj.envs.traffic_parallel import traffic_parallel_env  # noqa: E402

NORTH, SOUTH, WEST = math.pi / 2, -math.pi / 2, math.pi
OTTER_L = 2.0


def two_vessels(plant: str, own: dict, other: dict, duration: float = 20.0, third: dict | None = None):
    """A scenario of Otters: the own ship and ``other`` (named "ship"), optionally a third ("far")."""
    vessels = [{"name": "own", "steer": "keep", "speed": 1.0, **own}, {"name": "ship", "steer": "keep", **other}]
    if third is not None:
        vessels.append({"name": "far", "steer": "keep", **third})
    return load_scenario(preset="paper", overrides={
        "duration": duration, "control_period": 0.01, "vessel": {"kind": "otter"},
        "plant": {"kind": plant, "substeps": 10}, "vessels": vessels})


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_encounter_passes_gymnasiums_check_env(plant):
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make("usv_mj/Encounter-v0", situation=5, plant=plant)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped)
        assert [str(w.message) for w in caught] == []
        assert env.observation_space.shape == (N_OWN + 3 * N_TARGET,)
        assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
    finally:
        env.close()


@pytest.mark.parametrize("plant,duration", [("analytic", 3.0), ("mujoco", 1.0)])
def test_parallel_env_passes_pettingzoos_api_and_seed_tests(plant, duration):
    def make():
        return traffic_parallel_env(situation=5, plant=plant, duration=duration, action_repeat=1)

    env = make()
    try:
        assert env.possible_agents == ["own", "ts1", "ts2"]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pettingzoo_test.parallel_api_test(env, num_cycles=1000)
        assert [str(w.message) for w in caught] == []
    finally:
        env.close()
    pettingzoo_test.parallel_seed_test(make)
    # parallel_seed_test stops after its first step (any() of a non-empty dict): compare 40 steps here
    a, b = make(), make()
    try:
        for env in (a, b):
            env.reset(seed=3)
            for agent in env.possible_agents:
                env.action_space(agent).seed(7)
        for _ in range(40):
            acts = [{g: e.action_space(g).sample() for g in e.agents} for e in (a, b)]
            out_a, out_b = a.step(acts[0]), b.step(acts[1])
            for da, db in zip(out_a, out_b):
                assert da.keys() == db.keys()
                for g in da:
                    if isinstance(da[g], dict):
                        assert {k: np.asarray(v).tolist() for k, v in da[g].items()} == \
                               {k: np.asarray(v).tolist() for k, v in db[g].items()}
                    else:
                        assert np.array_equal(da[g], db[g])
    finally:
        a.close()
        b.close()


def test_observation_is_the_hand_computed_relative_geometry():
    """Own ship at the origin heading north at 1 m/s; the other at (30, 40) m heading west at 0.5 m/s.
    In the own body frame (x forward = north, y to port = west): position (40, -30) m, relative
    velocity R^T((-0.5, 0) - (0, 1)) = (-1, 0.5) m/s; range 50 m; relative bearing atan2(30, 40) =
    36.87 deg to starboard (sin 0.6, cos 0.8); TCPA = -(d.w)/|w|^2 = -(30 (-0.5) + 40 (-1)) / 1.25
    = 44 s, DCPA = |(30, 40) + 44 (-0.5, -1)| = |(8, -4)| = sqrt(80) m. The goal (0, 100) is 100 m
    ahead. The second and third slots are empty (mask 0, all zeros)."""
    sc = two_vessels("analytic", {"initial": {"eta": [0.0, 0.0, NORTH], "nu": [1.0, 0.0, 0.0]}},
                     {"initial": {"eta": [30.0, 40.0, WEST], "nu": [0.5, 0.0, 0.0]}})
    env = EncounterEnv(sc, goals={"own": (0.0, 100.0)}, k_R=50.0)
    try:
        obs, info = env.reset(seed=0)
        expected_slot = [1.0, 40.0, -30.0, -1.0, 0.5, 50.0, 0.6, 0.8, math.sqrt(80.0), 44.0]
        physical, names = env.traffic.observe(0)
        assert names == ("ship",) and info["targets"] == ("ship",)
        assert physical[:N_OWN] == pytest.approx([1.0, 0.0, 0.0, 100.0, 0.0], abs=1e-12)
        assert physical[N_OWN:N_OWN + N_TARGET] == pytest.approx(expected_slot, abs=1e-12)
        assert not physical[N_OWN + N_TARGET:].any()
        # the scaled float32 observation: lengths / R (R = 50 L = 100 m), speeds / U (1 m/s), times / T (100 s)
        R, T = 100.0, 100.0
        slot = obs[N_OWN:N_OWN + N_TARGET]
        assert slot == pytest.approx([1.0, 0.4, -0.3, -1.0, 0.5, 0.5, 0.6, 0.8, math.sqrt(80.0) / R, 44.0 / T],
                                     rel=1e-6)
        decoded = env.unwrapped.decode(obs)
        assert decoded["own"]["goal_x"] == pytest.approx(100.0, rel=1e-6)
        assert dict(zip(TARGET_FIELDS, decoded["targets"][0])) == pytest.approx(dict(zip(TARGET_FIELDS, expected_slot)),
                                                                                rel=1e-6, abs=1e-6)
        assert info["min_range"] == pytest.approx(50.0) and info["goal_distance"] == pytest.approx(100.0)
    finally:
        env.close()


def test_an_imazu_case_is_scaled_to_the_own_vessel():
    """Imazu case 5 for the Otter (L = 2 m) at 1 m/s: R = 50 L = 100 m, T = 100 s. The head-on target
    is 2 R dead ahead, the crossing one sqrt(2) R at 45 deg to starboard; both reach the collision
    point (0, R) with the own ship at T (TCPA = T, DCPA = 0); the goal is 2 R ahead."""
    env = EncounterEnv(5, plant="analytic")
    try:
        obs, info = env.reset(seed=0)
        d = env.decode(obs)
        assert (d["own"]["goal_x"], d["own"]["goal_y"]) == pytest.approx((200.0, 0.0), abs=1e-4)
        assert info["targets"] == ("ts2", "ts1") and info["situation"] == "imazu-05"
        crossing, head_on = (dict(zip(TARGET_FIELDS, row)) for row in d["targets"][:2])
        assert head_on["range"] == pytest.approx(200.0, rel=1e-6) and head_on["sin_bearing"] == pytest.approx(0.0, abs=1e-6)
        assert crossing["range"] == pytest.approx(100.0 * math.sqrt(2.0), rel=1e-6)
        assert crossing["sin_bearing"] == pytest.approx(math.sqrt(0.5), rel=1e-6)
        for t in (crossing, head_on):
            assert t["tcpa"] == pytest.approx(100.0, rel=1e-6) and t["dcpa"] == pytest.approx(0.0, abs=1e-4)
        assert env.traffic.time_limit == pytest.approx(300.0)   # 3 T
        # reset(options) runs another case; the space stays
        obs, info = env.reset(options={"situation": 1})
        assert info["targets"] == ("ts1",) and obs[N_OWN + N_TARGET] == 0.0 and env.observation_space.contains(obs)
    finally:
        env.close()


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_a_collision_terminates_the_episode_with_its_reason(plant):
    """The own ship at rest (zero thrust) with the other coming at it from 10 m at 1 m/s, keeping its
    course: the hulls (2 m long, their footprints reach 1.13 m from their origins) meet after about
    (10 - 2) / 1 s, when the centres are less than 2 x 1.13 m apart. On MuJoCo the contact force
    ends the episode, on the analytic plant the footprints' overlap (not the step before)."""
    sc = two_vessels(plant, {"initial": {"eta": [0.0, 0.0, NORTH], "nu": [0.0, 0.0, 0.0]}},
                     {"initial": {"eta": [0.0, 10.0, SOUTH], "nu": [1.0, 0.0, 0.0]}})
    env = EncounterEnv(sc, goals={"own": (0.0, 100.0)}, collision_penalty=5.0)
    try:
        env.reset(seed=0)
        before = math.inf
        for _ in range(200):
            if plant == "analytic":
                before = env.traffic.hull_distance(0, 1)
            obs, reward, terminated, truncated, info = env.step(np.zeros(2))
            if terminated or truncated:
                break
        assert terminated and not truncated
        assert info["kind"] == "collision" and "'own' collided with 'ship'" in info["reason"]
        assert reward < -4.0                           # the penalty of 5, less what little progress there was
        assert 7.0 < info["time"] < 9.0
        assert info["min_range"] < 2 * 1.13
        if plant == "analytic":
            assert before > 0.0 >= env.traffic.hull_distance(0, 1)
        with pytest.raises(gymnasium.error.ResetNeeded):
            env.step(np.zeros(2))
    finally:
        env.close()


def test_agents_leave_in_the_step_they_end_and_the_others_go_on():
    """PettingZoo: "ship" (heading held by a hand policy) runs into "own" (at rest); both are
    dropped from ``agents`` in that step with kind "collision", "far" (300 m away) goes on, then is
    truncated at the time limit; nobody comes back."""
    sc = two_vessels("analytic", {"initial": {"eta": [0.0, 0.0, NORTH], "nu": [0.0, 0.0, 0.0]}},
                     {"initial": {"eta": [0.0, 10.0, SOUTH], "nu": [1.0, 0.0, 0.0]}}, duration=12.0,
                     third={"initial": {"eta": [300.0, 0.0, NORTH], "nu": [1.0, 0.0, 0.0]}})
    env = traffic_parallel_env(sc, goals={"own": (0.0, 100.0), "ship": (0.0, -100.0), "far": (300.0, 200.0)})
    try:
        env.reset(seed=0)
        gone, collided_at = set(), None
        while env.agents:
            x = env.state().reshape(3, 6)
            acts = {}
            for a in env.agents:
                i = env.possible_agents.index(a)
                if a == "own":
                    acts[a] = np.zeros(2, np.float32)
                else:   # hold the start's heading: the yaw moment against the heading error and the yaw rate
                    psi_d = SOUTH if a == "ship" else NORTH
                    e = math.remainder(x[i, 2] - psi_d, 2 * math.pi)
                    acts[a] = np.array([0.4, np.clip(-4.0 * e - 2.0 * x[i, 5], -1, 1)], np.float32)
            live = list(env.agents)
            obs, rew, term, trunc, info = env.step(acts)
            assert set(obs) == set(rew) == set(term) == set(trunc) == set(info) == set(live)
            assert not gone & set(env.agents)
            ended = {a for a in live if term[a] or trunc[a]}
            assert set(env.agents) == set(live) - ended
            gone |= ended
            if term.get("own"):
                collided_at = info["own"]["time"]
                assert term["ship"] and info["ship"]["kind"] == info["own"]["kind"] == "collision"
                assert env.agents == ["far"]
        assert collided_at is not None and collided_at < 12.0
        assert trunc["far"] and info["far"]["kind"] == "time_limit" and info["far"]["time"] == pytest.approx(12.0)
    finally:
        env.close()


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_the_own_ships_step_is_the_fleet_loops_bit_for_bit(plant):
    """Imazu case 5 run by usv_mj.simulate (every vessel on its controller), then through the env
    with the own ship's recorded controller output as its actions (physical, one control period a
    step): the control step (clip within bounds, the quantizer, the actuators) and the plant give
    every vessel's state, and the own ship's commands, exactly as the fleet loop recorded them."""
    env = EncounterEnv(5, plant=plant, duration=2.0, action_repeat=1, physical_actions=True)
    try:
        record = simulate(env.traffic.scenario)
        assert record.status == "completed"
        own = record["own"]
        env.reset(seed=0)
        n = len(own["t"]) - 1
        assert n == 200
        for k in range(n):
            obs, reward, terminated, truncated, info = env.step(np.array([own["tau_u"][k], own["tau_r"][k]]))
            for c, name in enumerate(("tau_u", "tau_r")):
                assert info["action"][c] == own[name][k]
                assert info["command"][c] == own["q_" + name][k]
            assert info["thrust"][0] == own["f_u"][k] and info["thrust"][1] == own["f_r"][k]
            for i, vessel in enumerate(record.names):
                row = np.array([record[vessel][c][k + 1] for c in ("x", "y", "psi", "u", "v", "r")])
                assert np.array_equal(env.traffic.X[i], row), (plant, k, vessel)
        assert truncated and info["kind"] == "time_limit"
    finally:
        env.close()


def test_options_are_checked_with_the_place_named():
    with pytest.raises(ValueError, match=r"usv_mj/Encounter-v0: unknown options \['speeed'\]"):
        EncounterEnv(1, speeed=2.0)
    with pytest.raises(ValueError, match=r"situation must be an Imazu case 1\.\.22"):
        EncounterEnv(23, plant="analytic")
    with pytest.raises(ValueError, match=r"action_repeat must be an integer >= 1"):
        traffic_parallel_env(1, plant="analytic", action_repeat=0)
    env = traffic_parallel_env(1, plant="analytic")
    with pytest.raises(ValueError, match=r"step before reset\(\): call reset\(\) first"):
        env.step({"own": np.zeros(2)})


@pytest.mark.parametrize("quantize", [True, False])
def test_the_quantize_option_is_the_track_tasks(quantize):
    """quantize=False passes the clipped action to the actuators as it is (command = action);
    quantize=True puts it through Eq. 3's quantizer (a level, not 100 N), whatever [quantizer] says."""
    env = EncounterEnv(1, plant="analytic", physical_actions=True, quantize=quantize, action_repeat=1)
    try:
        env.reset(seed=0)
        _, _, _, _, info = env.step(np.array([100.0, 5.0]))
        assert info["action"].tolist() == [100.0, 5.0]
        assert (info["command"].tolist() == [100.0, 5.0]) is not quantize
    finally:
        env.close()
