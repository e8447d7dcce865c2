"""Obstacles, contacts, clearance and guidance (issue 8).

References: closed-form distances between the hull's collision shapes and circles/boxes; shapely's
polygon distances (an independent geometry library) for the numba kernels and the planner;
MuJoCo's own mj_geomDistance against the geometric kernels; static equilibrium (contact normal
force = thrust + the hull's hydrodynamic force at rest from usv_mj.physics.ship); the safety bound
clearance >= dist(p_d, O) - G(t) of usv_mj.references.planner checked row by row with MuJoCo's
distances in closed loop.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
import shapely

from usv_mj.core.layouts import N_REF
from usv_mj.scenario.obstacles import from_tables
from usv_mj.obstacles.clearance import GeometricClearance, MuJoCoClearance
from usv_mj.obstacles.hooks import make_plan
from usv_mj.plants.harbour import HarbourPlant
from usv_mj.references.planner import PlanningError, SafetyEnvelope
from usv_mj.scene.compose import compose_scene
from usv_mj.scene.hull import HULL_RADIUS
from usv_mj.references.planner import obstacle_distances
from usv_mj.scenario.spec import ScenarioError, load_scenario
from usv_mj.physics.ship import PaperDisturbance, ShipParams, hydrodynamic_force

SCENARIOS = Path(__file__).resolve().parent.parent / "examples" / "scenarios"
SHIP = ShipParams()
CALM = PaperDisturbance(scale=0.0)


def _run_through_build(scenario, **kwargs):
    """A run of an obstacle scenario through usv_mj.build / simulate: the record and its statics."""
    from types import SimpleNamespace

    from usv_mj.loop.simulate import simulate

    record = simulate(scenario, **kwargs)
    return SimpleNamespace(record=record, log=record.statics.obstacle_log, plan=record.statics.plan,
                           guidance=record.statics.guidance)


# --- specs --------------------------------------------------------------------------------------


@pytest.mark.parametrize("tables, key", [
    ([{"center": [0, 0], "radius": 1}, {"center": [3, 0], "radius": 1}, {"center": [0, 5], "radius": -0.5}],
     "obstacles[2].radius"),
    ([{"kind": "box", "center": [0, 0]}], "obstacles[0].size"),
    ([{"kind": "box", "center": [0, 0], "size": [1, 0]}], "obstacles[0].size[1]"),
    ([{"kind": "boat", "center": [0, 0]}], "obstacles[0].kind"),
    ([{"center": [0, "a"], "radius": 1}], "obstacles[0].center[1]"),
    ([{"center": [0, 0], "radius": 1, "velocity": [1.0]}], "obstacles[0].velocity"),
    ([{"center": [0, 0], "radius": 1, "colour": "red"}], "obstacles[0].colour"),
    ([{"center": [0, 0], "radius": 1, "yaw": 0.3}], "obstacles[0].yaw"),
    ([{"center": [0, 0], "radius": float("nan")}], "obstacles[0].radius"),
])
def test_bad_obstacle_names_its_key(tables, key):
    with pytest.raises(ScenarioError, match=key.replace("[", r"\[").replace("]", r"\]")):
        from_tables(tables, "test.toml")


def test_bad_guidance_names_its_key(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('preset = "paper"\n[guidance]\nmargin_m = -1.0\n')
    with pytest.raises(ScenarioError, match=r"guidance\.margin_m"):
        load_scenario(path)
    path.write_text('preset = "paper"\n[guidance]\navoid = 1\n')
    with pytest.raises(ScenarioError, match=r"guidance\.avoid"):
        load_scenario(path)


def test_example_scenarios_load():
    for name in ("harbour_gap", "ramming_pier", "crossing_boat", "head_on_boat"):
        osc = load_scenario(SCENARIOS / f"{name}.toml")
        assert osc.obstacles and osc.plant.kind == "mujoco"
    crossing = load_scenario(SCENARIOS / "crossing_boat.toml")
    assert crossing.obstacles[0].moving and crossing.obstacles[0].center_at(10.0) == (20.0, -11.5)


# --- composition and contact physics ------------------------------------------------------------


def test_composed_model_has_contacts_and_hull_collision_geoms_following_the_visual_hull():
    obstacles = from_tables([{"kind": "box", "center": [8, 0], "size": [2, 6]},
                             {"center": [0, 10], "radius": 1.0, "velocity": [0.5, 0.0]}])
    from dm_control import mjcf

    physics = mjcf.Physics.from_mjcf_model(compose_scene(obstacles))
    m = physics.model.ptr
    assert not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    gid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n)  # noqa: E731
    for visual, collision in (("hull_mid", "hull_collision_mid"), ("hull_bow", "hull_collision_bow")):
        v, c = gid(visual), gid(collision)
        assert m.geom_type[v] == m.geom_type[c]
        np.testing.assert_allclose(m.geom_size[c][:2], m.geom_size[v][:2])
        np.testing.assert_allclose(m.geom_pos[c][:2], m.geom_pos[v][:2])
        assert m.geom_contype[c] & m.geom_conaffinity[gid("obstacle_obstacle_0")]
        assert m.geom_contype[v] == 0 and m.geom_conaffinity[v] == 0
    assert m.nmocap == 1
    # the hull radius is the farthest collision-geom point in the water plane: box corner (-0.98, 0.38)
    assert HULL_RADIUS == pytest.approx(math.hypot(0.98, 0.38), abs=1e-9)


def test_contact_holds_the_hull_against_a_pier_in_static_equilibrium():
    """Constant thrust F into a pier: the hull stops at the face and the contact normal force equals
    F plus the hull's hydrodynamic surge force at rest (usv_mj.physics.ship), i.e. Newton at rest."""
    pier = from_tables([{"kind": "box", "center": [8, 0], "size": [2, 6]}])
    force = 100.0
    with HarbourPlant(SHIP, CALM, pier) as plant:
        plant.reset((5.5, 0.0, 0.0), (0.0, 0.0, 0.0))
        monitor = MuJoCoClearance(plant)
        for _ in range(6000):
            plant.step(force, 0.0)
        clearance = monitor.update(0.0)
        state = plant.state
        f_h = hydrodynamic_force(SHIP.as_array(), CALM.as_array(), plant.time, state[:3], np.zeros(3))
        assert monitor.in_contact[0]
        assert abs(state[3]) < 1e-4 and abs(state[5]) < 1e-3
        assert monitor.normal_force[0] == pytest.approx(force + f_h[0], rel=2e-3)
        # the bow (x = +1.0 m in the body frame) is at the pier face x = 7 m, within a millimetre
        assert state[0] + 1.0 == pytest.approx(7.0, abs=1e-3)
        assert -1e-3 < clearance[0] <= 1e-6


