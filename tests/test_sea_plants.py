"""Both plants in a sea (SEA.md §6-7, issue 7): the MuJoCo plant realises the sea of usv_mj.physics.sea.

References: the analytic sea kernels (sea_body_acceleration, the analytic RK4 plant with the same
Environment), the closed form of a hull carried by a uniform current (position x0 + t v_c), and the
MuJoCo plant without an environment (today's calm model) for the calm check.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.jobs.compare import open_loop_inputs
from usv_mj.plants import mujoco_callback as mcb
from usv_mj.plants.analytic import AnalyticPlant
from usv_mj.plants.mujoco_plant import MuJoCoPlant
from usv_mj.physics.sea import (CurrentSettings, Environment, SeaSettings, WindSettings, load_sea_preset,
                        sea_body_acceleration)
from usv_mj.physics.ship import PaperDisturbance, ShipParams

SHIP = ShipParams()
DIST = PaperDisturbance()
BARE = ShipParams(uncertainty_scale=0.0)      # the hull alone: no Delta
NO_DIST = PaperDisturbance(scale=0.0)         # and no d(t)
DT = 1e-3


def all_loads(current_sigma: float = 0.0, gust_sigma: float = 1.0) -> SeaSettings:
    """The issue's parity sea: preset ``moderate`` waves + current 0.3 m/s + wind 5 m/s (gusts)."""
    return SeaSettings(waves=load_sea_preset("moderate").waves,
                       current=CurrentSettings(speed=0.3, direction_deg=30.0, sigma=current_sigma),
                       wind=WindSettings(speed=5.0, direction_deg=90.0, gust_sigma=gust_sigma))


def thrust_schedule(duration: float, dt: float = DT) -> np.ndarray:
    """A 60 s style thrust schedule: surge steps and sines, yaw sines and a square wave [N, N m]."""
    t = np.arange(int(round(duration / dt))) * dt
    return np.stack([80 + 60 * np.sign(np.sin(0.7 * t)) + 20 * np.sin(0.3 * t),
                     6 * np.sin(0.45 * t) + 3 * np.sign(np.sin(1.3 * t))], axis=1)


def run(plant, inputs, eta0=(1.0, 2.0, 0.3), nu0=(0.5, 0.0, 0.0)) -> np.ndarray:
    plant.reset(eta0, nu0)
    out = np.empty((len(inputs), 6))
    for k, (tu, tr) in enumerate(inputs):
        plant.step(tu, tr)
        out[k] = plant.state
    return out


def max_position_difference(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])))


# --- SEA.md §7 check 1 (MuJoCo half): calm is today's model bit for bit ---------------------------


@pytest.mark.parametrize("callback, native_step, seconds", [("native", True, 60.0), ("native", False, 10.0),
                                                            ("python", False, 3.0)])
def test_calm_environment_is_bit_identical_to_no_environment(callback, native_step, seconds):
    inputs = thrust_schedule(seconds)
    runs = []
    for env in (None, Environment(), Environment(SeaSettings(), t_max=5.0)):
        with MuJoCoPlant(SHIP, DIST, DT, 1, callback=callback, native_step=native_step, environment=env) as p:
            assert p.environment is None and p.data.userdata[mcb.U_SEA_ON] == 0.0
            runs.append(run(p, inputs))
    assert np.array_equal(runs[0], runs[1]) and np.array_equal(runs[0], runs[2])
    # ... and the sea does change the motion (the comparison above can fail)
    with MuJoCoPlant(SHIP, DIST, DT, 1, callback=callback, native_step=native_step,
                     environment=Environment(all_loads())) as p:
        assert p.data.userdata[mcb.U_SEA_ON] == 1.0
        sea = run(p, inputs)
    assert max_position_difference(sea, runs[0]) > 1e-3


# --- the callback realises the analytic sea acceleration ------------------------------------------


