"""Sea state (SEA.md): the checks of §7 that need no MuJoCo plant, against independent numbers.

Checks 10 and 13 run on the analytic RK4 of :func:`usv_mj.physics.sea.dynamics.sea_rk4_advance`; check 1 is
the analytic half (bit-identical calm dynamics). Long records are ``slow``-marked but vectorised.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal, special

from usv_mj.plants.analytic import rk4_advance
from usv_mj.physics.sea import (CurrentSettings, Environment, HullGeometry, SeaSettings, SeaSettingsError,
                        WaveComponents, WaveSettings, WindSettings, jonswap_spectrum, load_sea_preset,
                        sea_preset_names, sea_rk4_advance, sea_rk4_trajectory, sea_state_derivative)
from usv_mj.physics.sea import layout as lay
from usv_mj.physics.sea.waves import fast_sincos, thin_barrier_reflection
from usv_mj.physics.sea.wind import wind_load
from usv_mj.physics.ship import PaperDisturbance, ShipParams, state_derivative

RHO, G = 1025.0, 9.81
SHIP = ShipParams()
P = SHIP.as_array()
DP = PaperDisturbance().as_array()
BARE = ShipParams(uncertainty_scale=0.0).as_array()   # the hull alone: no Delta
NO_DIST = PaperDisturbance(scale=0.0).as_array()       # and no d(t)


def moderate(**changes) -> WaveSettings:
    base = load_sea_preset("moderate").waves
    return WaveSettings(**{**base.__dict__, **changes})


def regular_env(amplitude, omega, direction, *, drift="off", hull=None, phase=0.3):
    comps = WaveComponents.regular(amplitude, omega, direction, phase=phase, g=G)
    settings = SeaSettings(waves=WaveSettings(hs=1.0, drift=drift))
    return Environment(settings, hull=hull, ramp_time=0.0, wave_components=comps)


# --- settings ------------------------------------------------------------------------------------


def test_presets_load_with_the_documented_values():
    assert set(sea_preset_names()) >= {"moderate", "steady-current", "breeze"}
    m = load_sea_preset("moderate")
    assert (m.waves.hs, m.waves.tp, m.waves.gamma, m.waves.components, m.waves.drift) == (0.2, 2.0, 3.3, 128, "newman")
    assert m.current == CurrentSettings() and m.wind == WindSettings()
    c = load_sea_preset("steady-current").current
    assert (c.speed, c.direction_deg, c.sigma) == (0.3, 30.0, 0.0)
    w = load_sea_preset("breeze").wind
    assert (w.speed, w.direction_deg, w.gust_sigma, w.gust_time_constant) == (5.0, 90.0, 1.0, 2.0)
    with pytest.raises(SeaSettingsError, match="unknown sea preset 'moderat'.*moderate"):
        load_sea_preset("moderat")


def test_defaults_are_calm():
    s = SeaSettings()
    assert s.calm
    env = Environment(s)
    assert env.calm and env.components.n == 0 and env.amplitude_bound == 0.0
    assert env.elevation(1.0, 2.0, 3.0) == 0.0
    loads = env.loads(5.0, [1, 2, 0.3], [0.5, 0.1, 0.2])
    for part in loads:
        assert np.all(part == 0.0)


@pytest.mark.parametrize("table, key", [
    ({"waves": {"hs": -0.1}}, "sea.waves.hs"),
    ({"waves": {"tp": 0.0}}, "sea.waves.tp"),
    ({"waves": {"gamma": 0.5}}, "sea.waves.gamma"),
    ({"waves": {"components": 0}}, "sea.waves.components"),
    ({"waves": {"drift": "second"}}, "sea.waves.drift"),
    ({"waves": {"seed": -1}}, "sea.waves.seed"),
    ({"waves": {"spreading": 1}}, "sea.waves.spreading"),
    ({"waves": {"hs": "big"}}, "sea.waves.hs"),
    ({"waves": {"hs": float("nan")}}, "sea.waves.hs"),
    ({"current": {"speed": -1.0}}, "sea.current.speed"),
    ({"current": {"time_constant": 0.0}}, "sea.current.time_constant"),
    ({"wind": {"gust_sigma": -1.0}}, "sea.wind.gust_sigma"),
    ({"wind": {"gust_time_constant": -2.0}}, "sea.wind.gust_time_constant"),
    ({"waves": {"xyz": 1.0}}, "sea.waves.xyz"),
    ({"tide": {}}, "sea.tide"),
])
def test_bad_values_name_their_key(table, key):
    with pytest.raises(SeaSettingsError) as info:
        SeaSettings.from_table(table, source="scen.toml")
    assert key in str(info.value) and "scen.toml" in str(info.value)


def test_from_table_reads_the_issue_example():
    table = {"waves": {"hs": 0.2, "tp": 2, "gamma": 3.3, "direction_deg": 0.0, "spreading": True,
                       "components": 128, "drift": "newman", "seed": 1},
             "current": {"speed": 0.3, "direction_deg": 30.0, "sigma": 0.0, "time_constant": 120.0},
             "wind": {"speed": 5.0, "direction_deg": 90.0, "gust_sigma": 1.0, "gust_time_constant": 2.0,
                      "seed": 2}}
    s = SeaSettings.from_table(table)
    assert s.waves.tp == 2.0 and isinstance(s.waves.tp, float)
    # to_dict writes the directions as a user does (compass, clockwise from north): going toward +x
    # (east) is waves from the west (270); toward 30 deg counter-clockwise from east is a current
    # setting toward compass 060; toward +y (north) is a wind from the south (180)
    marine = {"waves": ("from_deg", 270.0), "current": ("toward_deg", 60.0), "wind": ("from_deg", 180.0)}
    expected = {k: {(marine[k][0] if kk == "direction_deg" else kk):
                    (marine[k][1] if kk == "direction_deg" else float(vv) if kk == "tp" else vv)
                    for kk, vv in v.items()} for k, v in table.items()}
    assert s.to_dict() == expected
    assert SeaSettings.from_table(s.to_dict()) == s


# --- check 1 (analytic half): calm is bit-identical ---------------------------------------------


def test_calm_state_derivative_is_bit_identical():
    ep, waves, cg, wg = Environment().packed
    rng = np.random.default_rng(7)
    for _ in range(2000):
        x = rng.normal(size=6) * np.array([10, 10, 3, 2, 1, 1])
        t = rng.uniform(0, 300)
        tu, tr = rng.normal(size=2) * 20
        a = sea_state_derivative(P, DP, ep, waves, cg, wg, t, x, tu, tr)
        b = state_derivative(P, DP, t, x, tu, tr)
        assert np.array_equal(a, b)


def test_calm_rk4_60s_with_a_thrust_schedule_is_bit_identical():
    ep, waves, cg, wg = Environment().packed
    x_sea = x_ref = np.array([2.0, -3.0, 0.0, 0.0, 0.0, 0.0])
    h = 1e-3
    for k in range(60_000):
        t = k * h
        tu = 60.0 + 20.0 * math.sin(0.3 * t)
        tr = 2.0 * math.cos(0.2 * t)
        x_sea = sea_rk4_advance(P, DP, ep, waves, cg, wg, t, x_sea, tu, tr, h, 1)
        x_ref = rk4_advance(P, DP, t, x_ref, tu, tr, h, 1)
    assert np.array_equal(x_sea, x_ref)


def test_sea_force_is_callable_from_a_native_cfunc():
    """The kernels take plain C-contiguous arrays, so a numba cfunc (the MuJoCo callback) can wrap raw
    pointers with carray and call sea_force; it must give what the Python-side call gives."""
    import ctypes

    from numba import carray, cfunc, types

    from usv_mj.physics.sea import sea_force
    from usv_mj.physics.ship import N_DIST_PARAMS, N_SHIP_PARAMS

    f64p = types.CPointer(types.float64)
    sig = types.void(f64p, f64p, f64p, types.int64, f64p, types.int64, f64p, types.int64, f64p,
                     types.float64, f64p, f64p)

    @cfunc(sig)
    def native(p_ptr, dp_ptr, ep_ptr, n_waves, wv_ptr, n_cur, cg_ptr, n_wind, wg_ptr, t, state_ptr, out_ptr):
        p = carray(p_ptr, (N_SHIP_PARAMS,))
        dp = carray(dp_ptr, (N_DIST_PARAMS,))
        ep = carray(ep_ptr, (lay.N_ENV_PARAMS,))
        waves = carray(wv_ptr, (lay.N_WAVE_COLS, n_waves))
        cg = carray(cg_ptr, (n_cur, 2))
        wg = carray(wg_ptr, (n_wind, 1))
        state = carray(state_ptr, (6,))
        out = carray(out_ptr, (3,))
        f = sea_force(p, dp, ep, waves, cg, wg, t, state[:3], state[3:])
        for i in range(3):
            out[i] = f[i]

    env = Environment(_full_sea(), t_max=100.0)
    ep, waves, cg, wg = env.packed
    ptr = lambda arr: arr.ctypes.data_as(ctypes.POINTER(ctypes.c_double))  # noqa: E731
    call = native.ctypes
    rng = np.random.default_rng(5)
    for _ in range(20):
        t = rng.uniform(0, 100)
        state = np.ascontiguousarray(rng.normal(size=6) * 0.5)
        out = np.zeros(3)
        call(ptr(P), ptr(DP), ptr(ep), waves.shape[1], ptr(waves), cg.shape[0], ptr(cg), wg.shape[0], ptr(wg),
             t, ptr(state), ptr(out))
        direct = sea_force(P, DP, ep, waves, cg, wg, t, state[:3], state[3:])
        assert np.array_equal(out, direct)
        assert np.any(direct != sea_force(P, DP, *Environment().packed, t, state[:3], state[3:]))


# --- check 2: spectrum --------------------------------------------------------------------------


@pytest.mark.parametrize("hs, tp, gamma", [(0.2, 2.0, 3.3), (0.2, 2.0, 1.0), (1.5, 6.0, 2.0), (0.5, 3.0, 5.0)])
def test_spectrum_integrates_to_hs(hs, tp, gamma):
    wp = 2 * math.pi / tp
    m0, _ = integrate.quad(lambda w: float(jonswap_spectrum(np.array([w]), hs, tp, gamma)[0]), 0.01, 40.0,
                           points=[wp], limit=400, epsabs=0, epsrel=1e-10)
    assert abs(4 * math.sqrt(m0) / hs - 1) < 0.005
    # peak at w_p
    w = np.linspace(0.5 * wp, 2 * wp, 30001)
    assert abs(w[np.argmax(jonswap_spectrum(w, hs, tp, gamma))] / wp - 1) < 1e-3


def test_sampled_amplitudes_carry_hs_exactly_and_cover_the_band():
    env = Environment(SeaSettings(waves=moderate()))
    c = env.components
    assert c.n == 128
    assert abs(np.sum(c.a**2) / 2 - 0.2**2 / 16) < 1e-15
    wp = math.pi
    assert c.w.min() >= 0.5 * wp and c.w.max() <= 4.0 * wp and len(np.unique(c.w)) == 128
    assert np.allclose(c.k, c.w**2 / G, rtol=1e-15)
    # cos^2 spreading: |mu| <= pi/2 and its sample variance near that of (2/pi) cos^2 mu
    mu = c.beta - 0.0
    assert np.all(np.abs(mu) <= math.pi / 2)
    var_theory = math.pi**2 / 12 - 0.5
    assert abs(np.mean(mu**2) / var_theory - 1) < 0.1
    long = Environment(SeaSettings(waves=moderate(spreading=False)))
    assert np.all(long.components.beta == 0.0)


# --- check 3: record statistics -----------------------------------------------------------------


@pytest.mark.slow
def test_record_hs_and_peak_period_over_ten_seeds():
    ts = np.arange(0.0, 1800.0, 0.05)
    psd_sum = None
    for seed in range(10):
        env = Environment(SeaSettings(waves=moderate(seed=seed)), ramp_time=0.0)
        z = env.elevation(0.0, 0.0, ts)
        assert abs(4 * np.std(z) / 0.2 - 1) < 0.05, seed
        f, psd = signal.welch(z, fs=20.0, nperseg=4096)
        psd_sum = psd if psd_sum is None else psd_sum + psd
    tp_est = 1.0 / f[np.argmax(psd_sum)]
    assert abs(tp_est / 2.0 - 1) < 0.10


def test_start_up_ramp_scales_elevation_first_order_and_drift():
    settings = SeaSettings(waves=moderate(direction_deg=150.0))
    ramped, plain = Environment(settings, ramp_time=2.0), Environment(settings, ramp_time=0.0)
    eta, nu = np.array([0.5, -1.0, 0.3]), np.array([0.2, 0.0, 0.1])
    for t in [0.1, 1.0, 3.0, 10.0]:
        s = 1.0 - math.exp(-t / 2.0)
        a, b = ramped.loads(t, eta, nu), plain.loads(t, eta, nu)
        assert np.allclose(a.tau_wave1, s * b.tau_wave1, rtol=1e-12, atol=1e-12)
        assert np.allclose(a.tau_drift, s * s * b.tau_drift, rtol=1e-12, atol=1e-14)
        assert abs(ramped.elevation(0.5, -1.0, t) - s * plain.elevation(0.5, -1.0, t)) < 1e-14
    assert np.all(ramped.loads(0.0, eta, nu).tau_wave1 == 0.0) and ramped.elevation(0.0, 0.0, 0.0) == 0.0


# --- check 4: determinism -----------------------------------------------------------------------


def _full_sea(wave_seed=1, wind_seed=2):
    return SeaSettings(waves=moderate(seed=wave_seed),
                       current=CurrentSettings(speed=0.3, direction_deg=30.0, sigma=0.05, time_constant=120.0),
                       wind=WindSettings(speed=5.0, direction_deg=90.0, gust_sigma=1.0, seed=wind_seed))


def test_same_seed_gives_identical_fields_and_loads():
    a, b = Environment(_full_sea(), t_max=100.0), Environment(_full_sea(), t_max=900.0)
    rng = np.random.default_rng(3)
    ts = rng.uniform(0, 100, 200)
    etas = rng.normal(size=(200, 3))
    nus = rng.normal(size=(200, 3)) * 0.5
    assert np.array_equal(a.elevation(etas[:, 0], etas[:, 1], ts), b.elevation(etas[:, 0], etas[:, 1], ts))
    assert np.array_equal(a.loads_record(ts, etas, nus), b.loads_record(ts, etas, nus))


def test_a_new_wind_seed_leaves_the_waves_and_current_unchanged():
    a, b = Environment(_full_sea(wind_seed=2)), Environment(_full_sea(wind_seed=99))
    assert np.array_equal(a.packed.waves, b.packed.waves)
    assert np.array_equal(a.packed.current_grid, b.packed.current_grid)
    assert not np.array_equal(a.packed.wind_grid, b.packed.wind_grid)
    ts = np.linspace(0, 50, 101)
    ra, rb = a.loads_record(ts, [1, 2, 0.3], [0.4, 0, 0]), b.loads_record(ts, [1, 2, 0.3], [0.4, 0, 0])
    assert np.array_equal(ra[:, lay.L_WAVE1:], rb[:, lay.L_WAVE1:])
    assert np.array_equal(ra[:, :lay.L_WIND], rb[:, :lay.L_WIND])
    assert not np.array_equal(ra[:, lay.L_WIND:lay.L_WAVE1], rb[:, lay.L_WIND:lay.L_WAVE1])
    # and a new wave seed leaves the wind unchanged
    c = Environment(_full_sea(wave_seed=5))
    assert np.array_equal(a.packed.wind_grid, c.packed.wind_grid)


# --- check 5: closed form against a volume quadrature -------------------------------------------


def quadrature_box_load(a, k, beta, eps, t, eta, hull, draft, n=(48, 24, 16)):
    """-integral of grad p over the box (Gauss-Legendre), body frame, moment about the origin."""
    w = math.sqrt(G * k)
    L, B, xb = hull.length, hull.beam, hull.box_center_x
    gx, wx = np.polynomial.legendre.leggauss(n[0])
    gy, wy = np.polynomial.legendre.leggauss(n[1])
    gz, wz = np.polynomial.legendre.leggauss(n[2])
    xi = xb + gx * L / 2
    et = gy * B / 2
    z = -draft / 2 + gz * draft / 2
    wts = (wx[:, None, None] * wy[None, :, None] * wz[None, None, :]) * (L / 2) * (B / 2) * (draft / 2)
    XI, ET, Z = np.meshgrid(xi, et, z, indexing="ij")
    x0, y0, psi = eta
    c, s = math.cos(psi), math.sin(psi)
    xw = x0 + c * XI - s * ET
    yw = y0 + s * XI + c * ET
    theta = w * t - k * (xw * math.cos(beta) + yw * math.sin(beta)) + eps
    # p = rho g a e^{kz} cos(theta); grad_n p = rho g a e^{kz} sin(theta) k [cos beta, sin beta]
    amp = RHO * G * a * np.exp(k * Z) * np.sin(theta) * k
    fxn, fyn = -amp * math.cos(beta), -amp * math.sin(beta)
    fxb = c * fxn + s * fyn
    fyb = -s * fxn + c * fyn
    X = np.sum(wts * fxb)
    Y = np.sum(wts * fyb)
    N = np.sum(wts * (XI * fyb - ET * fxb))
    return np.array([X, Y, N])


@pytest.mark.parametrize("k, beta_deg, psi", [(0.5, 0.0, 0.0), (2.0, 30.0, 0.4), (5.0, 60.0, -0.7),
                                               (5.0, 135.0, 0.2), (1.0, 90.0, 0.0), (3.0, -100.0, 1.3)])
def test_closed_form_matches_volume_quadrature(k, beta_deg, psi):
    hull = HullGeometry(box_center_x=0.3)
    beta = math.radians(beta_deg)
    a = 0.05
    env = regular_env(a, math.sqrt(G * k), beta, hull=hull)
    eta = np.array([1.3, -0.4, psi])
    ts = np.linspace(0.0, 2 * math.pi / math.sqrt(G * k), 9)[:-1]
    closed = np.array([env.loads(t, eta, [0, 0, 0]).tau_wave1 for t in ts])
    quad = np.array([quadrature_box_load(a, k, beta, 0.3, t, eta, hull, env.draft) for t in ts])
    scale = np.max(np.abs(quad), axis=0)
    for i in range(3):
        if scale[i] > 1e-6 * np.max(scale):
            assert np.max(np.abs(closed[:, i] - quad[:, i])) < 0.005 * scale[i], (i, closed[:, i], quad[:, i])
        else:
            assert np.max(np.abs(closed[:, i])) < 1e-6 * np.max(scale)


def _reference_wave_loads(env, t, eta):
    """The closed form of SEA.md §3.4-3.5 in plain numpy with scipy's Bessel functions (libm trig),
    drift as the O(N^2) Newman double sum: an independent implementation of the kernel."""
    c, hull, T = env.components, env.hull, env.draft
    L, B, xb = hull.length, hull.beam, hull.box_center_x
    x, y, psi = eta
    xc, yc = x + math.cos(psi) * xb, y + math.sin(psi) * xb
    theta = c.w * t - c.k * (xc * np.cos(c.beta) + yc * np.sin(c.beta)) + c.eps
    br = c.beta - psi
    kx, ky = c.k * np.cos(br), c.k * np.sin(br)
    cj = RHO * G * c.a * (1 - np.exp(-c.k * T))
    j0 = lambda u: special.spherical_jn(0, u)  # noqa: E731
    j1 = lambda u: special.spherical_jn(1, u)  # noqa: E731
    P = j0(kx * L / 2) * j0(ky * B / 2)
    X = -cj * L * B * P * np.cos(br) * np.sin(theta)
    Y = -cj * L * B * P * np.sin(br) * np.sin(theta)
    N = cj * (L * B / 2) * (L * np.sin(br) * j1(kx * L / 2) * j0(ky * B / 2)
                            - B * np.cos(br) * j1(ky * B / 2) * j0(kx * L / 2)) * np.cos(theta) + xb * Y
    kt = c.k * T
    r2 = np.pi**2 * special.iv(1, kt) ** 2 / (np.pi**2 * special.iv(1, kt) ** 2 + special.kv(1, kt) ** 2)
    q = 0.5 * RHO * G * r2
    Q = np.stack([q * B * np.cos(br) * np.abs(np.cos(br)), q * L * np.sin(br) * np.abs(np.sin(br))])
    Q = np.vstack([Q, xb * Q[1]])
    cosdiff = np.cos(theta[:, None] - theta[None, :])
    aa = c.a[:, None] * c.a[None, :]
    drift = np.array([np.sum(aa * 0.5 * (Qi[:, None] + Qi[None, :]) * cosdiff) for Qi in Q])
    return np.array([X.sum(), Y.sum(), N.sum()]), drift


def test_kernel_equals_an_independent_implementation_for_the_preset_sea():
    hull = HullGeometry(box_center_x=0.25)
    env = Environment(SeaSettings(waves=moderate(seed=4)), hull=hull, ramp_time=0.0)
    rng = np.random.default_rng(11)
    for _ in range(20):
        t = rng.uniform(0, 5000)
        eta = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-4, 4)])
        got = env.loads(t, eta, [0.3, 0.1, 0.0])
        first, drift = _reference_wave_loads(env, t, eta)
        scale1 = np.max(np.abs(first)) + 1e-12
        assert np.max(np.abs(got.tau_wave1 - first)) < 1e-9 * max(scale1, 1.0)
        assert np.max(np.abs(got.tau_drift - drift)) < 1e-9


def test_fast_sincos_matches_libm():
    x = np.concatenate([np.linspace(-50, 50, 10001), np.random.default_rng(0).uniform(-1e6, 1e6, 10000)])
    got = np.array([fast_sincos(v) for v in x])
    assert np.max(np.abs(got[:, 0] - np.sin(x))) < 1e-14
    assert np.max(np.abs(got[:, 1] - np.cos(x))) < 1e-14


# --- check 6: drawn = pushing --------------------------------------------------------------------


@pytest.mark.parametrize("beta_deg, psi", [(0.0, 0.0), (40.0, 0.5), (200.0, -1.0)])
def test_long_wave_load_is_minus_rho_g_volume_times_drawn_slope(beta_deg, psi):
    hull = HullGeometry(box_center_x=0.3)
    k = 2 * math.pi / 200.0
    env = regular_env(0.1, math.sqrt(G * k), math.radians(beta_deg), hull=hull)
    vol = hull.length * hull.beam * env.draft
    h = 0.01
    for t in np.linspace(0.0, 2 * math.pi / math.sqrt(G * k), 7)[:-1]:
        eta = np.array([3.0, -2.0, psi])
        c, s = math.cos(psi), math.sin(psi)
        cx, cy = eta[0] + c * hull.box_center_x, eta[1] + s * hull.box_center_x
        slope_x = (env.elevation(cx + h * c, cy + h * s, t) - env.elevation(cx - h * c, cy - h * s, t)) / (2 * h)
        slope_y = (env.elevation(cx - h * s, cy + h * c, t) - env.elevation(cx + h * s, cy - h * c, t)) / (2 * h)
        want = -RHO * G * vol * np.array([slope_x, slope_y])
        got = env.loads(t, eta, [0, 0, 0]).tau_wave1[:2]
        amp = RHO * G * vol * 0.1 * k
        assert np.max(np.abs(got - want)) < 0.01 * amp


def test_hfield_node_under_the_hull_equals_elevation():
    env = Environment(_full_sea())
    xs = np.linspace(-10.0, 10.0, 201)
    ys = np.linspace(-10.0, 10.0, 201)
    for t, origin in [(0.7, (0.0, 0.0)), (37.3, (12.4, -3.1)), (250.0, (-80.0, 55.5))]:
        grid = env.elevation_grid(xs, ys, t, origin=origin)
        assert grid.shape == (201, 201)
        for i, l in [(100, 100), (0, 200), (57, 143)]:
            z = env.elevation(origin[0] + xs[i], origin[1] + ys[l], t)
            assert abs(grid[l, i] - z) < 1e-5
        assert np.max(np.abs(grid)) <= env.amplitude_bound
        heights = env.hfield_heights(xs, ys, t, origin=origin)
        A = np.sum(env.components.a)
        assert heights.dtype == np.float32 and heights.min() >= 0.0 and heights.max() <= 1.0
        assert np.allclose(heights * 2 * A - A, grid, atol=1e-6)
    assert np.all(Environment().hfield_heights(xs, ys, 1.0) == 0.5)


def test_sampled_spectrum_follows_the_target():
    env = Environment(SeaSettings(waves=moderate()))
    w, s = env.sampled_spectrum()
    target = env.spectrum(w)
    dw = env.components.dw
    # the normalisation scales all a_j by one factor: sum S dw = Hs^2/16 exactly, shape = target
    assert abs(np.sum(s) * dw - 0.2**2 / 16) < 1e-15
    ratio = s / np.maximum(target, 1e-300)
    assert np.allclose(ratio[target > 1e-6 * target.max()], ratio[np.argmax(target)], rtol=1e-9)
    assert abs(ratio[np.argmax(target)] - 1) < 0.01


# --- check 7: zero mean and standard deviation of the first-order load -------------------------


def _transfer_amplitudes(env, psi):
    """|H_j| (force per metre of wave amplitude) of X, Y, N from the closed form, numpy + scipy."""
    c, hull, T = env.components, env.hull, env.draft
    L, B = hull.length, hull.beam
    br = c.beta - psi
    kx, ky = c.k * np.cos(br), c.k * np.sin(br)
    f = RHO * G * (1 - np.exp(-c.k * T))
    j0 = lambda u: special.spherical_jn(0, u)  # noqa: E731
    j1 = lambda u: special.spherical_jn(1, u)  # noqa: E731
    P = j0(kx * L / 2) * j0(ky * B / 2)
    hx = f * L * B * np.abs(P * np.cos(br))
    hy = f * L * B * np.abs(P * np.sin(br))
    hn = f * (L * B / 2) * np.abs(L * np.sin(br) * j1(kx * L / 2) * j0(ky * B / 2)
                                  - B * np.cos(br) * j1(ky * B / 2) * j0(kx * L / 2))
    return np.stack([hx, hy, hn])


@pytest.mark.slow
@pytest.mark.parametrize("direction_deg, axis", [(180.0, 0), (90.0, 1)])
def test_first_order_load_has_zero_mean_and_the_transfer_std(direction_deg, axis):
    env = Environment(SeaSettings(waves=moderate(direction_deg=direction_deg)), ramp_time=0.0)
    ts = np.arange(0.0, 1800.0, 0.05)
    rec = env.loads_record(ts, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])[:, lay.L_WAVE1:lay.L_WAVE1 + 3]
    H = _transfer_amplitudes(env, 0.0)
    for i in range(3):
        std_theory = math.sqrt(np.sum((env.components.a * H[i]) ** 2) / 2)
        std = np.std(rec[:, i])
        assert abs(np.mean(rec[:, i])) < 0.01 * std
        assert abs(std / std_theory - 1) < 0.03, (i, std, std_theory)
    assert np.std(rec[:, axis]) > np.std(rec[:, 1 - axis])


# --- check 8: encounter frequency ----------------------------------------------------------------


def test_head_wave_encountered_at_1_m_per_s():
    w, U = math.pi, 1.0
    env = regular_env(0.05, w, math.pi)
    ts = np.arange(0.0, 600.0, 0.05)
    etas = np.stack([U * ts, np.zeros_like(ts), np.zeros_like(ts)], axis=1)
    X = env.loads_record(ts, etas, [U, 0.0, 0.0])[:, lay.L_WAVE1]
    spec = np.abs(np.fft.rfft(X * np.hanning(len(X))))
    freqs = np.fft.rfftfreq(len(X), 0.05) * 2 * math.pi
    i = int(np.argmax(spec))
    # parabolic refinement of the peak
    d = 0.5 * (spec[i - 1] - spec[i + 1]) / (spec[i - 1] - 2 * spec[i] + spec[i + 1])
    peak = freqs[i] + d * (freqs[1] - freqs[0])
    expected = w + w**2 * U / G
    assert abs(expected - 4.148) < 1e-3
    assert abs(peak / expected - 1) < 0.01


# --- check 9: drift ------------------------------------------------------------------------------


def test_thin_barrier_reflection_limits_and_monotone():
    assert thin_barrier_reflection(np.array([1e-4]))[0] < 1e-6
    assert thin_barrier_reflection(np.array([3.0]))[0] > 0.9999
    kt = np.logspace(-4, 2.5, 2000)
    r2 = thin_barrier_reflection(kt)
    assert np.all(np.diff(r2) >= 0) and np.all((r2 >= 0) & (r2 <= 1))
    # against the unscaled Bessel formula where it is representable
    k = np.array([0.01, 0.3, 1.0, 3.0, 10.0])
    direct = np.pi**2 * special.iv(1, k) ** 2 / (np.pi**2 * special.iv(1, k) ** 2 + special.kv(1, k) ** 2)
    assert np.allclose(thin_barrier_reflection(k), direct, rtol=1e-12)


def test_regular_head_wave_mean_drift_is_half_rho_g_a2_b():
    env0 = Environment()
    k = 3.0 / env0.draft
    a = 0.02
    env = regular_env(a, math.sqrt(G * k), math.pi, drift="newman")
    ts = np.linspace(0.0, 20.0, 401)
    rec = env.loads_record(ts, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])[:, lay.L_DRIFT:lay.L_DRIFT + 3]
    expected = -0.5 * RHO * G * a**2 * env.hull.beam
    assert abs(np.mean(rec[:, 0]) / expected - 1) < 0.01
    assert np.max(np.abs(rec[:, 1:])) < 1e-9 * abs(expected)
    env_mean = regular_env(a, math.sqrt(G * k), math.pi, drift="mean")
    assert abs(env_mean.loads(3.0, [0, 0, 0], [0, 0, 0]).tau_drift[0] / expected - 1) < 0.01
    env_off = regular_env(a, math.sqrt(G * k), math.pi, drift="off")
    assert np.all(env_off.loads(3.0, [0, 0, 0], [0, 0, 0]).tau_drift == 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("direction_deg, axis, sign", [(0.0, 0, 1.0), (90.0, 1, 1.0), (180.0, 0, -1.0)])
def test_irregular_drift_mean_and_direction(direction_deg, axis, sign):
    env = Environment(SeaSettings(waves=moderate(direction_deg=direction_deg)), ramp_time=0.0)
    ts = np.arange(0.0, 1800.0, 0.05)
    rec = env.loads_record(ts, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])[:, lay.L_DRIFT:lay.L_DRIFT + 3]
    c = env.components
    kt = c.k * env.draft
    r2 = np.pi**2 * special.iv(1, kt) ** 2 / (np.pi**2 * special.iv(1, kt) ** 2 + special.kv(1, kt) ** 2)
    q = 0.5 * RHO * G * r2
    cb, sb = np.cos(c.beta), np.sin(c.beta)
    expected = np.array([np.sum(c.a**2 * q * env.hull.beam * cb * np.abs(cb)),
                         np.sum(c.a**2 * q * env.hull.length * sb * np.abs(sb))])
    assert abs(np.mean(rec[:, axis]) / expected[axis] - 1) < 0.05
    assert sign * np.mean(rec[:, axis]) > 0  # down-wave
    # SEA.md §3.5: small in the preset sea [0.20 N head, 0.50 N beam]
    assert 0.05 < abs(expected[axis]) < 1.0


# --- check 10: current carries the hull (analytic RK4) --------------------------------------------


def _current_env(sigma=0.0):
    return Environment(SeaSettings(current=CurrentSettings(speed=0.3, direction_deg=30.0, sigma=sigma)),
                       t_max=200.0)


def test_hull_moving_with_the_current_stays_with_it():
    env = _current_env()
    ep, waves, cg, wg = env.packed
    vc, _ = env.current(0.0)
    psi0 = 0.4
    c, s = math.cos(psi0), math.sin(psi0)
    nu0 = [c * vc[0] + s * vc[1], -s * vc[0] + c * vc[1], 0.0]
    x0 = np.array([1.0, 2.0, psi0, *nu0])
    x = sea_rk4_advance(BARE, NO_DIST, ep, waves, cg, wg, 0.0, x0, 0.0, 0.0, 0.01, 10_000)
    assert np.max(np.abs(x[:2] - (x0[:2] + 100.0 * vc))) < 1e-6


def test_relative_velocity_decays_from_rest_with_yaw_rate():
    env = _current_env()
    ep, waves, cg, wg = env.packed
    x = sea_rk4_advance(BARE, NO_DIST, ep, waves, cg, wg, 0.0, np.array([0, 0, 0, 0, 0, 0.5]), 0.0, 0.0,
                        0.01, 12_000)
    nu_c = env.loads(120.0, x[:3], x[3:]).nu_c
    assert np.linalg.norm(x[3:] - nu_c) < 1e-3


def test_varying_current_derivative_is_the_slope_of_its_interpolant():
    env = _current_env(sigma=0.05)
    assert env.packed.current_grid.shape[0] > 200
    for t in [0.3, 17.5, 99.9, 150.25]:
        h = 1e-4
        v_plus, _ = env.current(t + h)
        v_minus, _ = env.current(t - h)
        _, vdot = env.current(t)
        assert np.allclose((v_plus - v_minus) / (2 * h), vdot, atol=1e-9)
    # nu_c_dot = [r v_cb, -r u_cb] + R^T v_c_dot
    eta, nu = np.array([0.0, 0.0, 0.7]), np.array([0.2, 0.1, 0.3])
    ld = env.loads(42.5, eta, nu)
    vc, vdot = env.current(42.5)
    c, s = math.cos(0.7), math.sin(0.7)
    ub, vb = c * vc[0] + s * vc[1], -s * vc[0] + c * vc[1]
    want = [0.3 * vb + c * vdot[0] + s * vdot[1], -0.3 * ub - s * vdot[0] + c * vdot[1], 0.0]
    assert np.allclose(ld.nu_c, [ub, vb, 0.0], atol=1e-15) and np.allclose(ld.nu_c_dot, want, atol=1e-15)


# --- check 11: wind ------------------------------------------------------------------------------


def _wind_env(speed, direction_deg):
    return Environment(SeaSettings(wind=WindSettings(speed=speed, direction_deg=direction_deg)))


def _tau_wind(speed, direction_deg, psi=0.0, nu=(0.0, 0.0, 0.0)):
    return _wind_env(speed, direction_deg).loads(1.0, [0.0, 0.0, psi], nu).tau_wind


def test_wind_quadratic_in_speed_and_signs():
    for d in [0.0, 37.0, 90.0, 150.0, 180.0, 260.0]:
        t1, t2 = _tau_wind(5.0, d), _tau_wind(10.0, d)
        assert np.allclose(t2, 4 * t1, rtol=1e-9, atol=1e-12)
    head = _tau_wind(5.0, 180.0)     # air from the bow (flowing toward -x)
    assert head[0] < 0 and abs(head[1]) < 1e-9 and abs(head[2]) < 1e-9
    assert abs(head[0] - (-0.5 * 1.225 * 25 * 0.55 * 0.25)) < 1e-9   # -2.1 N
    astern = _tau_wind(5.0, 0.0)
    assert astern[0] > 0 and abs(astern[1]) < 1e-9
    beam = _tau_wind(5.0, 90.0)      # air flowing toward +y_b
    assert beam[1] > 0 and abs(beam[0]) < 1e-9 and abs(beam[2]) < 1e-9
    assert abs(beam[1] / 8.27 - 1) < 0.01
    # with the hull turned, body-frame loads follow the relative direction
    assert np.allclose(_tau_wind(5.0, 90.0 + 30.0, psi=math.radians(30.0)), beam, atol=1e-9)


@pytest.mark.parametrize("delta_deg", [10.0, 45.0, 80.0, 100.0, 135.0, 170.0])
def test_wind_y_and_n_odd_x_even_in_gamma(delta_deg):
    plus, minus = _tau_wind(5.0, 180.0 + delta_deg), _tau_wind(5.0, 180.0 - delta_deg)
    assert abs(plus[0] - minus[0]) < 1e-9
    assert abs(plus[1] + minus[1]) < 1e-9 and abs(plus[2] + minus[2]) < 1e-9
    assert abs(plus[1]) > 0.1


def test_wind_zero_speed_gives_exactly_zero_on_a_moving_hull():
    env = _wind_env(5.0, 90.0)
    ep = env.packed.ep.copy()
    ep[lay.E_WIND_MEAN] = 0.0
    for nu in [(0.5, 0.1, 0.2), (-0.3, 0.4, -1.0), (2.0, 0.0, 0.0)]:
        assert wind_load(ep, np.zeros((0, 1)), 3.0, 0.7, nu[0], nu[1]) == (0.0, 0.0, 0.0)


# --- check 12: gusts -----------------------------------------------------------------------------


@pytest.mark.slow
def test_gust_statistics_over_ten_hours():
    wind = WindSettings(speed=5.0, direction_deg=90.0, gust_sigma=1.0, gust_time_constant=2.0, seed=2)
    env = Environment(SeaSettings(wind=wind), t_max=36_000.0)
    ts = np.arange(0.0, 36_000.0, 0.05)
    v = env.wind_speed(ts)
    assert abs(np.mean(v) - 5.0) < 0.05 * 1.0
    assert abs(np.std(v) / 1.0 - 1) < 0.05
    g = v - np.mean(v)
    lag = 40  # T_g / 0.05 s
    rho = np.dot(g[:-lag], g[lag:]) / np.dot(g, g)
    assert abs(rho - math.exp(-1)) < 0.05


def test_gusts_identical_at_rk4_and_substep_times_and_independent_of_history():
    wind = WindSettings(speed=5.0, direction_deg=90.0, gust_sigma=1.0, seed=2)
    a = Environment(SeaSettings(wind=wind), t_max=10.0)
    b = Environment(SeaSettings(wind=wind), t_max=5000.0)
    h = 1e-3
    stage_times = np.array([k * h + c for k in range(3000) for c in (0.0, 0.5 * h, h)])
    substep_times = np.arange(0, 6000) * (0.5 * h)
    first = a.wind_speed(stage_times)
    shuffled = np.random.default_rng(0).permutation(len(stage_times))
    again = np.empty_like(first)
    again[shuffled] = b.wind_speed(stage_times[shuffled])
    assert np.array_equal(first, again)
    # the times the two integrators share give the same values, and the field is continuous
    common = np.intersect1d(stage_times, substep_times)
    assert len(common) > 2000
    assert np.array_equal(a.wind_speed(common), b.wind_speed(common))
    assert np.max(np.abs(np.diff(a.wind_speed(substep_times)))) < 0.05
    # a horizon past the first grid is generated on demand, identically
    assert np.array_equal(a.wind_speed(np.array([4321.5])), b.wind_speed(np.array([4321.5])))


# --- check 13: plausibility of an unpowered hull in the preset sea --------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("direction_deg", [180.0, 90.0])
def test_unpowered_hull_in_the_preset_sea(direction_deg):
    env = Environment(SeaSettings(waves=moderate(direction_deg=direction_deg)), t_max=310.0)
    ep, waves, cg, wg = env.packed
    h, every = 0.005, 10
    traj = sea_rk4_trajectory(BARE, NO_DIST, ep, waves, cg, wg, 0.0, np.zeros(6), 0.0, 0.0, h, 60_000, every)
    assert np.all(np.isfinite(traj))
    fs = 1.0 / (h * every)
    sos = signal.butter(4, 0.25, "highpass", fs=fs, output="sos")
    keep = slice(int(20 * fs), None)
    hp = signal.sosfiltfilt(sos, traj[:, :2], axis=0)[keep]
    std_xy = math.sqrt(np.var(hp[:, 0]) + np.var(hp[:, 1]))
    assert std_xy <= 0.2 / 4
    assert std_xy > 1e-3  # the waves do move the hull
    start, end = traj[int(20 * fs), :2], traj[-1, :2]
    assert np.linalg.norm(end - start) / 280.0 < 0.03