def test_side_impact_impulse_changes_the_momentum_of_the_full_mass_including_added_mass():
    """A hull drifting sideways at 0.5 m/s into a wall: the contact impulse plus the hydrodynamic
    impulse (usv_mj.physics.ship) equals M (nu_1 - nu_0) with the paper's full M (m22 = 191.75 kg, of which
    the callback carries the added mass); a solver that saw only MuJoCo's rigid 141.85 kg would be
    26 % off."""
    wall = from_tables([{"kind": "box", "center": [0.0, 3.0], "size": [10.0, 2.0]}])   # face at y = 2
    with HarbourPlant(SHIP, CALM, wall) as plant:
        plant.reset((0.0, 1.55, 0.0), (0.0, 0.5, 0.0))
        monitor = MuJoCoClearance(plant)
        nu0 = plant.state[3:].copy()
        contact_impulse = 0.0
        hydro_impulse = np.zeros(3)
        dt = plant.control_period
        for _ in range(400):
            s = plant.state
            f0 = hydrodynamic_force(SHIP.as_array(), CALM.as_array(), plant.time, s[:3], s[3:])
            plant.step(0.0, 0.0)
            s = plant.state
            f1 = hydrodynamic_force(SHIP.as_array(), CALM.as_array(), plant.time, s[:3], s[3:])
            hydro_impulse += 0.5 * (f0 + f1) * dt
            monitor.update(plant.time)
            contact_impulse += monitor.normal_force[0] * dt
        nu1 = plant.state[3:]
        assert not monitor.in_contact[0] and nu1[1] < 0.0          # it hit and came off the wall
        momentum_change = SHIP.mass_matrix() @ (nu1 - nu0)
        assert contact_impulse > 50.0
        assert momentum_change[1] == pytest.approx(-contact_impulse + hydro_impulse[1], rel=0.01)