@pytest.mark.parametrize("callback", ["native", "python"])
def test_body_acceleration_in_a_sea_equals_the_analytic_kernel(callback):
    env = Environment(all_loads(current_sigma=0.05), t_max=400.0)
    ep, waves, cg, wg = env.packed
    p, dp = SHIP.as_array(), DIST.as_array()
    rng = np.random.default_rng(7)
    with MuJoCoPlant(SHIP, DIST, callback=callback, environment=env) as plant:
        for _ in range(100):
            eta = np.array([rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(-7, 7)])
            nu = np.array([rng.uniform(-2, 2), rng.uniform(-1, 1), rng.uniform(-0.8, 0.8)])
            t = rng.uniform(0.0, 300.0)
            tu, tr = rng.uniform(-300, 300), rng.uniform(-50, 50)
            plant.reset(eta, nu, t)
            got = plant.body_acceleration(tu, tr)
            want = sea_body_acceleration(p, dp, ep, waves, cg, wg, t, eta, nu, tu, tr)
            calm = sea_body_acceleration(p, dp, *Environment().packed, t, eta, nu, tu, tr)
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
            assert np.max(np.abs(want - calm)) > 1e-4  # the sea is really in it


# --- SEA.md §7 check 14: plant parity with all loads on -------------------------------------------


def _parity(duration: float, callback: str = "native", env_t_max: float = 600.0):
    inputs = open_loop_inputs(duration, DT)
    env = Environment(all_loads(current_sigma=0.05), t_max=env_t_max)
    xa = run(AnalyticPlant(SHIP, DIST, DT, 1, environment=env), inputs)
    with MuJoCoPlant(SHIP, DIST, DT, 1, callback=callback, environment=env) as plant:
        xm = run(plant, inputs)
    return xa, xm


def test_parity_all_loads_20_s_native_and_python():
    xa, xm = _parity(20.0)
    assert max_position_difference(xa, xm) < 1e-6
    assert np.max(np.abs(xa[:, 2] - xm[:, 2])) < 1e-6
    _, xp = _parity(3.0, callback="python")
    assert max_position_difference(xp, xm[:len(xp)]) < 1e-9


ALL_LOADS_TABLE = {"waves": {"hs": 0.2, "tp": 2.0, "gamma": 3.3},
                   "current": {"speed": 0.3, "direction_deg": 30.0, "sigma": 0.05},
                   "wind": {"speed": 5.0, "direction_deg": 90.0, "gust_sigma": 1.0}}


@pytest.mark.slow
def test_parity_all_loads_300_s():
    """Issue 7 / SEA.md §7 check 14: open loop, moderate sea + 0.3 m/s current + 5 m/s wind, 300 s at
    1 ms, identical inputs (compare's). The uncontrolled hull in this sea is sensitive: the analytic
    plant from a start moved by 1e-12 m departs from itself by metres within 300 s, so two distinct
    integrators cannot stay within 1e-6 m for 300 s. Checked: over the whole linear regime (the
    nudged twin within 1e-3 m, about 200 s here) the plants differ by no more than 10 x what a
    1e-12 m nudge of the start produces (usv_mj.jobs.compare.sea_sensitivity; measured ratio 1.2).
    usv-mj compare with this sea makes the same check."""
    from usv_mj.jobs.compare import run_open_loop, sea_environment, sea_sensitivity
    from usv_mj.scenario.spec import load_scenario

    scenario = load_scenario(preset="paper", overrides={"sea": ALL_LOADS_TABLE, "duration": 300.0})
    env = sea_environment(scenario)
    dt = scenario.control_period
    inputs = open_loop_inputs(300.0, dt)
    eta0, nu0 = scenario.initial.eta, scenario.initial.nu
    xa = run_open_loop(AnalyticPlant(scenario.ship, scenario.disturbance, dt, 1, environment=env), inputs, eta0, nu0)
    with MuJoCoPlant(scenario.ship, scenario.disturbance, dt, 1, environment=env) as plant:
        xm = run_open_loop(plant, inputs, eta0, nu0)
    assert np.all(np.isfinite(xm))
    assert max_position_difference(xa[:10_001], xm[:10_001]) < 1e-6  # the first 10 s
    sens = sea_sensitivity(scenario, env, inputs, xa, xm)
    assert sens["sensitivity_max_position_m"] > 1e-3  # the sea really is sensitive over 300 s
    assert sens["within_sensitivity"], sens


