"""The hydrodynamics as a reusable piece (usv_mj.attach_hydrodynamics, `usv-mj scene`).

MuJoCo alone, on the exported scene with the documented attach call and plain ``mj_step``, must
give the project's own MuJoCo plant's trajectory (to 1e-9 m over 10 s); on ``models/usv.xml`` the
attach call must give the analytic plant's surge speed (an independent integration of Eq. 2), and
without it MuJoCo's vacuum speed tau t / m11.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from usv_mj.plants.mujoco_callback import N_USERDATA  # what the hydrodynamics need (103: the vessels' and fleets' layout, the packed d(t))

import usv_mj
from usv_mj import build, load_scenario
from usv_mj.cli.main import main
from usv_mj.plants import attach
from usv_mj.plants import mujoco_callback as mcb
from usv_mj.plants.attach import hull_body
from usv_mj.plants.mujoco_callback import MODELS_DIR

TAU = (100.0, 5.0)  # constant surge [N] and yaw moment [N m]
T_END = 10.0


def _plant_trajectory(scenario, eta0, nu0):
    """Positions (x, y) [m] every step of the project's MuJoCo plant (the one build)."""
    with build(scenario, plant_kind="mujoco", duration=T_END) as parts:
        plant = parts.plant
        plant.reset(eta0, nu0)
        n = int(round(T_END / scenario.control_period))
        out = np.empty((n, 3))
        for k in range(n):
            plant.step(*TAU)
            out[k] = plant.state[:3]
    return out


def _mujoco_alone(path, scenario, eta0, nu0):
    """The same with MuJoCo alone: MjModel.from_xml_path + attach + mj_step with ctrl held."""
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    water = usv_mj.attach_hydrodynamics(model, data, body="hull", scenario=scenario)
    c, s = math.cos(eta0[2]), math.sin(eta0[2])
    data.qpos[:3] = eta0
    data.qvel[:3] = (c * nu0[0] - s * nu0[1], s * nu0[0] + c * nu0[1], nu0[2])
    data.ctrl[:2] = TAU
    n = int(round(T_END / model.opt.timestep))
    out = np.empty((n, 3))
    for k in range(n):
        mujoco.mj_step(model, data)
        out[k] = data.qpos[:3]
    water.detach()
    return out


@pytest.mark.parametrize("source, overrides", [
    (None, None),                                                       # the paper scenario, calm
    (None, {"sea": {"preset": "moderate"}}),                             # waves, current, wind
    ("examples/scenarios/harbour_gap.toml", None),                      # the harbour, obstacles and contact on
])
def test_exported_scene_with_attach_is_the_plant(tmp_path, source, overrides):
    scenario = load_scenario(source, overrides=overrides)
    out = tmp_path / "scene.xml"
    args = ["scene", "--out", str(out)] + (["--scenario", source] if source else [])
    if overrides:
        args += ["--sea", overrides["sea"]["preset"]]
    assert main(args) == 0
    eta0, nu0 = (0.5, -0.3, 0.2), (0.4, 0.05, -0.02)
    ref = _plant_trajectory(scenario, eta0, nu0)
    got = _mujoco_alone(out, scenario, eta0, nu0)
    assert np.max(np.abs(ref[:, :2] - got[:, :2])) < 1e-9
    assert np.max(np.abs(ref[:, 2] - got[:, 2])) < 1e-9
    assert np.hypot(*(ref[-1, :2] - eta0[:2])) > 2.0  # it did move


def test_harbour_export_holds_the_obstacles(tmp_path):
    out = tmp_path / "harbour.xml"
    assert main(["scene", "--scenario", "examples/scenarios/harbour_gap.toml", "--out", str(out)]) == 0
    model = mujoco.MjModel.from_xml_path(str(out))
    scenario = load_scenario("examples/scenarios/harbour_gap.toml")
    for o in scenario.obstacles:
        name = o.name if o.name.startswith("obstacle_") else f"obstacle_{o.name}"
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) >= 0, name


def _surge_speed_after(model, data, seconds):
    data.ctrl[:] = (100.0, 0.0)
    while data.time < seconds - 0.5 * model.opt.timestep:
        mujoco.mj_step(model, data)
    return math.hypot(data.qvel[0], data.qvel[1])