# --- clearance ----------------------------------------------------------------------------------


def test_clearance_closed_forms_mujoco_and_geometry():
    """Hull at the origin heading +x: bow tip at x = 1.0, sides at y = +-0.38, stern at x = -0.98."""
    obstacles = from_tables([
        {"center": [5.0, 0.0], "radius": 1.0},                        # 5 - 1 - 1.0 = 3.0
        {"kind": "box", "center": [0.0, 5.0], "size": [2.0, 2.0]},    # 4 - 0.38 = 3.62
        {"kind": "box", "center": [-4.0, -0.2], "size": [2.0, 8.0]},  # -0.98 - (-3) = 2.02
    ])
    expected = [3.0, 3.62, 2.02]
    geometric = GeometricClearance(obstacles)
    np.testing.assert_allclose(geometric.update(0.0, np.zeros(6)), expected, atol=1e-9)
    with HarbourPlant(SHIP, CALM, obstacles) as plant:
        plant.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        np.testing.assert_allclose(MuJoCoClearance(plant).update(0.0), expected, atol=1e-5)


def test_geometric_kernels_match_shapely_and_mujoco_at_random_poses():
    obstacles = from_tables([{"kind": "box", "center": [6, 1], "size": [3, 5], "yaw": 0.4},
                             {"center": [-3, 3], "radius": 0.7},
                             {"kind": "box", "center": [0, -6], "size": [4, 1.6], "velocity": [0.2, 0.1]}])
    numba_kernels = GeometricClearance(obstacles, exact_within=math.inf)
    bounded = GeometricClearance(obstacles, exact_within=3.0)
    reference = GeometricClearance(obstacles, method="shapely")
    rng = np.random.default_rng(3)
    with HarbourPlant(SHIP, CALM, obstacles) as plant:
        mj = MuJoCoClearance(plant, exact_within=math.inf)
        mj_bounded = MuJoCoClearance(plant, exact_within=3.0)
        for _ in range(150):
            x = np.r_[rng.uniform(-5, 9), rng.uniform(-8, 6), rng.uniform(-4, 4), 0, 0, 0]
            t = rng.uniform(0, 10)
            a = numba_kernels.update(t, x).copy()
            b = reference.update(t, x).copy()
            sep = b > 1e-9
            np.testing.assert_allclose(a[sep], b[sep], atol=1e-9)
            assert np.all((a <= 1e-9) == (b <= 1e-9))
            plant.reset(x[:3], (0, 0, 0))
            plant.move_obstacles(t)
            c = mj.update(t).copy()
            # far obstacles: a true lower bound, exact where the bound is under exact_within
            for approx, exact in ((bounded.update(t, x), a), (mj_bounded.update(t), c)):
                assert np.all(approx <= exact + 1e-9)
                near = approx <= 3.0
                np.testing.assert_allclose(approx[near], exact[near], atol=1e-9)
            # polygonal ellipse (0.7 mm at most) and MuJoCo's convex solver tolerance
            sep = c > 0.01
            np.testing.assert_allclose(a[sep], c[sep], atol=2e-3)


