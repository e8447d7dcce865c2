"""The propellers' shaft-speed lag (Otter: T_n = 0.1 s, thrust k n|n| per propeller), exact at the
control period.

Independent numbers: the closed form of the thrust impulse after a step from rest,
k n_c^2 [t - 2 T (1 - e^(-t/T)) + T/2 (1 - e^(-2t/T))]; a reversal through n = 0 (k changes there)
integrated by scipy's quad; the reference's own ODE (otter.py's n_dot = (n_c - n)/T_n) integrated by
solve_ivp; and the other plant.
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from usv_mj import load_scenario
from usv_mj.physics.actuators import ActuatorSpec, Actuators, S_N_P, S_N_S

K_POS, K_NEG, TN, SEP = 0.02216 / 2, 0.01289 / 2, 0.1, 0.79


def _otter_spec(**kw):
    return ActuatorSpec(kind="twin", separation_m=SEP, thruster_forward_n=119.682, thruster_reverse_n=66.708,
                        shaft_time_constant_s=TN, thrust_coeff_forward=K_POS, thrust_coeff_reverse=K_NEG, **kw)


def test_step_from_rest_carries_the_closed_form_impulse():
    h = 0.01
    act = Actuators(_otter_spec(), h)
    thrust = 80.0                                   # N per propeller
    n_c = math.sqrt(thrust / K_POS)
    impulse = 0.0
    for k in range(1, 101):
        f_u, f_r, _, _ = act.apply(2 * thrust, 0.0)
        impulse += f_u * h
        t = k * h
        closed = 2 * K_POS * n_c ** 2 * (t - 2 * TN * (1 - math.exp(-t / TN)) + TN / 2 * (1 - math.exp(-2 * t / TN)))
        assert impulse == pytest.approx(closed, rel=1e-12)
        assert act.state[S_N_P] == pytest.approx(n_c * (1 - math.exp(-t / TN)), rel=1e-12)
        assert f_r == pytest.approx(0.0, abs=1e-12)
    # the thrust response of a shaft-speed lag is not a first-order thrust lag: at t = T_n it is
    # (1 - 1/e)^2 = 40 % of the final thrust (a thrust lag: 63 %)
    act.reset()
    for _ in range(10):
        act.apply(2 * thrust, 0.0)
    n = act.state[S_N_P]
    assert K_POS * n * n / thrust == pytest.approx((1 - math.exp(-1)) ** 2, rel=1e-12)


def test_a_reversal_through_zero_speed_and_a_turn_against_quadrature():
    """From steady ahead on both shafts, full yaw to port: the port shaft reverses (through n = 0,
    where k changes from k_pos to k_neg), the starboard one speeds up; each period's average thrust
    against quad of k(n) n|n| of the exact n(t), and the shaft speeds against solve_ivp of the
    reference's ODE."""
    h = 0.02
    act = Actuators(_otter_spec(), h)
    for _ in range(200):                            # 4 s = 40 T_n: steady at 60 N per propeller
        act.apply(120.0, 0.0)
    n0p, n0s = act.state[S_N_P], act.state[S_N_S]
    assert K_POS * n0p ** 2 == pytest.approx(60.0, rel=1e-12)
    tau_r = 0.5 * SEP * (100.0 - (-50.0))           # T_s = 100 N, T_p = -50 N
    cp, cs = -math.sqrt(50.0 / K_NEG), math.sqrt(100.0 / K_POS)

    def thrust(n):
        return (K_POS if n > 0 else K_NEG) * n * abs(n)

    def n_at(n0, c, t):
        return c + (n0 - c) * math.exp(-t / TN)

    ref = solve_ivp(lambda t, n: [(cp - n[0]) / TN, (cs - n[1]) / TN], (0.0, 0.3), [n0p, n0s],
                    method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    for k in range(15):
        f_u, f_r, _, _ = act.apply(50.0, tau_r)
        t0 = k * h
        tp = quad(lambda t: thrust(n_at(n0p, cp, t)), t0, t0 + h, points=[TN * math.log((cp - n0p) / cp)],
                  epsabs=1e-13, limit=200)[0] / h
        ts = quad(lambda t: thrust(n_at(n0s, cs, t)), t0, t0 + h, epsabs=1e-13)[0] / h
        assert f_u == pytest.approx(tp + ts, abs=1e-9)
        assert f_r == pytest.approx(0.5 * SEP * (ts - tp), abs=1e-9)
        np.testing.assert_allclose([act.state[S_N_P], act.state[S_N_S]], ref.sol(t0 + h), rtol=0, atol=1e-8)


def test_otter_has_it_and_both_plants_get_the_same_thrust():
    from usv_mj.loop.simulate import simulate

    sc = load_scenario(preset="paper", overrides={
        "vessel": {"kind": "otter"}, "duration": 2.0, "disturbance": {"scale": 0.0}, "quantizer": {"enabled": False},
        "initial": {"eta": [0.0, 0.0, 0.0], "nu": [0.0, 0.0, 0.0]}, "baseline": {"enabled": False},
        "controller": {"kind": "open_loop", "times": [0.0], "tau_u": 160.0, "tau_r": 0.0}})
    assert sc.actuators.shaft_time_constant_s == TN and sc.actuators.thrust_coeff_forward == K_POS
    runs = {k: simulate(sc, plant_kind=k) for k in ("analytic", "mujoco")}
    h = sc.control_period
    n_c = math.sqrt(80.0 / K_POS)
    for rec in runs.values():
        impulse = np.cumsum(rec["f_u"]) * h
        k = min(len(impulse), 1500)
        te = (np.arange(1, k + 1)) * h
        closed = 2 * K_POS * n_c ** 2 * (te - 2 * TN * (1 - np.exp(-te / TN)) + TN / 2 * (1 - np.exp(-2 * te / TN)))
        np.testing.assert_allclose(impulse[:k], closed, rtol=1e-9)
    a, m = runs["analytic"], runs["mujoco"]
    assert np.max(np.hypot(a["x"] - m["x"], a["y"] - m["y"])) < 1e-9
