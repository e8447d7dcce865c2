"""Open-loop inputs (controllers/open_loop.py), the zig-zag (controllers/zigzag.py) and the paper
hull's open-loop yaw instability (docs/model.md §8), against closed forms."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.builder import make_controller
from usv_mj.core.errors import ScenarioError
from usv_mj.physics.ship import ShipParams, sway_yaw_linearization

ROOT = Path(__file__).resolve().parent.parent


def _scenario(**over):
    base = {"baseline": {"enabled": False}, "plant": {"kind": "analytic"}, "quantizer": {"enabled": False},
            "disturbance": {"scale": 0.0}}
    for key, value in over.items():
        base[key] = {**base.get(key, {}), **value} if isinstance(value, dict) else value
    return load_scenario(preset="paper", overrides=base)


# --- open loop ---------------------------------------------------------------------------------

LINEAR = {"kind": "open_loop", "times": [0.0, 5.0, 5.0, 10.0], "tau_u": [0.0, 10.0, 20.0, 40.0],
          "tau_r": 1.5, "interpolation": "linear"}
STEP = {"kind": "open_loop", "times": [1.0, 2.0, 4.0], "tau_u": 7.0, "tau_r": [1.0, -1.0, 3.0],
        "interpolation": "step"}


@pytest.mark.parametrize("table, t, tau_u, tau_r", [
    (LINEAR, 0.0, 0.0, 1.5), (LINEAR, 2.5, 5.0, 1.5), (LINEAR, 4.999, 9.998, 1.5),
    (LINEAR, 5.0, 20.0, 1.5),  # a time given twice is a step, continuous from the right
    (LINEAR, 7.5, 30.0, 1.5), (LINEAR, 10.0, 40.0, 1.5), (LINEAR, 12.0, 40.0, 1.5),
    (STEP, 0.0, 7.0, 1.0), (STEP, 1.999, 7.0, 1.0), (STEP, 2.0, 7.0, -1.0), (STEP, 3.5, 7.0, -1.0),
    (STEP, 4.0, 7.0, 3.0), (STEP, 100.0, 7.0, 3.0),
])
def test_table_values_at_chosen_times(table, t, tau_u, tau_r):
    ctrl = make_controller(_scenario(controller=table))
    ctrl.reset()
    u, r, _ = ctrl(t, np.zeros(6), np.zeros(7))
    assert u == pytest.approx(tau_u, abs=1e-12) and r == pytest.approx(tau_r, abs=1e-12)


def test_a_run_applies_the_table_and_is_not_judged():
    """The record's commanded forces at every row are the table's closed form (unquantized)."""
    rec = simulate(_scenario(duration=12.0, controller=LINEAR))
    t = rec["t"]
    expect = np.where(t < 5.0, 2.0 * t, np.minimum(20.0 + 4.0 * (t - 5.0), 40.0))
    assert np.allclose(rec["tau_u"], expect, atol=1e-9)
    assert np.all(rec["tau_r"] == 1.5)
    assert np.allclose(rec["f_u"], rec["tau_u"]) and np.allclose(rec["f_r"], rec["tau_r"])
    ctrl = make_controller(_scenario(controller=LINEAR))
    assert ctrl.criterion.kind == "not_judged"


@pytest.mark.parametrize("table, words", [
    ({"times": [0.0, 2.0, 1.0], "tau_u": [0.0, 1.0, 2.0]}, r"controller.times must be non-decreasing: times\[2\]"),
    ({"times": [0.0, 1.0], "tau_u": [0.0, 1.0, 2.0]}, "controller.tau_u has 3 values but controller.times has 2"),
    ({"tau_r": [0.0, 1.0]}, "controller.tau_r is a list of 2 values but controller.times is not given"),
    ({"tau_u": "fast"}, "controller.tau_u must be a finite number"),
    ({"times": [0.0, float("nan")], "tau_u": [0.0, 1.0]}, r"controller.times\[1\] must be a finite number"),
    ({"interpolation": "cubic"}, "controller.interpolation must be one of 'step', 'linear'"),
    ({"tau": 1.0}, "unknown key 'controller.tau'"),
])
def test_bad_tables_name_the_key(table, words):
    with pytest.raises(ScenarioError, match=words):
        _scenario(controller={"kind": "open_loop", **table})


# --- zig-zag -----------------------------------------------------------------------------------

@pytest.mark.parametrize("switch_deg, first", [(10.0, "starboard"), (20.0, "port")])
def test_zigzag_switches_exactly_when_the_heading_change_passes_the_threshold(switch_deg, first):
    """On the record: the heading change is the unwrapped psi - psi(0) (from the state columns); the
    yaw moment reverses at exactly the rows where the change first passes +-psi_switch in the
    direction of the turn, and nowhere else."""
    amp = 10.0
    rec = simulate(_scenario(duration=60.0, initial={"eta": [0.0, 0.0, 0.0], "nu": [0.6, 0.0, 0.0]},
                             controller={"kind": "zigzag", "tau_r_amplitude": amp, "psi_switch_deg": switch_deg,
                                         "first_turn": first}))
    assert rec.status == "completed"
    dpsi = np.unwrap(rec["psi"]) - rec["psi"][0]
    thr = math.radians(switch_deg)
    sign = np.sign(rec["tau_r"])
    assert np.all(np.abs(rec["tau_r"]) == amp)
    expected_first = -1.0 if first == "starboard" else 1.0
    turn, expected = expected_first, []
    for k in range(len(dpsi)):  # the switching rule of IMO's zig-zag, on the recorded heading
        if (turn < 0 and dpsi[k] <= -thr) or (turn > 0 and dpsi[k] >= thr):
            turn = -turn
        expected.append(turn)
    assert np.array_equal(sign, np.array(expected))
    switches = np.flatnonzero(np.diff(sign)) + 1
    assert len(switches) >= 4
    for k in switches:  # the threshold is passed at row k and was not at row k - 1
        assert abs(dpsi[k]) >= thr - 1e-12 and abs(dpsi[k - 1]) < thr
        assert np.sign(dpsi[k]) == -sign[k]
    assert np.allclose(rec["heading_change"], dpsi, atol=1e-9)
    assert rec["switches"][-1] == len(switches)


def test_zigzag_bad_input_names_the_key():
    with pytest.raises(ScenarioError, match="controller.first_turn must be 'starboard' or 'port'"):
        _scenario(controller={"kind": "zigzag", "first_turn": "left"})
    with pytest.raises(ScenarioError, match="controller.psi_switch_deg must be > 0"):
        _scenario(controller={"kind": "zigzag", "psi_switch_deg": 0.0})


# --- the open-loop yaw instability (docs/model.md §8) ----------------------------------------

def _n_closed_form(s: ShipParams, u0: float) -> np.ndarray:
    """N(u0) of docs/model.md §8 written out from the printed coefficients."""
    return np.array([[s.d22[0], s.m11 * u0 + s.d23[0]],
                     [(s.m22 - s.m11) * u0 + s.d32[0], s.m23 * u0 + s.d33[0]]])


def test_linearized_sway_yaw_dynamics_has_a_positive_real_eigenvalue():
    s = ShipParams()
    m_sy = np.array([[s.m22, s.m23], [s.m23, s.m33]])
    for u0 in (0.0, 0.3, 0.6, 1.0):
        a = -np.linalg.solve(m_sy, _n_closed_form(s, u0))
        assert np.allclose(sway_yaw_linearization(s, u0), a, rtol=1e-6, atol=1e-6)
    lam = np.linalg.eigvals(sway_yaw_linearization(s, 0.6))
    assert np.all(np.isreal(lam))
    assert max(lam.real) == pytest.approx(0.6014, abs=1e-4) and min(lam.real) < 0
    assert np.linalg.det(_n_closed_form(s, 0.6)) < 0  # det N < 0 <=> one positive real eigenvalue
    # at rest the hull is stable; det N(u) = 0 at the critical speed, a quadratic in u written out
    assert max(np.linalg.eigvals(sway_yaw_linearization(s, 0.0)).real) < 0
    d22, d23, d32, d33 = s.d22[0], s.d23[0], s.d32[0], s.d33[0]
    quad = [-s.m11 * (s.m22 - s.m11), d22 * s.m23 - s.m11 * d32 - d23 * (s.m22 - s.m11), d22 * d33 - d23 * d32]
    u_crit = max(np.roots(quad).real)
    assert u_crit == pytest.approx(0.201, abs=1e-3)
    assert max(np.linalg.eigvals(sway_yaw_linearization(s, u_crit)).real) == pytest.approx(0.0, abs=1e-6)


def test_simulated_yaw_rate_grows_at_the_linearized_rate():
    """The scenario of docs/model.md §8 (tau_u holds 0.6 m/s, tau_r = 0, r(0) = 1e-3 rad/s) on the
    analytic plant: over 2-6 s the yaw rate follows expm(A t) (0, r0) within 3 % and grows at
    lambda_1 within 3 %. Tolerance: up to 6 s |v| < 0.01 m/s and |r| < 0.015 rad/s, where the
    quadratic damping terms the linearization drops (73.85 |v| in d22, 10.71 |r| in d23 and d33)
    change N by under 3 %; the stable mode (-1.13 1/s) is below 1e-3 of the unstable one from 2 s on."""
    sc = load_scenario(ROOT / "examples" / "scenarios" / "yaw_instability.toml",
                       overrides={"duration": 6.0, "plant": {"kind": "analytic"}})
    assert sc.initial.nu == (0.6, 0.0, 1e-3) and sc.controller.kind == "open_loop"
    rec = simulate(sc)
    t, r = rec["t"], rec["r"]
    a = sway_yaw_linearization(sc.ship, 0.6)
    lam, vec = np.linalg.eig(a)
    c = np.linalg.solve(vec, np.array([0.0, 1e-3]))
    window = (t >= 2.0) & (t <= 6.0)
    r_lin = (vec[1] * c) @ np.exp(np.outer(lam, t[window]))
    assert np.allclose(r[window], r_lin.real, rtol=0.03)
    rate = np.polyfit(t[window], np.log(r[window]), 1)[0]
    assert rate == pytest.approx(max(lam.real), rel=0.03)
    assert np.abs(rec["v"][window]).max() < 0.01 and r[window].max() < 0.015


@pytest.mark.parametrize("name, kind", [("yaw_instability", "open_loop"), ("zigzag_10_10", "zigzag"),
                                        ("los_circle", "los")])
def test_example_scenarios_load(name, kind):
    sc = load_scenario(ROOT / "examples" / "scenarios" / f"{name}.toml")
    assert sc.controller.kind == kind and not sc.baseline.enabled
