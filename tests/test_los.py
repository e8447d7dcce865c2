"""The LOS controller (controllers/los.py): its steering law against the closed form, the heading
loop's steady state, cross-track convergence on both plants, and the command line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.builder import make_controller
from usv_mj.cli.main import main
from usv_mj.core.errors import ScenarioError

DELTA = 3.0


def _scenario(**over):
    base = {"controller": {"kind": "los"}, "baseline": {"enabled": False}, "plant": {"kind": "analytic"}}
    for key, value in over.items():
        base[key] = {**base.get(key, {}), **value} if isinstance(value, dict) else value
    return load_scenario(preset="paper", overrides=base)


def _path_errors(rec):
    """(x_e, y_e) from the record's own columns: the path frame of the reference velocity."""
    pi_p = np.arctan2(rec["y_d_dot"], rec["x_d_dot"])
    dx, dy = rec["x"] - rec["x_d"], rec["y"] - rec["y_d"]
    return np.cos(pi_p) * dx + np.sin(pi_p) * dy, -np.sin(pi_p) * dx + np.cos(pi_p) * dy


@pytest.mark.parametrize("heading_deg, along, cross", [(0.0, 0.0, 2.0), (30.0, 1.5, -4.0), (135.0, -2.0, 0.5),
                                                        (-100.0, 0.0, 25.0)])
