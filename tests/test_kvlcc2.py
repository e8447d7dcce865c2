"""KVLCC2 by the MMG standard method (usv_mj.physics.mmg, usv_mj.vessels.kvlcc2) beside the ``shipmmg`` package.

The oracle is shipmmg's ``simulate_mmg_3dof`` (a test extra; scipy's RK45 at tight tolerances) with
the same KVLCC2 7 m parameters, in SI units throughout (rho = 1025 kg/m^3 for the masses and the
forces alike; shipmmg's own test fixture mixes rho = 1.025 in the masses with its default 1025 in the
forces). Conventions matched (docs/vessels.md, KVLCC2): shipmmg's frame has y, r and delta to
starboard, usv_mj's to port, so its (y, psi, v, r, delta) are mirrored; its rudder is a given
delta(t) (a natural cubic spline through the samples), so the rudder's ramp at the model's rate is
sampled at 0.01 s; the propeller's n_P is the one our approach found (taken from the run). The
zig-zag's switching is written here with solve_ivp's terminal events (shipmmg's own
``zigzag_test_mmg_3dof`` does not pass tolerances on and runs at rtol = 1e-3: its heading reaches
10 deg 0.36 s early, 3 %). One difference of model: shipmmg takes U and beta from v - x_G r where
the MMG standard takes the midship v_m (our v); the vessel's ``drift_point_x = -x_G`` reproduces
it (the oracle runs), and the standard (the default) is checked against shipmmg where the two
coincide (x_G = 0) and, for the turning circle, at the paper's x_G too. Our rudder moves in steps of
rate * control period (the actuators' exact per-period limit), shipmmg's along a spline: 0.05 %.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from shipmmg.mmg_3dof import (Mmg3DofBasicParams, Mmg3DofManeuveringParams, get_sub_values_from_simulation_result,
                              simulate_mmg_3dof)

from usv_mj import load_scenario
from usv_mj.jobs.manoeuvres import turning_circle, zigzag
from usv_mj.jobs.manoeuvres.imo import criteria
from usv_mj.jobs.manoeuvres.measures import turning_measures, zigzag_measures
from usv_mj.physics.mmg import mmg_forces, mmg_terms
from usv_mj.vessels.kvlcc2 import KVLCC2Options, pack

TIGHT = {"rtol": 1e-9, "atol": 1e-11, "max_step": 0.05}


def oracle_params(o: KVLCC2Options):
    m_x, m_y, j_z = o.added_masses()
    basic = Mmg3DofBasicParams(
        L_pp=o.L_pp, B=o.B, d=o.d, x_G=o.x_G, D_p=o.D_p, m=o.mass, I_zG=o.I_zG, A_R=o.A_R, η=o.D_p / o.H_R,
        m_x=m_x, m_y=m_y, J_z=j_z, f_α=o.f_alpha, ϵ=o.epsilon, t_R=o.t_R, x_R=o.x_R_dash * o.L_pp, a_H=o.a_H,
        x_H=o.x_H_dash * o.L_pp, γ_R_minus=o.gamma_R_minus, γ_R_plus=o.gamma_R_plus, l_R=o.l_R_dash, κ=o.kappa,
        t_P=o.t_P, w_P0=o.w_P0, x_P=o.x_P_dash)
    names = ("k_0", "k_1", "k_2", "R_0_dash", "X_vv_dash", "X_vr_dash", "X_rr_dash", "X_vvvv_dash", "Y_v_dash",
             "Y_r_dash", "Y_vvv_dash", "Y_vvr_dash", "Y_vrr_dash", "Y_rrr_dash", "N_v_dash", "N_r_dash", "N_vvv_dash",
             "N_vvr_dash", "N_vrr_dash", "N_rrr_dash")
    return basic, Mmg3DofManeuveringParams(**{k: getattr(o, k) for k in names})


def kvlcc2(**options):
    return load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2", **options}})


@pytest.fixture(scope="module")
def scenario():
    """KVLCC2 with shipmmg's drift point (module docstring): the oracle's model exactly."""
    return kvlcc2(drift_point_x=-KVLCC2Options().x_G)


def test_forces_equal_shipmmg_at_states():
    """X_H, X_P, X_R, Y_H, Y_R, N_H, N_R of the one kernel equal shipmmg's at states of both signs
    (x_G = 0, where shipmmg's U and beta from v - x_G r are the standard's), and the mirror into
    usv_mj's frame is exact."""
    o = KVLCC2Options(x_G=0.0)
    q = np.array(pack(o))
    basic, man = oracle_params(o)
    states = [(1.179, 0.0, 0.0, 0.0, 11.85), (1.0, 0.12, 0.05, 0.4, 11.85), (0.7, -0.2, -0.08, -0.61, 14.0),
              (0.9, 0.3, -0.04, 0.2, 9.0), (0.5, -0.05, 0.1, -0.3, 17.95)]
    u, v, r, d, n = (list(c) for c in zip(*states))
    ref = np.array(get_sub_values_from_simulation_result(u, v, r, d, n, basic, man, ρ=o.rho))   # 7 x states
    # shipmmg 0.0.11's get_sub_values writes Y_R = -(1 - t_R) F_N cos(delta); its simulator (and the
    # MMG standard) -(1 + a_H) F_N cos(delta): the simulator's is the one checked
    ref[4] *= (1.0 + o.a_H) / (1.0 - o.t_R)
    for i, (ui, vi, ri, di, ni) in enumerate(states):
        x_h, y_h, n_h, x_p, x_r, y_r, n_r = mmg_forces(q, 0, ui, vi, ri, ni, di)
        ours = np.array([x_h, x_r, x_p, y_h, y_r, n_h, n_r])
        np.testing.assert_allclose(ours, ref[:, i], rtol=1e-10, atol=1e-9)
        # the mirror: our (v, r, delta) to port are the MMG's negated; Y and N come back negated
        f = mmg_terms(q, 0, ui, -vi, -ri, ni, -di)
        m, mx, my = o.mass, *o.added_masses()[:2]
        assert f[0] == pytest.approx(x_h + x_p + x_r + (m + my) * vi * ri, rel=1e-12, abs=1e-12)
        assert -f[1] == pytest.approx(y_h + y_r - (m + mx) * ui * ri, rel=1e-12, abs=1e-12)
        assert -f[2] == pytest.approx(n_h + n_r, rel=1e-12, abs=1e-12)