def test_usv_xml_is_a_vacuum_until_attached():
    """100 N for 10 s: tau t / m11 = 7.05 m/s in MuJoCo alone; the analytic plant's speed with water."""
    path = f"{MODELS_DIR}/usv.xml"
    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)
    assert _surge_speed_after(model, data, 10.0) == pytest.approx(100.0 * 10.0 / 141.85, rel=1e-9)

    scenario = load_scenario(overrides={"disturbance": {"scale": 0.0}})
    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)
    water = usv_mj.attach_hydrodynamics(model, data, scenario=scenario)
    with_water = _surge_speed_after(model, data, 10.0)
    water.detach()
    with build(scenario, plant_kind="analytic", duration=10.0) as parts:
        for _ in range(10000):
            parts.plant.step(100.0, 0.0)
        analytic = math.hypot(*parts.plant.state[3:5])
    assert with_water == pytest.approx(analytic, abs=1e-6)
    assert 0.7 < with_water < 0.9  # the 0.83 m/s the README quotes


def test_detach_leaves_mujoco_alone():
    model = mujoco.MjModel.from_xml_path(f"{MODELS_DIR}/usv.xml")
    data = mujoco.MjData(model)
    usv_mj.attach_hydrodynamics(model, data).detach()
    assert _surge_speed_after(model, data, 1.0) == pytest.approx(100.0 / 141.85, rel=1e-9)


@pytest.mark.parametrize("xml, words", [
    (f'<mujoco><size nuserdata="{N_USERDATA}"/><worldbody><body name="boat"><joint type="slide" axis="1 0 0"/>'
     '<joint type="slide" axis="0 1 0"/><joint type="hinge" axis="0 0 1"/><geom size="0.5"/></body>'
     '</worldbody></mujoco>', "no body 'hull'"),
    ('<mujoco><worldbody><body name="hull"><joint type="slide" axis="1 0 0"/>'
     '<joint type="slide" axis="0 1 0"/><joint type="hinge" axis="0 0 1"/><geom size="0.5"/></body>'
     '</worldbody></mujoco>', f'nuserdata="{N_USERDATA}"'),
    (f'<mujoco><size nuserdata="{N_USERDATA}"/><worldbody><body name="hull"><freejoint/><geom size="0.5"/></body>'
     '</worldbody></mujoco>', "is 'simple' to MuJoCo"),
    (f'<mujoco><size nuserdata="{N_USERDATA}"/><worldbody><body name="buoy"><joint type="slide" axis="0 0 1"/>'
     '<geom size="0.5"/></body><body name="hull"><freejoint/><geom size="0.5" pos="0.1 0 0"/></body>'
     '</worldbody></mujoco>', "must be the model's first joint"),
    (f'<mujoco><size nuserdata="{N_USERDATA}"/><worldbody><body name="hull"><joint type="ball"/><geom size="0.5"/></body>'
     '</worldbody></mujoco>', "or one free joint"),
    (f'<mujoco><size nuserdata="{N_USERDATA}"/><worldbody><body name="hull"><joint type="slide" axis="0 1 0"/>'
     '<joint type="slide" axis="1 0 0"/><joint type="hinge" axis="0 0 1"/><geom size="0.5"/></body>'
     '</worldbody></mujoco>', "slide along x"),
    (f'<mujoco><size nuserdata="{N_USERDATA}"/><worldbody><body name="buoy"><joint type="slide" axis="0 0 1"/>'
     '<geom size="0.5"/></body><body name="hull"><joint type="slide" axis="1 0 0"/>'
     '<joint type="slide" axis="0 1 0"/><joint type="hinge" axis="0 0 1"/><geom size="0.5"/></body>'
     '</worldbody></mujoco>', "first three degrees of freedom"),
])
def test_unusable_models_are_named(xml, words):
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(ValueError, match="attach_hydrodynamics: ") as info:
        hull_body(model)
    assert words in str(info.value)


def test_other_bodies_after_the_hull_keep_their_own_physics():
    """A user's scene: the hull first, a free-falling ball after it; the hull still moves as the plant."""
    spec = mujoco.MjSpec.from_file(f"{MODELS_DIR}/usv.xml")
    ball = spec.worldbody.add_body(name="ball", pos=[5, 5, 3])
    ball.add_freejoint()
    ball.add_geom(size=[0.2, 0, 0], mass=1.0)
    spec.option.gravity = [0, 0, -9.81]
    spec.option.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
    model = spec.compile()
    data = mujoco.MjData(model)
    water = usv_mj.attach_hydrodynamics(model, data)
    data.ctrl[:] = TAU
    for _ in range(1000):
        mujoco.mj_step(model, data)
    water.detach()
    assert data.qpos[5] == pytest.approx(3.0 - 0.5 * 9.81 * 1.0, abs=1e-6)  # the ball fell freely
    scenario = load_scenario()
    with build(scenario, plant_kind="mujoco", duration=1.0) as parts:
        for _ in range(1000):
            parts.plant.step(*TAU)
        ref = parts.plant.state[:3]
    assert np.max(np.abs(data.qpos[:3] - ref)) < 1e-9