def _clearance_on_the_bindings(monitor):
    """MuJoCoClearance.update (but the contacts) as written on the Python bindings: the reference
    of its native kernel. (clearance, exact, witness rows of the exact entries)."""
    m, d = monitor.model, monitor.data
    mujoco.mj_kinematics(m, d)
    n = len(monitor.obstacle_geoms)
    clearance, exact, witness, fromto = np.full(n, np.inf), np.ones(n, dtype=bool), np.zeros((n, 6)), np.zeros(6)
    if math.isfinite(monitor.exact_within) and n >= monitor.PREFILTER_FROM:
        rel = d.geom_xpos[monitor.obstacle_geoms, :2] - d.qpos[:2]
        lower = np.sqrt(rel[:, 0] ** 2 + rel[:, 1] ** 2) - monitor._bound
        exact = lower < monitor.exact_within
        clearance[:] = lower
    for i in np.flatnonzero(exact):
        best = math.inf
        for hg in monitor.hull_geoms:
            dist = mujoco.mj_geomDistance(m, d, hg, monitor.obstacle_geoms[i], monitor.distmax, fromto)
            if dist < best:
                best = dist
                witness[i] = fromto
        clearance[i] = best
    return clearance, exact, witness[exact]


@pytest.mark.parametrize("exact_within", [math.inf, 3.0])
def test_native_mujoco_clearance_is_the_bindings_bit_for_bit(exact_within):
    """The native update (mj_kinematics and mj_geomDistance called from compiled code, the
    bounding-circle prefilter of 8 or more obstacles) gives exactly what the bindings give."""
    tables = [{"kind": "box", "center": [6, 1], "size": [3, 5], "yaw": 0.4}, {"center": [-3, 3], "radius": 0.7},
              {"kind": "box", "center": [0, -6], "size": [4, 1.6], "velocity": [0.2, 0.1]}]
    tables += [{"center": [-8.0 + 3.0 * i, 8.0 - (i % 3)], "radius": 0.4 + 0.1 * i} for i in range(6)]
    rng = np.random.default_rng(5)
    for n in (3, len(tables)):  # without and with the prefilter
        with HarbourPlant(SHIP, CALM, from_tables(tables[:n])) as plant:
            monitor = MuJoCoClearance(plant, exact_within=exact_within)
            assert (n >= monitor.PREFILTER_FROM) == (n == len(tables))
            bounded = 0
            for _ in range(60):
                plant.reset((rng.uniform(-8, 9), rng.uniform(-8, 8), rng.uniform(-4, 4)), (0, 0, 0))
                plant.move_obstacles(rng.uniform(0, 10))
                c, exact, witness = _clearance_on_the_bindings(monitor)
                native = monitor.update(0.0).copy()
                assert np.array_equal(native, c) and np.array_equal(monitor.exact, exact)
                assert np.array_equal(monitor.witness[exact], witness)
                bounded += int(np.sum(~exact))
            # the prefilter left some far obstacles to their bound exactly when it is on
            assert (bounded > 0) == (math.isfinite(exact_within) and n >= monitor.PREFILTER_FROM)


def test_min_only_clearance_keeps_the_minimum_its_index_and_the_contact_test():
    """The branch and bound of the harbor task (kernel_args(min_only=True)): the summary (contact,
    first argmin, minimum) is the full update's bit for bit, measured entries are exact, skipped
    ones keep a true lower bound above the minimum; poses near and inside obstacles included."""
    from usv_mj.envs.native import clearance_summary
    from usv_mj.obstacles.clearance import mujoco_clearance_kernel

    tables = [{"kind": "box", "center": [6, 1], "size": [3, 5], "yaw": 0.4}, {"center": [-3, 3], "radius": 0.7},
              {"kind": "box", "center": [0, -6], "size": [4, 1.6], "velocity": [0.2, 0.1]}]
    tables += [{"center": [-8.0 + 3.0 * i, 8.0 - (i % 3)], "radius": 0.4 + 0.1 * i} for i in range(6)]
    rng = np.random.default_rng(7)
    for n, exact_within in ((3, 10.0), (6, 10.0), (len(tables), 10.0), (len(tables), math.inf)):
        with HarbourPlant(SHIP, CALM, from_tables(tables[:n])) as plant:
            monitor = MuJoCoClearance(plant, exact_within=exact_within)
            skipped = contacts = 0
            for _ in range(80):
                plant.reset((rng.uniform(-8, 9), rng.uniform(-8, 8), rng.uniform(-4, 4)), (0, 0, 0))
                plant.move_obstacles(rng.uniform(0, 10))
                full = monitor.update(0.0).copy()
                full_exact = monitor.exact.copy()
                mujoco_clearance_kernel(*monitor.kernel_args(min_only=True))
                c = monitor.clearance
                no_contact = np.zeros(n, dtype=bool)
                assert clearance_summary(c, no_contact) == clearance_summary(full, no_contact)
                assert np.array_equal(c[monitor.exact], full[monitor.exact])
                assert np.all(monitor.exact <= full_exact)
                far = full_exact & ~monitor.exact
                assert np.all(c[far] <= full[far]) and np.all(c[far] > np.min(full))
                skipped += int(np.sum(far))
                contacts += int(np.min(full) <= 0.0)
            assert skipped > 0 and contacts > 0