def _oracle_turning(o, n_p, u0, t_execute, duration, rudder_deg=35.0):
    basic, man = oracle_params(o)
    t = np.arange(0.0, duration + 1e-9, 0.01)
    delta = np.clip(math.radians(o.rudder_rate_deg_s) * (t - t_execute), 0.0, math.radians(rudder_deg))
    sol = simulate_mmg_3dof(basic, man, t, delta, np.full(len(t), n_p), u0=u0, ρ=o.rho, **TIGHT)
    u, v, r, x, y, psi = sol.sol(t)[:6]
    return turning_measures(t, x, -y, -psi, u, -v, -r, t_execute=t_execute, length=o.L_pp)   # mirrored


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_turning_circle_35_beside_shipmmg(scenario, plant):
    """The 35 deg starboard turning circle: advance and tactical diameter within 1 % of shipmmg's."""
    ours = turning_circle(scenario, plant_kind=plant, duration=70.0)
    m, o = ours["measures"], KVLCC2Options()
    ref = _oracle_turning(o, m["propeller_rps"], o.service_speed, 5.0, 70.0)
    if plant == "analytic":   # the standard's drift point: still within 1 % here
        std = turning_circle(kvlcc2(), plant_kind=plant, duration=70.0)["measures"]
        for key in ("advance_m", "tactical_diameter_m"):
            assert std[key] == pytest.approx(ref[key], rel=0.01), key
    assert ours["status"] == "completed" and m["turn"] == "starboard"
    for key in ("advance_m", "tactical_diameter_m", "transfer_m"):
        assert m[key] == pytest.approx(ref[key], rel=0.01), key
    rows = {r["criterion"]: r for r in ours["imo"]["rows"]}
    assert ours["imo"]["applies"] and rows["advance < 4.5 L"]["value"] == pytest.approx(m["advance_m"] / 7.0)