def test_run_log_attaches_the_scene_the_plant_ran(tmp_path):
    """The log's scene/main.xml, loaded by MuJoCo with the attach call, replays the logged run."""
    from usv_mj import simulate
    from usv_mj.outputs.log import RunLogWriter, read_run

    scenario = load_scenario("examples/scenarios/harbour_gap.toml", overrides={"duration": 2.0})
    with RunLogWriter(tmp_path / "run.mcap", scenario, background=False) as writer:
        record = simulate(scenario, sinks=[writer.sink("main")])
    log = read_run(tmp_path / "run.mcap")
    xml = log.attachments["scene/main.xml"].decode()
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.opt.timestep == scenario.control_period
    for o in scenario.obstacles:
        name = o.name if o.name.startswith("obstacle_") else f"obstacle_{o.name}"
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) >= 0
    # replay the logged thrust open loop in MuJoCo alone: the logged positions come back
    data = mujoco.MjData(model)
    water = usv_mj.attach_hydrodynamics(model, data, scenario=scenario)
    data.qpos[:3] = scenario.initial.eta
    assert np.allclose(scenario.initial.nu, 0.0)
    f_u, f_r, x = record["f_u"], record["f_r"], record["x"]
    for k in range(len(x) - 1):
        data.ctrl[:2] = (f_u[k], f_r[k])
        mujoco.mj_step(model, data)
    water.detach()
    assert abs(data.qpos[0] - x[-1]) < 1e-6


def test_an_environments_scene_outlives_its_close():
    """The harbor task's composed scene (obstacles, rangefinders) as MJCF text, kept after close()
    removes the plant's temporary copy: MuJoCo loads it with the same bodies, geoms and sensors."""
    import mujoco

    from usv_mj import envs

    env = envs.load("harbor")
    try:
        xml = env.scene_xml()
        model = env.physics.model
        counts = (model.nbody, model.ngeom, model.nsensor, model.nu)
    finally:
        env.close()
    again = mujoco.MjModel.from_xml_string(xml)
    assert (again.nbody, again.ngeom, again.nsensor, again.nu) == counts
    assert counts[1] > 3 and counts[2] > 0   # the harbour's obstacles and the rangefinder fan are in it


# --- a free body held to the plane ---------------------------------------------------------------

G = 9.81


def _free_hull_model(path, gravity=True):
    """The scene with the hull's three planar joints replaced by a free joint, and MuJoCo's gravity on
    (as in a user's scene): what the attach call must hold to the plane."""
    spec = mujoco.MjSpec.from_file(str(path))
    hull = spec.body("hull")
    for joint in list(hull.joints):
        spec.delete(joint)
    hull.add_freejoint()
    if gravity:
        spec.option.gravity = [0.0, 0.0, -G]
        spec.option.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
    return spec.compile()


def _tilt(q):
    """Angle [rad] between the body's z axis and world z, from the quaternion (w, x, y, z)."""
    w, x, y, z = q / np.linalg.norm(q)
    n0, n1, n2 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    return math.atan2(math.hypot(n0, n1), n2)