# --- planner ------------------------------------------------------------------------------------


def _exact_distances(obstacles, positions):
    """Shapely distances, circles exactly: |p - c| - r via the distance to the centre point."""
    pts = shapely.points(positions)
    out = []
    for o in obstacles:
        if o.kind == "circle":
            out.append(shapely.distance(shapely.Point(*o.center), pts) - o.radius)
        else:
            out.append(shapely.distance(o.shape(0.0), pts))
    return np.stack(out, axis=1)


def test_harbour_plan_keeps_clear_and_is_a_smooth_unicycle_reference():
    osc = load_scenario(SCENARIOS / "harbour_gap.toml")
    plan = make_plan(osc)
    sc = osc
    t = np.arange(0.0, sc.duration, 0.05)
    ref = plan.reference.sample(t)
    dist = _exact_distances(osc.obstacles, ref[:, :2])
    rho_inf = sc.funnel.rho_xy[1]
    assert dist.min() >= HULL_RADIUS + rho_inf                      # the requirement
    envelope = SafetyEnvelope.from_scenario(sc, osc.guidance.margin_m)
    assert np.all(dist >= envelope.required(t)[:, None] - 1e-9)     # the full property G(t) + margin
    # the path goes through the gap between the piers (x = 10..18, |y| < 4), not around them
    in_gap = (ref[:, 0] > 10.0) & (ref[:, 0] < 18.0)
    assert in_gap.any() and np.all(np.abs(ref[in_gap, 1]) < 4.0)
    # ... and around the buoy that sits on the straight line
    assert plan.polyline.shape[0] > 2
    # unicycle consistency: x_d_dot = u cos psi_d is the derivative of x_d; r_d of psi_d. Trapezoid
    # rule on a 0.01 s grid: its error is at most dt * (jump of the slope) / 8, the slope of r_d
    # jumping by at most 2 max_yaw_accel, of x_d_dot by at most 2 u |r_d|max
    g = osc.guidance
    dt = 0.01
    ref = plan.reference.sample(np.arange(0.0, sc.duration, dt))
    u = sc.trajectory.speed
    tol_xy = dt * 2 * u * g.max_yaw_rate / 8 + 1e-6
    np.testing.assert_allclose(np.diff(ref[:, 0]) / dt, 0.5 * (ref[1:, 3] + ref[:-1, 3]), atol=tol_xy)
    np.testing.assert_allclose(np.diff(ref[:, 1]) / dt, 0.5 * (ref[1:, 4] + ref[:-1, 4]), atol=tol_xy)
    np.testing.assert_allclose(np.diff(ref[:, 2]) / dt, 0.5 * (ref[1:, 5] + ref[:-1, 5]),
                               atol=dt * 2 * g.max_yaw_accel / 8 + 1e-9)
    # bounded r_d and r_d_dot
    assert np.max(np.abs(ref[:, 5])) <= g.max_yaw_rate + 1e-9
    assert np.max(np.abs(np.diff(ref[:, 5]) / dt)) <= g.max_yaw_accel * 1.01
    assert ref[0, 0] == 0.0 and ref[0, 1] == 0.0