def _oracle_zigzag(o, n_p, u0, angle_deg, duration):
    """The zig-zag on shipmmg's simulator: the rudder ramps at the model's rate to +-angle (MMG sign:
    starboard first), reversed by a terminal event when the heading passes +-angle."""
    basic, man = oracle_params(o)
    rate, target, switch = math.radians(o.rudder_rate_deg_s), math.radians(angle_deg), math.radians(angle_deg)
    t0, state, side = 0.0, (u0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), 1.0
    ts, psis, cmds = [], [], []
    while t0 < duration - 1e-9:
        t = np.arange(t0, duration + 1e-9, 0.01)
        delta = np.clip(state[6] + side * rate * (t - t0), -target, target)

        def passed(tt, y, s=side):
            return y[5] - s * switch
        passed.terminal = True
        passed.direction = side
        sol = simulate_mmg_3dof(basic, man, t, delta, np.full(len(t), n_p), u0=state[0], v0=state[1], r0=state[2],
                                x0=state[3], y0=state[4], ψ0=state[5], ρ=o.rho, events=passed, **TIGHT)
        t_end = float(sol.t[-1])
        k = t <= t_end
        ts.append(t[k])
        psis.append(sol.sol(t[k])[5])
        cmds.append(np.full(k.sum(), -side))        # our command's sign: starboard is negative
        if sol.status != 1:
            break
        state, t0, side = tuple(sol.y_events[0][0]), t_end, -side
    t, psi, cmd = np.concatenate(ts), np.concatenate(psis), np.concatenate(cmds)
    return zigzag_measures(t, -psi, cmd, angle_deg)


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_zigzag_10_10_beside_shipmmg(scenario, plant):
    """The 10/10 zig-zag at the model's rudder rate: first and second overshoot within 1 % of the oracle's."""
    ours = zigzag(scenario, plant_kind=plant, duration=80.0)
    m, o = ours["measures"], KVLCC2Options()
    ref = _oracle_zigzag(o, m["propeller_rps"], o.service_speed, 10.0, 80.0)
    assert m["second_overshoot_deg"] is not None
    for key in ("first_overshoot_deg", "second_overshoot_deg", "time_to_second_execute_s"):
        assert m[key] == pytest.approx(ref[key], rel=0.01), key
    lv = 7.0 / o.service_speed * math.sqrt(45.714)   # the full-scale ship's L/V sets the limits
    assert ours["imo"]["full_scale"]["L_over_V_s"] == pytest.approx(lv) and lv >= 30
    limits = {r["criterion"]: r["limit"] for r in ours["imo"]["rows"]}
    assert limits["10/10 first overshoot"] == 20.0 and limits["10/10 second overshoot"] == 40.0


# SIMMAN 2008's free-running tests of the KVLCC2 7 m model at MARIN (1:45.714, U_0 = 1.179 m/s): the
# measures derived from MARIN's time series as the SIMMAN data give them (restated in the public repo
# martinlarsalbert/System-identification-of-Vessel-Manoeuvring-Models @ 4b7ce53, data/01_raw/kvlcc2/
# MARIN_FREE_KVLCC2_tc_-35_m.dat and _zz_-10_m.dat, starboard first; docs/vessels.md, KVLCC2 beside
# the model tests). They are not the MMG's: the deviations below are the coefficient set's, stated.
MARIN_STARBOARD_35 = {"advance_L": 3.10, "tactical_diameter_L": 3.34}
MARIN_ZIGZAG_10_FIRST_DEG = 8.1


def test_turning_and_zigzag_beside_the_simman_free_running_tests():
    """The standard MMG (the default drift point) beside MARIN's model tests: the 35 deg advance
    within 3 % (ours 1 % short), the tactical diameter within 12 % and tighter (ours 10 % under), the
    10/10 first overshoot within 45 % and smaller (ours 38 % under: the coefficient set's
    yaw-checking is stronger than the tank's)."""
    turn = turning_circle(kvlcc2(), plant_kind="analytic", duration=70.0)["measures"]
    advance, td = turn["advance_m"] / 7.0, turn["tactical_diameter_m"] / 7.0
    assert advance == pytest.approx(MARIN_STARBOARD_35["advance_L"], rel=0.03)
    assert td == pytest.approx(MARIN_STARBOARD_35["tactical_diameter_L"], rel=0.12) and td < 3.34
    first = zigzag(kvlcc2(), plant_kind="analytic", duration=80.0)["measures"]["first_overshoot_deg"]
    assert first == pytest.approx(MARIN_ZIGZAG_10_FIRST_DEG, rel=0.45) and first < MARIN_ZIGZAG_10_FIRST_DEG


def test_standard_zigzag_equals_shipmmg_where_their_drift_points_coincide():
    """With x_G = 0, v - x_G r is the midship v_m: the standard (default) model agrees to 1 %."""
    o = KVLCC2Options(x_G=0.0)
    m = zigzag(kvlcc2(x_G=0.0), plant_kind="analytic", duration=80.0)["measures"]
    ref = _oracle_zigzag(o, m["propeller_rps"], o.service_speed, 10.0, 80.0)
    for key in ("first_overshoot_deg", "second_overshoot_deg"):
        assert m[key] == pytest.approx(ref[key], rel=0.01), key


def test_imo_criteria_of_a_model_are_the_ships():
    c = criteria("zigzag", {"first_overshoot_deg": 5.0}, 7.0, 1.179, switch_deg=10, scale=45.714)
    assert c["applies"] and c["length_m"] == pytest.approx(320.0, rel=1e-4)
    assert c["model_L_over_V_s"] == pytest.approx(7.0 / 1.179)
    assert not criteria("zigzag", {}, 7.0, 1.179, switch_deg=10)["applies"]