@pytest.mark.slow
def test_parity_all_loads_adrift_300_s_at_the_calm_tolerance():
    """SEA.md §7 check 14 with the calm-water number: the unpowered hull (tau = 0; d(t) and Delta on)
    in the moderate sea + varying current + gusty wind, 300 s at 1 ms: the plants stay within 1e-6 m.
    It is a real excursion (tens of metres drifted, yawing) and, unlike the driven hull above, not
    sensitive to its start (a 1e-12 m nudge stays below 1e-9 m), so the tolerance means something."""
    from usv_mj.jobs.compare import compare_adrift, sea_environment
    from usv_mj.scenario.spec import load_scenario

    scenario = load_scenario(preset="paper", overrides={"sea": ALL_LOADS_TABLE, "duration": 300.0})
    res = compare_adrift(scenario, sea_environment(scenario))
    assert res["max_position_m"] < 1e-6, res
    assert res["max_heading_rad"] < 1e-6, res
    assert res["path_length_m"] > 30.0 and res["max_yaw_rate_rad_s"] > 0.5, res
    assert res["sensitivity_max_position_m"] < 1e-9, res


def test_plants_difference_in_a_sea_is_rk4_truncation():
    """Halving dt divides the plants' difference by about 2^4 = 16 (both are RK4 of the same ODE; a
    different model would leave a difference that does not shrink)."""
    diffs = []
    for dt in (0.02, 0.01):
        inputs = open_loop_inputs(20.0, dt)
        env = Environment(all_loads(current_sigma=0.05), t_max=100.0)
        xa = run(AnalyticPlant(SHIP, DIST, dt, 1, environment=env), inputs)
        with MuJoCoPlant(SHIP, DIST, dt, 1, environment=env) as plant:
            xm = run(plant, inputs)
        diffs.append(max_position_difference(xa[1::int(round(0.02 / dt))], xm[1::int(round(0.02 / dt))]))
    ratio = diffs[0] / diffs[1]
    assert 8.0 < ratio < 32.0, (diffs, ratio)


def test_grids_growing_during_a_run_refresh_the_callback():
    """An environment made with a 1 s horizon (varying current, gusts) must give the same run as one
    made with the whole horizon: the plant extends the grids and re-writes their addresses."""
    inputs = thrust_schedule(150.0, dt=0.01)
    runs = []
    for t_max in (1.0, 400.0):
        env = Environment(all_loads(current_sigma=0.05), t_max=t_max)
        with MuJoCoPlant(SHIP, DIST, 0.01, 1, environment=env) as plant:
            runs.append(run(plant, inputs))
            assert plant.environment.horizon >= 150.0
    assert np.array_equal(runs[0], runs[1])


# --- SEA.md §7 check 10 on MuJoCo: a current carries the hull -------------------------------------


def test_hull_moving_with_the_current_is_carried_by_it():
    env = Environment(SeaSettings(current=CurrentSettings(speed=0.3, direction_deg=30.0)), t_max=200.0)
    vc, _ = env.current(0.0)
    psi0 = 0.4
    c, s = math.cos(psi0), math.sin(psi0)
    nu0 = (c * vc[0] + s * vc[1], -s * vc[0] + c * vc[1], 0.0)
    with MuJoCoPlant(BARE, NO_DIST, 0.01, 1, environment=env) as plant:
        plant.reset((1.0, 2.0, psi0), nu0)
        for _ in range(10_000):
            plant.step(0.0, 0.0)
        x = plant.state
    assert np.max(np.abs(x[:2] - (np.array([1.0, 2.0]) + 100.0 * vc))) < 1e-3
    assert abs(x[2] - psi0) < 1e-9