def test_paper_funnel_closes_the_harbour():
    """rho_0 = 18 m: G(0) = 26.6 m, so the start itself lies inside the inflated piers."""
    osc = load_scenario(SCENARIOS / "harbour_gap.toml", overrides={"funnel": {"rho_xy": [18.0, 2.0],
                                                                                          "rate": 0.05}})
    with pytest.raises(PlanningError, match="inside an inflated obstacle"):
        make_plan(osc)


# --- closed loops on the MuJoCo plant -----------------------------------------------------------


def _reference_distance_slack(run, osc):
    r = run.record
    t = r["t"]
    pos = np.c_[r["x_d"], r["y_d"]]
    dist = obstacle_distances(osc.obstacles, pos, t)
    envelope = SafetyEnvelope.from_scenario(osc, osc.guidance.margin_m)
    return dist, envelope


def test_harbour_closed_loop_keeps_clear_on_mujoco():
    osc = load_scenario(SCENARIOS / "harbour_gap.toml")
    run = _run_through_build(osc)
    r = run.record
    summary = run.log.summary()
    assert r.status == "completed"
    assert summary["contacts"] == 0 and summary["min_clearance_m"] > 0
    z = np.stack([r["z1"], r["z2"]])
    inside = np.all(np.abs(z) < 1.0, axis=0)
    assert inside.all()
    # the safety bound row by row, with MuJoCo's distances: clearance > dist(p_d, O) - G(t)
    dist, envelope = _reference_distance_slack(run, osc)
    bound = dist - envelope.guaranteed_radius(r["t"])[:, None]
    clearance = run.log.clearance[: r.n_rows]
    assert np.all(clearance[inside] >= bound[inside] - 1e-6)
    assert summary["min_clearance_m"] >= osc.guidance.margin_m
    assert r.metadata["obstacles"]["min_clearance_m"] == summary["min_clearance_m"]


def test_ramming_a_pier_is_stopped_by_contact_and_stays_finite():
    osc = load_scenario(SCENARIOS / "ramming_pier.toml")
    run = _run_through_build(osc)
    r = run.record
    assert r.status in ("completed", "diverged")        # a recorded stop at worst, never an exception
    contacts = [e for e in r.events if e.kind == "contact"]
    assert contacts and contacts[0].values["obstacle"] == "pier" and contacts[0].values["normal_force_N"] > 0
    assert run.log.summary()["contacts"] >= 1
    state = np.c_[r["x"], r["y"], r["psi"], r["u"], r["v"], r["r"]]
    assert np.all(np.isfinite(state))
    # the pier face is x = 18 m; the hull's farthest point ahead of its origin is 1.0 m (the bow),
    # so the origin never gets past 17 m by more than the contact's softness
    assert np.max(r["x"]) < 17.0 + 0.02
    assert run.log.clearance[: r.n_rows].min() > -0.02
    assert np.max(run.log.normal_force) > 1000.0          # the PPC law pushes hard


def test_ramming_on_the_analytic_plant_records_a_collision_and_says_so():
    osc = load_scenario(SCENARIOS / "ramming_pier.toml", overrides={"duration": 32.0})
    run = _run_through_build(osc, plant_kind="analytic")
    kinds = [e.kind for e in run.record.events]
    assert "collision" in kinds and kinds.count("note") == 1
    assert run.log.summary()["contact_physics"] is False
    assert run.log.summary()["min_clearance_m"] < 0                # passes through: no contact physics