def test_both_plants_accelerate_alike():
    """The callback (MuJoCo, inputs in ctrl on gearless motors) and the analytic derivative call the
    one kernel: nu_dot agrees at a turning state with the rudder over."""
    from usv_mj.builder import make_plant

    s = load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}, "disturbance": {"scale": 0.0}})
    from usv_mj.physics.ship import PaperDisturbance, body_acceleration

    nu = np.array([0.9, 0.1, -0.05])
    mj = make_plant(s, "mujoco", environment=None)
    try:
        mj.reset((1.0, 2.0, 0.3), nu)
        a_mj = mj.body_acceleration(11.85, -0.5)
    finally:
        mj.close()
    a_an = body_acceleration(s.ship.as_array(), PaperDisturbance(scale=0.0).as_array(), 0.0,
                             np.array([1.0, 2.0, 0.3]), nu, 11.85, -0.5)
    np.testing.assert_allclose(a_mj, a_an, rtol=1e-9, atol=1e-12)


def test_spiral_steps_the_rudder_and_its_steady_turn_is_shipmmgs(scenario):
    """Dieudonné's spiral on the ruddered vessel steps the rudder angle (10 deg to port, 0, 10 deg to
    starboard and back): the first hold's steady yaw rate equals shipmmg's for the same rudder
    ramped to 10 deg to port (MMG frame: -10 deg) at the same n_P, to 1 %."""
    from usv_mj.jobs.manoeuvres import spiral

    res = spiral(scenario, plant_kind="analytic", max_rudder_deg=10.0, steps=1, hold_s=120.0)
    assert res["status"] == "completed" and res["rudder"].startswith("rudder angle")
    first = res["measures"]["points"][0]
    assert (first["command"], first["branch"]) == (10.0, "down")
    o = KVLCC2Options()
    basic, man = oracle_params(o)
    t = np.arange(0.0, 120.0 + 1e-9, 0.01)
    delta = -np.clip(math.radians(o.rudder_rate_deg_s) * t, 0.0, math.radians(10.0))
    sol = simulate_mmg_3dof(basic, man, t, delta, np.full(len(t), res["measures"]["propeller_rps"]),
                            u0=o.service_speed, ρ=o.rho, **TIGHT)
    r_oracle = -np.mean(sol.sol(t[t >= 90.0])[2])     # mirrored: our r is to port
    assert r_oracle > 0.02 and first["yaw_rate"] == pytest.approx(r_oracle, rel=0.01)


def test_stopping_is_refused_on_the_ruddered_vessel(scenario):
    from usv_mj.core.errors import ScenarioError
    from usv_mj.scenario.manoeuvre import manoeuvre_from_table

    with pytest.raises(ScenarioError, match="not available on the vessel 'kvlcc2': the MMG standard "
                                            "method models the propeller ahead only"):
        manoeuvre_from_table({"kind": "stopping"}, "<test>", scenario.vessel)
    assert manoeuvre_from_table({"kind": "spiral"}, "<test>", scenario.vessel).options.max_rudder_deg == 10.0


def test_a_sea_is_refused_on_the_mmg_vessel():
    from usv_mj.core.errors import ScenarioError

    with pytest.raises(ScenarioError, match="calm deep water only"):
        load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}, "sea": {"preset": "moderate"}})


def test_both_plants_agree_open_loop():
    """60 s of rudder and propeller steps (both signs of delta, n_P changing) at h = 0.01 s: the
    MuJoCo plant (rigid body + callback) and the analytic RK4 of the same kernel stay together."""
    from usv_mj.builder import make_plant

    s = load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}, "disturbance": {"scale": 0.0},
                                                 "control_period": 0.01})
    states = {}
    for kind in ("analytic", "mujoco"):
        plant = make_plant(s, kind, environment=None)
        try:
            plant.reset((0.0, 0.0, 0.0), (1.179, 0.0, 0.0))
            out = []
            for k in range(6000):
                t = 0.01 * k
                delta = math.radians(20.0) * math.sin(0.3 * t) - math.radians(5.0)
                plant.step(11.85 + 3.0 * (t > 30.0), delta)
                out.append(np.array(plant.state))
            states[kind] = np.array(out)
        finally:
            plant.close()
    a, m = states["analytic"], states["mujoco"]
    assert np.max(np.hypot(a[:, 0] - m[:, 0], a[:, 1] - m[:, 1])) < 1e-9
    assert np.max(np.abs(a[:, 2] - m[:, 2])) < 1e-10
    assert abs(a[-1, 2]) > 0.1 and np.ptp(a[:, 5]) > 0.01   # it did turn


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_compiled_and_python_loops_give_the_same_record(plant):
    """The zig-zag (the heading switch, the rudder's rate limit, the MMG kernel) bit for bit in both loops."""
    from usv_mj.jobs.manoeuvres.trial import manoeuvre_scenario
    from usv_mj.scenario.manoeuvre import ManoeuvreSpec, ZigzagOptions
    from usv_mj.loop.simulate import simulate

    s = kvlcc2()
    spec = ManoeuvreSpec("zigzag", ZigzagOptions(approach_speed=1.179, duration=15.0, control_period=0.01))
    ms = manoeuvre_scenario(s, spec)
    fast = simulate(ms, plant_kind=plant, loop="auto")
    slow = simulate(ms, plant_kind=plant, loop="python")
    assert (fast.metadata["loop"], slow.metadata["loop"]) == ("compiled", "python")
    for col in ("x", "y", "psi", "u", "v", "r", "f_u", "f_r", "sat_r", "heading_change"):
        assert np.array_equal(fast[col], slow[col]), col
    assert np.ptp(fast["f_r"]) > 0.3   # the rudder went both ways