def test_steering_law_is_the_lookahead_closed_form(heading_deg, along, cross):
    """A ship placed at (along, cross) in the path frame of a reference moving at heading_deg, with no
    sway (no crab angle): y_e, x_e and chi_d = pi_p - atan(y_e / Delta) (K_p = 1/Delta)."""
    ctrl = make_controller(_scenario(controller={"lookahead": DELTA}))
    ctrl.reset()
    h = math.radians(heading_deg)
    xd, yd, u = 10.0, -4.0, 0.6
    pos = (xd + along * math.cos(h) - cross * math.sin(h), yd + along * math.sin(h) + cross * math.cos(h))
    state = np.array([pos[0], pos[1], h + 0.2, 0.5, 0.0, 0.0])
    ref = np.array([xd, yd, h, u * math.cos(h), u * math.sin(h), 0.0, u])
    _, _, diag = ctrl(0.0, state, ref)
    d = dict(zip(ctrl.diagnostic_fields, diag))
    assert d["cross_track_error"] == pytest.approx(cross, abs=1e-12)
    assert d["along_track_error"] == pytest.approx(along, abs=1e-12)
    assert math.remainder(d["path_angle"] - h, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    chi = h - math.atan(cross / DELTA)
    assert math.remainder(d["chi_d"] - chi, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    # a large offset steers at most 90 deg off the path, toward it
    assert abs(math.remainder(d["chi_d"] - h, 2 * math.pi)) < math.pi / 2


def test_heading_loop_holds_a_constant_heading_against_a_constant_yaw_moment():
    """Delta = 1e6 m makes chi_d = pi_p = 30 deg a constant heading command. Against a constant
    5 N m yaw moment (the paper disturbance with zero frequencies) the PID's integral takes the whole
    moment: in the steady state tau_r = -5 N m and the heading error vanishes (a P loop alone would
    keep 5 N m / kp = 5e-3 rad). The sway the first turn made decays with the hull's sway time
    constant m22/d22 = 6.5 s (and with it the Munk moment the loop also holds): by 55 s it is under
    1e-4 m/s, 3e-3 N m of yaw moment."""
    sc = _scenario(duration=60.0, controller={"lookahead": 1e6, "crab_compensation": False},
                   trajectory={"kind": "line", "heading_deg": 30.0}, initial={"eta": [0.0, 0.0, 0.0]},
                   quantizer={"enabled": False}, ship={"uncertainty_scale": 0.0},
                   disturbance={"scale": 1.0, "amplitudes": [0.0, 0.0, 5.0], "cos_frequencies": [0.0, 0.0, 0.0],
                                "sin_frequencies": [0.0, 0.0, 0.0]})
    rec = simulate(sc)
    assert rec.status == "completed"
    late = rec["t"] >= 55.0
    err = np.abs(np.angle(np.exp(1j * (rec["psi"][late] - math.radians(30.0)))))
    assert err.max() < 2e-4
    assert rec["tau_r"][late].mean() == pytest.approx(-5.0, rel=1e-3)
    assert np.abs(rec["r"][late]).max() < 1e-4


@pytest.mark.parametrize("ctrl, offset", [({"crab_compensation": False}, "lookahead"),
                                          ({"crab_compensation": False, "ilos_sigma": 0.5}, "none"),
                                          ({}, "none")])
def test_a_steady_side_force_leaves_the_lookahead_offset_unless_crab_is_compensated(ctrl, offset):
    """A constant 3 N side force makes the hull crab at beta = atan(v/u). Plain LOS steering the
    heading (no crab compensation) settles where the heading command chi_d = pi_p - atan(y_e/Delta)
    equals the heading that keeps the course on the path, pi_p - beta: y_e = Delta v/u (closed
    form, from the record's v and u). The integral LOS, or the measured crab angle, removes it."""
    sc = _scenario(duration=150.0, controller=ctrl, trajectory={"kind": "line"}, initial={"eta": [0.0, 0.0, 0.0]},
                   quantizer={"enabled": False}, ship={"uncertainty_scale": 0.0},
                   disturbance={"scale": 1.0, "amplitudes": [0.0, 3.0, 0.0], "cos_frequencies": [0.0, 0.0, 0.0],
                                "sin_frequencies": [0.0, 0.0, 0.0]})
    rec = simulate(sc)
    _, y_e = _path_errors(rec)
    v, u = rec["v"][-1], rec["u"][-1]
    assert v / u > 0.1  # the side force makes a real crab angle (about 8 deg)
    if offset == "lookahead":
        assert y_e[-1] == pytest.approx(DELTA * v / u, rel=1e-3)
    else:
        assert abs(y_e[-1]) < 2e-3


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_cross_track_error_converges_on_a_line_from_an_offset_start(plant):
    """Start 3 m left of a straight line heading north-east, at rest and heading east: the cross-track
    error (from the record's columns, not the controller's) falls below 5 cm within 25 s without
    overshooting by more than 10 % of the offset, and the along-track error below 0.2 m."""
    sc = _scenario(duration=25.0, trajectory={"kind": "line", "heading_deg": 45.0},
                   initial={"eta": [-3.0 / math.sqrt(2), 3.0 / math.sqrt(2), 0.0]})
    rec = simulate(sc, plant_kind=plant)
    assert rec.status == "completed"
    x_e, y_e = _path_errors(rec)
    assert y_e[0] == pytest.approx(3.0, abs=1e-9)
    assert np.allclose(y_e, rec["cross_track_error"], atol=1e-9)
    assert abs(y_e[-1]) < 0.05
    assert y_e.min() > -0.3
    assert abs(x_e[-1]) < 0.2


def test_python_loop_and_compiled_loop_give_the_same_record():
    """The law is one numba function that both loops call: the records are equal bit for bit."""
    sc = _scenario(duration=3.0)
    a, b = simulate(sc), simulate(sc, loop="python")
    assert a.metadata["loop"] == "compiled" and b.metadata["loop"] == "python"
    assert np.array_equal(a.data[:a.n_rows], b.data[:b.n_rows])


@pytest.mark.parametrize("key, value, words", [("lookahead", 0.0, "controller.lookahead must be > 0"),
                                                ("kp_psi", -1.0, "controller.kp_psi must be >= 0"),
                                                ("crab_compensation", 1.0, "controller.crab_compensation"),
                                                ("lookahed", 3.0, "did you mean 'lookahead'")])
def test_bad_gains_name_the_key(key, value, words):
    with pytest.raises(ScenarioError, match=words):
        _scenario(controller={key: value})


def test_cli_run_with_the_los_controller_exits_0(tmp_path):
    out = tmp_path / "run"
    code = main(["run", "--plant", "analytic", "--duration", "3", "--set", "controller.kind=los", "--no-video",
                 "--no-log", "--no-baseline", "-q", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert "los" in json.dumps(summary)