def test_crossing_boat_is_avoided_by_retiming_with_replan_events():
    osc = load_scenario(SCENARIOS / "crossing_boat.toml")
    # without re-timing the straight reference would come within less than the required distance
    plan = make_plan(osc)
    t = np.arange(0.0, osc.duration, 0.1)
    nominal = plan.reference.positions(t)
    envelope = SafetyEnvelope.from_scenario(osc, osc.guidance.margin_m)
    nominal_dist = obstacle_distances(osc.obstacles, nominal, t)[:, 0]
    assert np.min(nominal_dist - envelope.required(t)) < -1.0
    run = _run_through_build(osc)
    r = run.record
    replans = [e for e in r.events if e.kind == "replan"]
    assert replans and replans[0].values["obstacle"] == "crossing_boat"
    assert r.status == "completed"
    dist, envelope = _reference_distance_slack(run, osc)
    assert np.all(dist[:, 0] >= envelope.required(r["t"]) - 1e-6)    # the re-timed reference keeps clear
    summary = run.log.summary()
    assert summary["contacts"] == 0 and summary["min_clearance_m"] >= osc.guidance.margin_m
    # smooth re-timing: u_d continuous with |u_d_dot| <= max_accel
    du = np.diff(r["u_d"]) / osc.control_period
    assert np.max(np.abs(du)) <= osc.guidance.max_accel + 1e-9


def test_start_inside_an_obstacle_is_a_scenario_error():
    osc = load_scenario(SCENARIOS / "ramming_pier.toml", overrides={"initial": {"eta": [19.0, 0.0, 0.0]}})
    with pytest.raises(ScenarioError, match=r"initial\.eta .* inside obstacles\[0\] \(pier"):
        _run_through_build(osc, duration=1.0)


def _guidance_for(osc, **changes):
    from dataclasses import replace

    from usv_mj.references.planner import Guidance

    osc = replace(osc, guidance=replace(osc.guidance, **changes))
    plan = make_plan(osc)
    guidance = Guidance(plan.reference, osc.obstacles, plan.envelope, osc.guidance, osc.trajectory.speed)
    return osc, plan, guidance


def test_guidance_detects_the_crossing_boat_within_its_horizon_and_retimes_smoothly():
    """With a 15 s horizon the conflict (the boat crosses x = 20 m at about 33 s) is seen only on
    the way: the re-timing happens mid-run, and the reference it leaves keeps G(t) + margin."""
    osc, plan, guidance = _guidance_for(load_scenario(SCENARIOS / "crossing_boat.toml"), horizon=15.0)
    times = np.arange(0.0, 60.0, 0.01)
    ref = np.empty((len(times), N_REF))
    for k, t in enumerate(times):           # what the loop does: update, then evaluate
        guidance.update(float(t))
        ref[k] = plan.reference.evaluate(float(t))
    replans = [e for e in guidance.events if e.kind == "replan"]
    assert replans and replans[0].t > 5.0
    dist = obstacle_distances(osc.obstacles, ref[:, :2], times)[:, 0]
    assert np.all(dist >= plan.envelope.required(times) - 1e-6)
    du = np.diff(ref[:, 6]) / 0.01
    assert np.max(np.abs(du)) <= osc.guidance.max_accel + 1e-9 and np.min(ref[:, 6]) > 0


def test_head_on_boat_gets_a_starboard_detour_that_keeps_clear():
    """A boat coming along the path cannot be waited out: the guidance shifts the path to starboard
    (time-aware check over the horizon), continuing from the current heading and curvature."""
    osc = load_scenario(SCENARIOS / "crossing_boat.toml", overrides={
        "duration": 80.0,
        "obstacles": [{"kind": "box", "center": [40.0, 0.0], "size": [4.0, 1.6], "velocity": [-0.5, 0.0],
                       "name": "head_on"}]})
    from usv_mj.references.planner import Guidance

    plan = make_plan(osc)
    guidance = Guidance(plan.reference, osc.obstacles, plan.envelope, osc.guidance, osc.trajectory.speed,
                        goal=plan.polyline[-1])
    dt = 0.01
    times = np.arange(0.0, 80.0, dt)
    ref = np.empty((len(times), N_REF))
    for k, t in enumerate(times):
        guidance.update(float(t))
        ref[k] = plan.reference.evaluate(float(t))
    replans = [e for e in guidance.events if e.kind == "replan"]
    assert replans and replans[0].values["mode"] == "path" and replans[0].values["side"] == "starboard"
    dist = obstacle_distances(osc.obstacles, ref[:, :2], times)[:, 0]
    assert np.all(dist >= plan.envelope.required(times) - 1e-6)
    # the boat passes on the ship's port side (the ship is south of it, y < 0, when they are abeam)
    boat_x = 40.0 - 0.5 * times
    abeam = np.argmin(np.abs(ref[:, 0] - boat_x))
    assert ref[abeam, 1] < -2.0
    # continuous and bounded: no jump of the reference, |r_d| and |r_d_dot| within the limits
    g = osc.guidance
    assert np.max(np.hypot(np.diff(ref[:, 0]), np.diff(ref[:, 1]))) <= 0.6 * dt * 1.001
    assert np.max(np.abs(ref[:, 5])) <= g.max_yaw_rate + 1e-9
    assert np.max(np.abs(np.diff(ref[:, 5]) / dt)) <= g.max_yaw_accel * 1.01


