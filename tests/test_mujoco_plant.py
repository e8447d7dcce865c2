"""The MuJoCo plant is the paper's ship (SPEC §1, issue 3).

References: the analytic M^-1(tau + d + Delta - C nu - D nu) of usv_mj.physics.ship (Eq. 2), closed-form
initial accelerations from the printed masses, and the analytic RK4 plant driven with the same
inputs.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from usv_mj.plants import mujoco_callback as mcb
from usv_mj.plants.analytic import AnalyticPlant
from usv_mj.plants.mujoco_callback import installed_callback
from usv_mj.plants.mujoco_plant import MuJoCoPlant
from usv_mj.physics.ship import PaperDisturbance, RigidBodySplit, ShipParams, body_acceleration

SHIP = ShipParams()
DIST = PaperDisturbance(scale=1e-3)  # ten times the paper preset: d(t) clearly matters


def switching_inputs(n: int, dt: float, seed: int = 1) -> np.ndarray:
    """A rich, switching input sequence: piecewise-constant levels held for random 0.05-3 s spans,
    plus a chirp, steps of both signs (surge -60..220 N, yaw -25..25 N m)."""
    rng = np.random.default_rng(seed)
    out = np.empty((n, 2))
    k = 0
    while k < n:
        span = int(rng.uniform(0.05, 3.0) / dt)
        out[k:k + span, 0] = rng.uniform(-60.0, 220.0)
        out[k:k + span, 1] = rng.uniform(-25.0, 25.0)
        k += span
    t = np.arange(n) * dt
    out[:, 0] += 20.0 * np.sin(0.02 * t * t / (1.0 + 0.01 * t))
    out[:, 1] += 5.0 * np.sign(np.sin(1.3 * t))
    return out


def run_both(inputs, eta0=(2.0, -3.0, 0.3), nu0=(0.1, 0.0, 0.0), dt=1e-3, substeps=1, split=RigidBodySplit(),
             ship=SHIP, dist=DIST, callback="native", native_step=True):
    with MuJoCoPlant(ship, dist, dt, substeps, split=split, callback=callback, native_step=native_step) as pm:
        pa = AnalyticPlant(ship, dist, dt, substeps)
        pm.reset(eta0, nu0)
        pa.reset(eta0, nu0)
        xm = np.empty((len(inputs), 6))
        xa = np.empty((len(inputs), 6))
        for k, (tu, tr) in enumerate(inputs):
            pm.step(tu, tr)
            pa.step(tu, tr)
            xm[k] = pm.state
            xa[k] = pa.state
        assert pm.time == pytest.approx(pa.time, abs=1e-12)
    return xm, xa


@pytest.mark.parametrize("callback", ["native", "python"])
@pytest.mark.parametrize("fraction", [0.0, 0.3])
def test_body_acceleration_equals_analytic(callback, fraction):
    rng = np.random.default_rng(42)
    p, dp = SHIP.as_array(), DIST.as_array()
    with MuJoCoPlant(SHIP, DIST, split=RigidBodySplit(fraction), callback=callback) as plant:
        for _ in range(200):
            eta = rng.uniform(-50, 50, 3)
            eta[2] = rng.uniform(-10, 10)
            nu = rng.uniform(-2.5, 2.5, 3)
            nu[2] = rng.uniform(-1.0, 1.0)
            t = rng.uniform(0, 300)
            tu, tr = rng.uniform(-500, 500), rng.uniform(-100, 100)
            plant.reset(eta, nu, t)
            got = plant.body_acceleration(tu, tr)
            want = body_acceleration(p, dp, t, eta, nu, tu, tr)
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(plant.state, np.concatenate([eta, nu]), rtol=1e-12, atol=1e-12)


def test_initial_acceleration_closed_form_and_body_frame_gear():
    """At rest with no disturbance or uncertainty, the thrust alone accelerates the hull:
    u_dot = tau_u/m11 and (v_dot, r_dot) = [[m22, m23], [m23, m33]]^-1 (0, tau_r), in the body frame.
    With psi = 90 deg a surge force moves the hull along world +y."""
    ship = ShipParams(uncertainty_scale=0.0)
    quiet = PaperDisturbance(scale=0.0)
    m11, m22, m23, m33 = 141.85, 191.75, 5.7, 15.6
    det = m22 * m33 - m23 * m23
    with MuJoCoPlant(ship, quiet) as plant:
        plant.reset((1.0, 2.0, math.pi / 2), (0.0, 0.0, 0.0))
        acc = plant.body_acceleration(100.0, 10.0)
        np.testing.assert_allclose(acc, [100.0 / m11, -m23 * 10.0 / det, m22 * 10.0 / det], rtol=1e-12, atol=1e-14)
        plant.reset((1.0, 2.0, math.pi / 2), (0.0, 0.0, 0.0))
        for _ in range(100):  # 0.1 s of 100 N surge
            plant.step(100.0, 0.0)
        x, y, psi, u, v, r = plant.state
        assert abs(x - 1.0) < 1e-12 and abs(psi - math.pi / 2) < 1e-12
        # along world y, with the linear surge damping d = 45.6 in closed form (the quadratic
        # terms 67.26 |u| u + 10 u^3 are under 0.3 % of the thrust over these 0.1 s)
        f, dlin, t = 100.0, 45.6, 0.1
        u_lin = f / dlin * (1 - math.exp(-dlin * t / m11))
        y_lin = f / dlin * (t - m11 / dlin * (1 - math.exp(-dlin * t / m11)))
        assert (y - 2.0) == pytest.approx(y_lin, rel=2e-3)
        assert u == pytest.approx(u_lin, rel=3e-3)
        assert abs(v) < 1e-12 and abs(r) < 1e-12


def test_open_loop_short_substeps_and_split():
    inputs = switching_inputs(20_000, 1e-3)
    xm, xa = run_both(inputs)
    assert np.max(np.abs(xm - xa)) < 1e-9
    xm4, xa4 = run_both(inputs[:5000], substeps=4)
    assert np.max(np.abs(xm4 - xa4)) < 1e-10
    # a different split of rigid and added mass gives the same motion
    xs, _ = run_both(inputs, split=RigidBodySplit(added_mass_fraction_surge=0.3))
    assert np.max(np.abs(xs[:, :2] - xm[:, :2])) < 1e-9
    assert np.max(np.abs(xs - xa)) < 1e-9


def test_python_callback_matches_native():
    inputs = switching_inputs(3000, 1e-3, seed=5)
    xn, xa = run_both(inputs)
    xp, _ = run_both(inputs, callback="python")
    assert np.max(np.abs(xn - xp)) < 1e-12
    # stepping from compiled code is the same computation as through the bindings
    xb, _ = run_both(inputs, native_step=False)
    np.testing.assert_array_equal(xb, xn)
    xb4, _ = run_both(inputs[:500], substeps=3, native_step=False)
    xn4, _ = run_both(inputs[:500], substeps=3)
    np.testing.assert_array_equal(xb4, xn4)
    assert np.max(np.abs(xp - xa)) < 1e-10


@pytest.mark.slow
def test_open_loop_300_s_matches_analytic():
    """Issue 3: 300 s at dt = 1 ms with identical switching inputs, position difference < 1e-6 m."""
    inputs = switching_inputs(300_000, 1e-3, seed=3)
    xm, xa = run_both(inputs)
    pos = np.max(np.hypot(xm[:, 0] - xa[:, 0], xm[:, 1] - xa[:, 1]))
    assert pos < 1e-6
    assert np.max(np.abs(xm[:, 2] - xa[:, 2])) < 1e-6
    # the run really went somewhere and turned (not a trivial trajectory)
    path = np.sum(np.hypot(np.diff(xm[:, 0]), np.diff(xm[:, 1])))
    assert path > 50.0 and np.ptp(xm[:, 2]) > 1.0 and np.ptp(xm[:, 3]) > 0.5


def test_two_plants_with_different_parameters_do_not_disturb_each_other():
    heavy = ShipParams(m11=300.0, m22=400.0, m33=40.0)
    other_dist = PaperDisturbance(scale=5e-3)
    inputs = switching_inputs(4000, 1e-3, seed=7)
    with MuJoCoPlant(SHIP, DIST) as a, MuJoCoPlant(heavy, other_dist, callback="python") as b:
        ra, rb = AnalyticPlant(SHIP, DIST), AnalyticPlant(heavy, other_dist)
        for p in (a, b, ra, rb):
            p.reset((0.0, 0.0, 0.5), (0.5, 0.0, 0.0))
        for tu, tr in inputs:  # interleaved steps
            a.step(tu, tr)
            b.step(tu, tr)
            ra.step(tu, tr)
            rb.step(tu, tr)
        # same ship to RK4 discretization level (the plants integrate different coordinates);
        # a clobbered parameter set would be off by metres
        assert np.max(np.abs(a.state - ra.state)) < 1e-8
        assert np.max(np.abs(b.state - rb.state)) < 1e-8
        assert np.max(np.abs(a.state - b.state)) > 1e-2  # they really differ
    assert installed_callback() is None


def test_python_callback_error_surfaces_and_plant_recovers(monkeypatch):
    with MuJoCoPlant(SHIP, DIST, callback="python") as plant:
        plant.reset((0, 0, 0), (0.5, 0, 0))
        plant.step(50.0, 0.0)

        def broken(*args):
            raise ZeroDivisionError("injected failure")

        monkeypatch.setattr(mcb, "passive_terms", broken)
        with pytest.raises(mcb.HydrodynamicCallbackError, match="injected failure") as info:
            plant.step(50.0, 0.0)
        assert "t = 0.001" in str(info.value)
        assert isinstance(info.value.__cause__, ZeroDivisionError)
        monkeypatch.undo()
        # the process survived and the plant works again after a reset
        plant.reset((0, 0, 0), (0.5, 0, 0))
        plant.step(50.0, 0.0)
        assert np.all(np.isfinite(plant.state))


def test_native_callback_error_surfaces():
    with MuJoCoPlant(SHIP, DIST) as plant:
        plant.reset((0, 0, 0), (0.5, 0, 0))
        plant.data.userdata[mcb.U_P + 4] = np.nan  # corrupt d11: the force comes out NaN
        with pytest.raises(mcb.HydrodynamicCallbackError, match="non-finite"):
            plant.step(50.0, 0.0)
        plant.reset((0, 0, 0), (0.5, 0, 0))  # reset rewrites the parameters
        plant.step(50.0, 0.0)
        assert np.all(np.isfinite(plant.state))
        # MuJoCo's own NaN guard is reported too, not passed on silently
        plant.data.qvel[0] = np.inf
        with pytest.raises(mcb.HydrodynamicCallbackError, match="qvel"):
            plant.step(50.0, 0.0)


def test_close_removes_callback_and_unmarks_data():
    before = mujoco.get_mjcb_passive()
    plant = MuJoCoPlant(SHIP, DIST)
    assert installed_callback() == "native"
    plant.reset((0, 0, 0), (1.0, 0, 0))
    m, d = plant.model, plant.data
    plant.close()
    plant.close()  # idempotent
    assert installed_callback() is None
    assert mujoco.get_mjcb_passive() is before
    with pytest.raises(RuntimeError, match="closed"):
        plant.reset((0, 0, 0), (0, 0, 0))
    # a marked mjData is ignored after close even if some other plant reinstalls the callback
    with MuJoCoPlant(SHIP, DIST):
        d.ctrl[:] = 0.0
        for _ in range(100):
            mujoco.mj_step(m, d)
        # no hydrodynamics: the rigid body coasts at constant speed
        assert d.qvel[0] == pytest.approx(1.0, abs=1e-12)


def test_scene_model_and_bad_inputs():
    with MuJoCoPlant(SHIP, DIST, model_path=mcb.MODELS_DIR + "/scene.xml") as plant:
        plant.reset((2, -3, 0), (0, 0, 0))
        plant.step(100.0, 1.0)
        assert plant.state[3] > 0
    with pytest.raises(ValueError, match="control_period"):
        MuJoCoPlant(SHIP, DIST, control_period=0.0)
    with pytest.raises(ValueError, match="substeps"):
        MuJoCoPlant(SHIP, DIST, substeps=0)
    with pytest.raises(FileNotFoundError, match="nowhere.xml"):
        MuJoCoPlant(SHIP, DIST, model_path="/nowhere.xml")
    with MuJoCoPlant(SHIP, DIST) as plant:
        with pytest.raises(ValueError, match="eta0"):
            plant.reset((0, np.nan, 0), (0, 0, 0))
    assert installed_callback() is None