def test_a_force_controller_drives_the_ruddered_vessel_through_the_allocation():
    """PPC's, PI's and LOS's (tau_u, tau_r) are allocated to (n_P, delta) (usv_mj.physics.mmg.mmg_allocate);
    the open-loop controller, whose channels are the vessel's own, is not allocated; a controller that
    commands a rudder is refused on a hull that takes forces."""
    from usv_mj.builder import build, check_commands
    from usv_mj.core.errors import ScenarioError

    s = load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}, "duration": 1.0})
    for kind in ("ppc", "pi", "los"):
        check_commands(s, kind)
        with build(s, plant_kind="analytic", controller_kind=kind) as parts:
            assert parts.actuators.allocation is not None
    with build(s, plant_kind="analytic", controller_kind="open_loop") as parts:
        assert parts.controller.commands == "any" and parts.actuators.allocation is None
    from usv_mj.builder import commands_error

    rudder = type("RudderLaw", (), {"commands": "rudder"})()
    assert "commands the propeller's n_P and a rudder angle" in commands_error(load_scenario(preset="paper"), rudder, "mine")
    with pytest.raises(ScenarioError):
        raise ScenarioError(commands_error(load_scenario(preset="paper"), rudder, "mine"))


def test_the_command_line_checks_vessel_keys_and_compare_runs_the_rudder(tmp_path):
    """--set vessel.KEY belongs to --vessel's kind (KVLCC2's rudder rate, not a paper-hull key); compare
    drives the ruddered hull with n_P and rudder steps in open loop (the force signal mapped to its
    channels, within 35 deg) and the PPC law through the allocation in closed loop: both plants agree
    as the paper hull's do."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    run = lambda *a: subprocess.run([sys.executable, "-m", "usv_mj.cli.main", *a], cwd=tmp_path, capture_output=True,
                                    text=True, timeout=300, env={**__import__("os").environ, "PYTHONPATH": str(root)})
    bad = run("manoeuvre", "turning", "--vessel", "kvlcc2", "--set", "vessel.rudder_rate_deg_s=-1",
              "--out", str(tmp_path / "m"), "-q")
    assert bad.returncode == 2 and "vessel.rudder_rate_deg_s must be > 0, got -1.0" in bad.stderr, bad.stderr
    done = run("compare", "--vessel", "kvlcc2", "--duration", "5", "--out", str(tmp_path / "c"), "-q")
    assert done.returncode == 0, done.stderr
    result = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert result["open_loop"]["max_position_m"] < 1e-9 and "rudder angle" in result["open_loop"]["inputs"]
    assert result["closed_loop"]["max_position_m"] < 1e-9


def test_the_open_loop_signal_of_a_ruddered_vessel_is_the_force_signal_in_its_channels():
    from usv_mj.jobs.compare import open_loop_inputs, vessel_inputs

    s = kvlcc2()
    raw, ours = open_loop_inputs(20.0, 0.01), vessel_inputs(s, 20.0, 0.01)
    np.testing.assert_allclose(ours[:, 0], 11.85 * (0.5 + (raw[:, 0] + 60.0) / 280.0), rtol=1e-12)
    np.testing.assert_allclose(ours[:, 1], math.radians(30.0) * raw[:, 1] / 11.0, rtol=1e-12)
    assert np.abs(ours[:, 1]).max() <= math.radians(30.0) + 1e-12 and ours[:, 0].min() >= 0.5 * 11.85 - 1e-9