@pytest.mark.parametrize("case", ["detour", "retiming"])
def test_guided_kernel_is_evaluate_bit_for_bit_after_the_guidance_changed_the_reference(case):
    """GuidedReference.kernel (its evaluate natively, usv_mj.core.kernels) on a reference the guidance
    changed during the run (a head-on boat: a switched path; the crossing boat: a re-timed speed
    profile): the same 7 numbers as evaluate at every 0.01 s, before the start and past the path's
    end included; kernel_key says when a kernel's snapshot is stale."""
    from usv_mj.references.planner import Guidance

    if case == "detour":
        osc = load_scenario(SCENARIOS / "crossing_boat.toml", overrides={
            "duration": 80.0, "obstacles": [{"kind": "box", "center": [40.0, 0.0], "size": [4.0, 1.6],
                                             "velocity": [-0.5, 0.0], "name": "head_on"}]})
    else:
        osc = load_scenario(SCENARIOS / "crossing_boat.toml")
    plan = make_plan(osc)
    reference = plan.reference
    guidance = Guidance(reference, osc.obstacles, plan.envelope, osc.guidance, osc.trajectory.speed,
                        goal=plan.polyline[-1])
    key0, kernel0 = reference.kernel_key(), reference.kernel()
    for t in np.arange(0.0, osc.duration, 0.01):
        guidance.update(float(t))
    assert any(e.kind == "replan" for e in guidance.events)
    assert reference.kernel_key() != key0
    kernel = reference.kernel()
    assert len(reference.segments) > 1 if case == "detour" else len(reference.profile.pieces) > 1
    times = np.arange(-0.5, osc.duration + 200.0, 0.01)
    path_end = max(seg[1] + seg[2].length for seg in reference.segments)
    assert reference.profile.state(times[-1])[0] > path_end  # past the end of the last path
    out = np.empty(N_REF)
    for t in times:
        want = reference.evaluate(float(t)).copy()
        got = kernel.fn(float(t), *kernel.args[:-1], out)
        assert np.array_equal(got, want), (t, got, want)
    stale = kernel0.fn(float(times[-1]), *kernel0.args[:-1], out)
    assert not np.array_equal(stale, reference.evaluate(float(times[-1])))


def test_an_obstacle_that_cannot_be_avoided_is_reported():
    """A 200 m wide barge sweeping down the path: neither re-timing nor a detour helps."""
    osc = load_scenario(SCENARIOS / "crossing_boat.toml", overrides={
        "obstacles": [{"kind": "box", "center": [30.0, 0.0], "size": [4.0, 200.0], "velocity": [-0.5, 0.0],
                       "name": "barge"}]})
    from usv_mj.references.planner import Guidance

    plan = make_plan(osc)
    guidance = Guidance(plan.reference, osc.obstacles, plan.envelope, osc.guidance, osc.trajectory.speed,
                        goal=plan.polyline[-1])
    assert guidance.update(0.0) is False
    assert [e.kind for e in guidance.events] == ["guidance_conflict"]
    assert guidance.events[0].values["obstacle"] == "barge"