@pytest.mark.parametrize("overrides", [None, {"sea": {"preset": "moderate"}}], ids=["calm", "sea"])
def test_a_free_body_held_to_the_plane_follows_the_plant(tmp_path, overrides):
    """A free joint (gravity on) after the attach call: x, y and yaw are the project's plant's to
    1e-9 m / rad over 10 s. The hold lets a load F move a held dof by F / k at most (critically
    damped, no overshoot): the hull's weight m g / k_z in heave, its moment m g x_g / k_pitch in
    pitch, and those move the plane's motion only to second order, so the planar bound is the planar
    joints' own round-off."""
    scenario = load_scenario(None, overrides=overrides)
    out = tmp_path / "scene.xml"
    assert main(["scene", "--out", str(out)] + (["--sea", "moderate"] if overrides else [])) == 0
    eta0, nu0 = (0.5, -0.3, 0.2), (0.4, 0.05, -0.02)
    ref = _plant_trajectory(scenario, eta0, nu0)

    model = _free_hull_model(out)
    data = mujoco.MjData(model)
    water = usv_mj.attach_hydrodynamics(model, data, body="hull", scenario=scenario)
    assert water.free
    z0 = float(model.qpos0[2])
    c, s = math.cos(eta0[2]), math.sin(eta0[2])
    data.qpos[:7] = (eta0[0], eta0[1], z0, math.cos(eta0[2] / 2), 0.0, 0.0, math.sin(eta0[2] / 2))
    data.qvel[:6] = (c * nu0[0] - s * nu0[1], s * nu0[0] + c * nu0[1], 0.0, 0.0, 0.0, nu0[2])  # body-frame omega
    data.ctrl[:2] = TAU
    n = len(ref)
    got, heave, tilt = np.empty((n, 3)), np.empty(n), np.empty(n)
    for k in range(n):
        mujoco.mj_step(model, data)
        q = data.qpos
        got[k] = q[0], q[1], 2.0 * math.atan2(q[6], q[3])
        heave[k], tilt[k] = q[2] - z0, _tilt(q[3:7].copy())
    assert data.userdata[mcb.U_STATUS] == 0.0
    water.detach()
    assert np.max(np.abs(ref[:, :2] - got[:, :2])) < 1e-9
    assert np.max(np.abs(np.angle(np.exp(1j * (ref[:, 2] - got[:, 2]))))) < 1e-9
    assert np.hypot(*(ref[-1, :2] - eta0[:2])) > 2.0  # it did move

    # the hold, from its own parameters (m, x_g from the ship's rigid body)
    m, x_g = float(model.body_mass[water.body]), float(model.body_ipos[water.body][0])
    hold = attach.hold_parameters(model, water.body)
    w = 2 * math.pi / attach.HOLD_PERIOD_S
    assert hold[2] == pytest.approx((attach.HOLD_LOCK + 1) * m * w * w, rel=1e-12)
    sag, trim = m * G / hold[2], m * G * x_g / hold[8]
    assert 2e-13 < sag < 3e-13 and np.all(heave <= 0) and np.max(-heave) <= sag * (1 + 1e-6)
    assert np.max(tilt) <= trim * (1 + 1e-3) + 1e-16
    assert -heave[-1] == pytest.approx(sag, rel=1e-3)  # settled at the static deflection


def test_a_free_hull_released_off_the_plane_returns_as_a_critically_damped_oscillator():
    """Released 5 cm high and heeled 0.02 rad (no gravity, no thrust, no d(t)), heave and roll each
    follow e(t) = e0 (1 + w t) exp(-w t), w = 2 pi / HOLD_PERIOD_S, the closed form of
    e'' + 2 w e' + w^2 e = 0 from rest."""
    scenario = load_scenario(overrides={"disturbance": {"scale": 0.0}})
    model = _free_hull_model(f"{MODELS_DIR}/usv.xml", gravity=False)
    data = mujoco.MjData(model)
    water = usv_mj.attach_hydrodynamics(model, data, scenario=scenario)
    z0, e_z, e_roll = float(model.qpos0[2]), 0.05, 0.02
    data.qpos[:7] = (0.0, 0.0, z0 + e_z, math.cos(e_roll / 2), math.sin(e_roll / 2), 0.0, 0.0)
    w = 2 * math.pi / attach.HOLD_PERIOD_S
    worst = 0.0
    while data.time < 3.0 - 1e-9:
        mujoco.mj_step(model, data)
        closed = (1 + w * data.time) * math.exp(-w * data.time)
        q = data.qpos
        roll = 2 * math.atan2(q[4], q[3])
        worst = max(worst, abs(q[2] - z0 - e_z * closed) / e_z, abs(roll - e_roll * closed) / e_roll)
    water.detach()
    assert worst < 1e-6


def test_a_held_hull_has_the_planar_joints_inverse_weights():
    """MuJoCo scales a contact's softness by the bodies' inverse weights at qpos0 (mj_setConst): with the
    hold's lock they are the planar hull's, as MuJoCo itself computes them for the planar joints."""
    planar = mujoco.MjModel.from_xml_path(f"{MODELS_DIR}/usv.xml")
    usv_mj.attach_hydrodynamics(planar, mujoco.MjData(planar)).detach()
    free = _free_hull_model(f"{MODELS_DIR}/usv.xml")
    water = usv_mj.attach_hydrodynamics(free, mujoco.MjData(free))
    water.detach()
    body = water.body
    assert free.body_invweight0[body] == pytest.approx(planar.body_invweight0[body], rel=1e-9)


def test_the_readme_states_the_userdata_the_call_needs():
    """The README's nuserdata for a user's own model is the layout's N_USERDATA (it drifted once, as
    the packed hull grew): a model sized as the README says is accepted."""
    import re
    from pathlib import Path

    from usv_mj.plants.mujoco_callback import N_USERDATA

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    stated = [int(n) for n in re.findall(r'<size nuserdata="(\d+)"/>` or more', text)]
    assert stated == [N_USERDATA]
