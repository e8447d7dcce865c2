"""The analytic plant against independent truths (closed forms and convergence order)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from usv_mj.physics import ship
from usv_mj.plants.analytic import AnalyticPlant

CALM = ship.PaperDisturbance(scale=0.0)
NO_DELTA = ship.ShipParams(uncertainty_scale=0.0)


def test_surge_speed_settles_where_damping_balances_thrust():
    tau = 60.0
    plant = AnalyticPlant(NO_DELTA, CALM, control_period=0.01)
    plant.reset((0, 0, 0), (0, 0, 0))
    for _ in range(6000):
        plant.step(tau, 0.0)
    u_star = brentq(lambda u: (45.6 + 67.26 * abs(u) + 10 * u * u) * u - tau, 0, 5)
    assert plant.state[3] == pytest.approx(u_star, abs=1e-9)
    assert abs(plant.state[4]) < 1e-12 and abs(plant.state[5]) < 1e-12


def test_kinetic_energy_decays_without_input():
    plant = AnalyticPlant(NO_DELTA, CALM, control_period=0.01)
    plant.reset((0, 0, 0), (1.0, 0.4, 0.3))
    energies = [ship.kinetic_energy(NO_DELTA, plant.state[3:])]
    for _ in range(2000):
        plant.step(0.0, 0.0)
        energies.append(ship.kinetic_energy(NO_DELTA, plant.state[3:]))
    e = np.array(energies)
    assert np.all(np.diff(e) < 0)  # C is skew-symmetric, D dissipates
    # dE/dt = -nu^T D nu: check the rate at the start
    nu0 = np.array([1.0, 0.4, 0.3])
    rate = -nu0 @ ship.damping_matrix(NO_DELTA.as_array(), nu0) @ nu0
    assert (e[1] - e[0]) / 0.01 == pytest.approx(rate, rel=0.02)


def test_rk4_converges_at_fourth_order():
    """On a trajectory where u, v, r keep their signs: the |u|, |v|, |r| of D(nu) are kinks where a
    velocity crosses zero, and RK4 is only fourth order on smooth right-hand sides."""
    p, dp = ship.ShipParams().as_array(), ship.PaperDisturbance(scale=1e-4).as_array()
    x0 = np.array([2.0, -3.0, 0.1, 0.8, -0.1, 0.1])
    tau_u, tau_r = 100.0, 1.0

    def rhs(t, x):
        return ship.state_derivative(p, dp, t, x, tau_u, tau_r)

    sol = solve_ivp(rhs, (0, 5), x0, method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True)
    assert np.all(sol.y[3] > 0) and np.all(sol.y[4] < 0) and np.all(sol.y[5] > 0)

    ref = sol.y[:, -1]
    errors = []
    for dt in (0.2, 0.1, 0.05, 0.025):
        plant = AnalyticPlant(ship.ShipParams(), ship.PaperDisturbance(scale=1e-4), control_period=dt)
        plant.reset(x0[:3], x0[3:])
        for _ in range(int(round(5 / dt))):
            plant.step(tau_u, tau_r)
        errors.append(np.max(np.abs(plant.state - ref)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    print("RK4 errors", errors, "orders", orders)
    assert np.all(orders > 3.7) and np.all(orders < 4.5)


def test_body_acceleration_is_the_solution_of_equation_2():
    rng = np.random.default_rng(0)
    s = ship.ShipParams()
    p, dp = s.as_array(), ship.PaperDisturbance(scale=1e-4).as_array()
    for _ in range(20):
        eta, nu = rng.normal(size=3), rng.normal(size=3)
        tu, tr, t = rng.normal() * 50, rng.normal() * 5, rng.uniform(0, 100)
        acc = ship.body_acceleration(p, dp, t, eta, nu, tu, tr)
        lhs = s.mass_matrix() @ acc + ship.coriolis_matrix(p, nu) @ nu + ship.damping_matrix(p, nu) @ nu
        rhs = np.array([tu, 0, tr]) + ship.disturbance_force(dp, t) + ship.uncertainty_force(p, eta, nu)
        assert lhs == pytest.approx(rhs, abs=1e-10)


def test_nominal_terms_match_the_dynamics_in_transformed_coordinates():
    """Eq. 7/28: with no disturbance and Delta, u_dot = phi_u + tau_u/m11, v_bar_dot = phi_v,
    r_dot = phi_r + m22 tau_r / Delta_M."""
    rng = np.random.default_rng(1)
    s = NO_DELTA
    p, dp = s.as_array(), CALM.as_array()
    dm = s.m22 * s.m33 - s.m23 ** 2
    for _ in range(20):
        nu = rng.normal(size=3)
        tu, tr = rng.normal() * 30, rng.normal() * 3
        acc = ship.body_acceleration(p, dp, 0.0, np.zeros(3), nu, tu, tr)
        pu, pv, pr = ship.nominal_terms(p, nu)
        assert acc[0] == pytest.approx(pu + tu / s.m11, abs=1e-12)
        assert acc[1] + s.eps * acc[2] == pytest.approx(pv, abs=1e-12)
        assert acc[2] == pytest.approx(pr + s.m22 * tr / dm, abs=1e-12)


def test_coriolis_is_skew_symmetric_and_split_adds_up():
    p = ship.ShipParams().as_array()
    c = ship.coriolis_matrix(p, np.array([0.7, -0.2, 0.4]))
    assert np.allclose(c, -c.T)
    split = ship.RigidBodySplit()
    m, xg, iz = split.rigid_body(ship.ShipParams())
    ma = split.added_mass(ship.ShipParams())
    assert m == 141.85 and xg == pytest.approx(5.7 / 141.85) and iz == 15.6
    assert np.allclose(ma, np.diag([0.0, 191.75 - 141.85, 0.0]))