def test_relative_velocity_decays_from_rest_with_yaw_rate():
    env = Environment(SeaSettings(current=CurrentSettings(speed=0.3, direction_deg=30.0)), t_max=200.0)
    with MuJoCoPlant(BARE, NO_DIST, 0.01, 1, environment=env) as plant:
        plant.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.5))
        for _ in range(12_000):
            plant.step(0.0, 0.0)
        x = plant.state
    nu_c = env.loads(120.0, x[:3], x[3:]).nu_c
    assert np.linalg.norm(x[3:] - nu_c) < 1e-3


# --- wiring ---------------------------------------------------------------------------------------


def test_make_plant_builds_a_mujoco_plant_in_the_scenario_sea():
    from usv_mj.scenario.spec import load_scenario
    from usv_mj.builder import make_plant

    scenario = load_scenario(preset="paper", overrides={"sea": {"waves": {"hs": 0.2},
                                                                    "current": {"speed": 0.3}}})
    plant = make_plant(scenario, "mujoco")
    try:
        assert plant.environment is not None and not plant.environment.calm
        assert plant.data.userdata[mcb.U_SEA_ON] == 1.0
        assert plant.data.userdata[mcb.U_SEA_NWAVES] == 128
    finally:
        plant.close()
    calm = make_plant(load_scenario(preset="paper"), "mujoco")
    try:
        assert calm.environment is None and calm.data.userdata[mcb.U_SEA_ON] == 0.0
    finally:
        calm.close()


def test_bad_environment_is_rejected_with_its_type():
    with pytest.raises(TypeError, match="environment must be a usv_mj.physics.sea.Environment.*dict"):
        MuJoCoPlant(SHIP, DIST, environment={"hs": 0.2})


# --- usv_mj.outputs.sea_figures -----------------------------------------------------------------------------


def _fixed_hull_record(duration: float, dt: float, x: float = 3.0, y: float = -4.0):
    from usv_mj.record.run_record import RunRecord

    t = np.arange(int(round(duration / dt)) + 1) * dt
    zero = np.zeros_like(t)
    return RunRecord.from_arrays({"t": t, "x": zero + x, "y": zero + y, "psi": zero + 0.3, "u": zero, "v": zero,
                                  "r": zero})


def test_sea_summary_gives_hs_at_the_hull_and_the_settings():
    """SEA.md §7 check 3 through the summary: a hull held at one point for 1800 s (0.05 s rows) sees
    4 std(zeta) within 5 % of the preset's Hs = 0.2 m; calm water and no environment give 0."""
    from usv_mj.outputs.sea_figures import sea_summary

    settings = all_loads()
    env = Environment(settings, t_max=2000.0)
    out = sea_summary(_fixed_hull_record(1800.0, 0.05), env)
    assert abs(out["hs_at_hull_m"] / 0.2 - 1.0) < 0.05
    assert out["sea"] == settings.to_dict() and out["sea"]["waves"]["hs"] == 0.2
    short = _fixed_hull_record(10.0, 0.05)
    assert sea_summary(short, Environment()) == {"sea": SeaSettings().to_dict(), "hs_at_hull_m": 0.0}
    assert sea_summary(short, None) == {"sea": None, "hs_at_hull_m": 0.0}
    with pytest.raises(TypeError, match="sea_summary: env must be a usv_mj.physics.sea.Environment"):
        sea_summary(short, {"hs": 0.2})


def test_sea_figures_are_written(tmp_path):
    import matplotlib.image as mpimg

    from usv_mj.outputs.sea_figures import LOADS_FIGURE, SPECTRUM_FIGURE, draw_sea_figures

    env = Environment(all_loads(current_sigma=0.05), t_max=100.0)
    paths = draw_sea_figures(_fixed_hull_record(60.0, 0.01), env, tmp_path)
    assert [p.name for p in paths] == [SPECTRUM_FIGURE, LOADS_FIGURE]
    for p in paths:
        img = mpimg.imread(p)
        assert img.shape[0] > 300 and img.shape[1] > 600 and np.std(img) > 0.01
    # no waves: only the loads figure
    paths = draw_sea_figures(_fixed_hull_record(5.0, 0.01),
                             Environment(SeaSettings(current=CurrentSettings(speed=0.3))), tmp_path / "c")
    assert [p.name for p in paths] == [LOADS_FIGURE]
