"""Waves: JONSWAP spectrum, sampling, elevation, Froude-Krylov box load and drift (docs/sea.md §3).

Sign conventions (docs/sea.md §0): a component travels toward its going-to direction beta_j in the earth
frame, theta_j = w_j t - k_j (x cos beta_j + y sin beta_j) + eps_j, zeta = s(t) sum_j a_j cos theta_j.
Loads are body-frame generalised forces (X [N], Y [N], N [N m]) about the body origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.physics.sea.layout import (DRIFT_MEAN, DRIFT_NEWMAN, E_BEAM, E_BOX_X, E_DRIFT_MODE, E_LENGTH,
                     N_WAVE_COLS, W_A, W_C, W_COSB, W_EPS, W_K, W_Q, W_SINB, W_W)

FREQUENCY_RANGE = (0.5, 4.0)  # components cover w in [0.5, 4] w_p (docs/sea.md §3)


def jonswap_spectrum(w, hs: float, tp: float, gamma: float) -> np.ndarray:
    """JONSWAP wave spectrum S(w) [m^2 s/rad], DNV-RP-C205 form (MSS waveSpectrum type 7; docs/sea.md §3).

    S(w) = (1 - 0.287 ln gamma) (5/16) Hs^2 wp^4 w^-5 exp(-1.25 (wp/w)^4)
           gamma^exp(-(w - wp)^2 / (2 s^2 wp^2)),  s = 0.07 (w < wp) else 0.09, wp = 2 pi / tp.
    Zero at w <= 0.
    """
    w = np.asarray(w, dtype=float)
    wp = 2.0 * np.pi / tp
    out = np.zeros_like(w)
    pos = w > 0
    wv = w[pos]
    sigma = np.where(wv < wp, 0.07, 0.09)
    peak = gamma ** np.exp(-((wv - wp) ** 2) / (2.0 * sigma**2 * wp**2))
    out[pos] = ((1.0 - 0.287 * np.log(gamma)) * (5.0 / 16.0) * hs**2 * wp**4 * wv**-5
                * np.exp(-1.25 * (wp / wv) ** 4) * peak)
    return out


def spreading_cdf(mu):
    """CDF of the cos^2 spreading (2/pi) cos^2 mu on [-pi/2, pi/2]: F = 1/2 + (mu + sin mu cos mu)/pi."""
    mu = np.asarray(mu, dtype=float)
    return 0.5 + (mu + np.sin(mu) * np.cos(mu)) / np.pi


def spreading_inverse_cdf(p):
    """mu = F^-1(p) of :func:`spreading_cdf` for p in [0, 1] (Newton from a bracketing start, to 1e-14)."""
    p = np.asarray(p, dtype=float)
    mu = (p - 0.5) * np.pi * 0.5  # F is steeper than uniform near 0: start inside
    for _ in range(60):
        f = spreading_cdf(mu) - p
        fp = (2.0 / np.pi) * np.cos(mu) ** 2
        step = f / np.maximum(fp, 1e-300)
        mu = np.clip(mu - step, -np.pi / 2, np.pi / 2)
        if np.all(np.abs(f) < 1e-15):
            break
    return mu


def thin_barrier_reflection(kt):
    """R^2(kT): deep-water reflection coefficient of a thin vertical barrier of draft T (Ursell 1947).

    R^2 = pi^2 I1(kT)^2 / (pi^2 I1(kT)^2 + K1(kT)^2), computed with the exponentially scaled Bessel
    functions so that it neither under- nor overflows (docs/sea.md §3) [T].
    """
    from scipy.special import ive, kve

    kt = np.asarray(kt, dtype=float)
    if np.any(kt <= 0):
        raise ValueError(f"thin_barrier_reflection: kT must be > 0, got min {kt.min()!r}")
    # K1 / (pi I1) = kve e^{-k} / (pi ive e^{k})
    with np.errstate(over="ignore", under="ignore"):
        q = kve(1, kt) / (np.pi * ive(1, kt)) * np.exp(-2.0 * kt)
        return 1.0 / (1.0 + q * q)


@dataclass(frozen=True)
class WaveComponents:
    """The sampled sea: one entry per component (docs/sea.md §3).

    a [m], w [rad/s], k [rad/m] (deep water k = w^2/g), beta [rad] (going-to, earth frame),
    eps [rad] (phase). ``dw`` is the bin width [rad/s] (0 for hand-made components).
    """

    a: np.ndarray
    w: np.ndarray
    k: np.ndarray
    beta: np.ndarray
    eps: np.ndarray
    dw: float = 0.0

    def __post_init__(self) -> None:
        n = len(self.a)
        for name in ("a", "w", "k", "beta", "eps"):
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != (n,) or not np.all(np.isfinite(arr)):
                raise ValueError(f"WaveComponents.{name} must be {n} finite numbers, got shape {arr.shape}")
            object.__setattr__(self, name, arr)
        if np.any(self.a < 0) or np.any(self.k <= 0) or np.any(self.w <= 0):
            raise ValueError("WaveComponents: need a >= 0, w > 0 and k > 0 for every component")

    @property
    def n(self) -> int:
        return len(self.a)

    @classmethod
    def empty(cls) -> "WaveComponents":
        z = np.zeros(0)
        return cls(z, z, z, z, z)

    @classmethod
    def regular(cls, amplitude: float, omega: float, direction: float, phase: float = 0.0,
                g: float = 9.81) -> "WaveComponents":
        """One regular (Airy) deep-water wave: amplitude [m], omega [rad/s], going-to direction [rad]."""
        return cls(np.array([amplitude]), np.array([omega]), np.array([omega**2 / g]),
                   np.array([direction]), np.array([phase]))


def sample_wave_components(hs: float, tp: float, gamma: float, direction: float, spreading: bool,
                           n: int, rng: np.random.Generator, g: float = 9.81) -> WaveComponents:
    """Draw the N components of docs/sea.md §3 from ``rng`` (all draws here, once).

    Equal bins over [0.5, 4] w_p, w_j uniform in bin j, a_j = sqrt(2 S(w_j) dw) scaled so that
    sum a_j^2 / 2 = Hs^2 / 16 exactly, eps_j uniform in [0, 2 pi), k_j = w_j^2 / g (deep water),
    beta_j = direction + mu_j, mu_j = F^-1((p_j + U_j) / N) with p a random permutation (cos^2
    spreading) or mu_j = 0 (long-crested). hs = 0 gives no components (calm).
    The draws are made in a fixed order (w offsets, phases, permutation, offsets) whatever ``spreading``
    and ``hs`` are, so that switching spreading changes directions only.
    """
    if hs <= 0 or n < 1:
        return WaveComponents.empty()
    wp = 2.0 * np.pi / tp
    lo, hi = FREQUENCY_RANGE[0] * wp, FREQUENCY_RANGE[1] * wp
    dw = (hi - lo) / n
    u_w = rng.random(n)
    eps = rng.random(n) * 2.0 * np.pi
    perm = rng.permutation(n)
    u_dir = rng.random(n)
    w = lo + (np.arange(n) + u_w) * dw
    s = jonswap_spectrum(w, hs, tp, gamma)
    a = np.sqrt(2.0 * s * dw)
    total = np.sum(a * a) / 2.0
    target = hs * hs / 16.0
    if total > 0:  # guard the 0/0 of the normalisation (docs/sea.md §0)
        a = a * math.sqrt(target / total)
    if spreading:
        mu = spreading_inverse_cdf((perm + u_dir) / n)
    else:
        mu = np.zeros(n)
    return WaveComponents(a=a, w=w, k=w * w / g, beta=direction + mu, eps=eps, dw=dw)


def pack_waves(comp: WaveComponents, draft: float, rho_water: float, g: float,
               diffraction_factor: float = 1.0) -> np.ndarray:
    """The ``(N_WAVE_COLS, N)`` component array of :mod:`usv_mj.physics.sea.layout` (c_j and q_j precomputed)."""
    out = np.zeros((N_WAVE_COLS, comp.n))
    if comp.n == 0:
        return out
    out[W_A] = comp.a
    out[W_W] = comp.w
    out[W_K] = comp.k
    out[W_COSB] = np.cos(comp.beta)
    out[W_SINB] = np.sin(comp.beta)
    out[W_EPS] = comp.eps
    out[W_C] = diffraction_factor * rho_water * g * comp.a * (1.0 - np.exp(-comp.k * draft))
    out[W_Q] = 0.5 * rho_water * g * thin_barrier_reflection(comp.k * draft)
    return np.ascontiguousarray(out)


# --- kernels -----------------------------------------------------------------------------------


@njit(cache=True)
def ramp_factor(ramp_time, t):
    """s(t) = 1 - exp(-t / tau_ramp) for t > 0 (0 before), 1 when tau_ramp = 0 (docs/sea.md §3)."""
    if ramp_time <= 0.0:
        return 1.0
    if t <= 0.0:
        return 0.0
    return 1.0 - math.exp(-t / ramp_time)


# fast-math flags that keep NaN/inf semantics and a fixed order of operations (no reassoc or contract:
# a kernel inlined into the compiled loop must round as it does alone). Not on fast_sincos.
_FAST = {"nsz", "arcp"}
# Cody-Waite split of pi/2 in three parts (fdlibm pio2_1, pio2_2, pio2_2t; 33 + 33 + 53 bits)
_PIO2_1 = 1.5707963267341256
_PIO2_2 = 6.077100506303966e-11
_PIO2_3 = 2.0222662487959506e-21
FAST_TRIG_LIMIT = 1.0e6  # rad: fast_sincos within 1e-15 of libm below it


# contract only: fused multiply-adds in the polynomials (20 % faster; as exact: the reduction's
# products q * pio2_1 and q * pio2_2 are exact either way). Flags are per instruction, so the
# function rounds the same inlined anywhere.
@njit(cache=True, fastmath={"contract"})
def fast_sincos(x):
    """(sin x, cos x) by Cody-Waite reduction and fdlibm's kernel polynomials, branch-free so that loops
    over components vectorise (|error| < 1e-15 for |x| < FAST_TRIG_LIMIT, about |x| 1e-16 beyond)."""
    q = math.floor(x * 0.6366197723675814 + 0.5)
    y = x - q * _PIO2_1
    y = y - q * _PIO2_2
    y = y - q * _PIO2_3
    z = y * y
    s = y + y * z * (-1.66666666666666324348e-01 + z * (8.33333333332248946124e-03 + z * (
        -1.98412698298579493134e-04 + z * (2.75573137070700676789e-06 + z * (
            -2.50507602534068634195e-08 + z * 1.58969099521155010221e-10)))))
    c = 1.0 - 0.5 * z + z * z * (4.16666666666666019037e-02 + z * (-1.38888888888741095749e-03 + z * (
        2.48015872894767294178e-05 + z * (-2.75573143513906633035e-07 + z * (
            2.08757232129817482790e-09 + z * -1.13596475577881948265e-11)))))
    qi = np.int64(q)
    swap = qi & 1
    sign_s = 1.0 - 2.0 * ((qi >> 1) & 1)
    sign_c = 1.0 - 2.0 * (((qi + 1) >> 1) & 1)
    ss = c if swap else s
    cc = s if swap else c
    return sign_s * ss, sign_c * cc


@njit(cache=True, fastmath=_FAST)
def spherical_j01_from(u, s, c):
    """j0(u) = sin u / u and j1(u) = (sin u - u cos u) / u^2 given s = sin u, c = cos u; the series
    for |u| < 0.1 (branch-free select; one division)."""
    small = abs(u) < 0.1
    u2 = u * u
    j0s = 1.0 - u2 / 6.0 * (1.0 - u2 / 20.0 * (1.0 - u2 / 42.0))
    j1s = u / 3.0 * (1.0 - u2 / 10.0 * (1.0 - u2 / 28.0 * (1.0 - u2 / 54.0)))
    inv = 1.0 / (1.0 if small else u)
    return (j0s if small else s * inv), (j1s if small else (s - u * c) * (inv * inv))


_N_TERMS = 8  # per-component terms of _wave_terms' first pass


@njit(cache=True, fastmath=_FAST)
def _wave_terms(ep, waves, t, x, y, psi):
    """Accumulate the per-component terms of :func:`wave_loads` in two passes: every component's
    phase, Bessel factors and terms first (no sums: LLVM vectorises it over components), then the
    sums in component order (no reassociation, so the result does not depend on where it is inlined)."""
    L, B, xb = ep[E_LENGTH], ep[E_BEAM], ep[E_BOX_X]
    cpsi, spsi = math.cos(psi), math.sin(psi)
    xc = x + cpsi * xb
    yc = y + spsi * xb
    hl, hb = 0.5 * L, 0.5 * B
    lb = L * B
    n = waves.shape[1]
    wa = waves[W_A]
    ww = waves[W_W]
    wk = waves[W_K]
    wcb = waves[W_COSB]
    wsb = waves[W_SINB]
    weps = waves[W_EPS]
    wc = waves[W_C]
    wq = waves[W_Q]
    terms = np.empty((_N_TERMS, n))
    for j in range(n):
        k = wk[j]
        cbr = wcb[j] * cpsi + wsb[j] * spsi  # cos(beta - psi)
        sbr = wsb[j] * cpsi - wcb[j] * spsi  # sin(beta - psi)
        st, ct = fast_sincos(ww[j] * t - k * (xc * wcb[j] + yc * wsb[j]) + weps[j])
        ux = k * cbr * hl
        uy = k * sbr * hb
        sx, cx = fast_sincos(ux)
        sy, cy = fast_sincos(uy)
        j0x, j1x = spherical_j01_from(ux, sx, cx)
        j0y, j1y = spherical_j01_from(uy, sy, cy)
        c = wc[j]
        f = -c * lb * j0x * j0y * st
        a = wa[j]
        q = wq[j]
        terms[0, j] = f * cbr
        terms[1, j] = f * sbr
        terms[2, j] = c * 0.5 * lb * (L * sbr * j1x * j0y - B * cbr * j1y * j0x) * ct
        terms[3, j] = a * ct
        terms[4, j] = a * st
        terms[5, j] = q * B * cbr * abs(cbr)  # the drift coefficients Q_j
        terms[6, j] = q * L * sbr * abs(sbr)
        terms[7, j] = a * a
    X1 = 0.0
    Y1 = 0.0
    N1 = 0.0
    are = 0.0
    aim = 0.0
    qx_re = 0.0
    qx_im = 0.0
    qy_re = 0.0
    qy_im = 0.0
    mx = 0.0
    my = 0.0
    for j in range(n):
        X1 += terms[0, j]
        Y1 += terms[1, j]
        N1 += terms[2, j]
        ac = terms[3, j]
        as_ = terms[4, j]
        qx = terms[5, j]
        qy = terms[6, j]
        are += ac
        aim += as_
        qx_re += qx * ac
        qx_im += qx * as_
        qy_re += qy * ac
        qy_im += qy * as_
        mx += terms[7, j] * qx
        my += terms[7, j] * qy
    return X1, Y1, N1 + xb * Y1, qx_re * are + qx_im * aim, qy_re * are + qy_im * aim, mx, my


@njit(cache=True)
def wave_loads(ep, waves, t, x, y, psi):
    """First-order Froude-Krylov box load and second-order drift, body frame, **no ramp** (docs/sea.md §3).

    Returns (X1, Y1, N1, Xd, Yd, Nd) [N, N, N m]. The phase of each component is taken at the box
    centre (x, y) + R(psi) [x_b, 0]; beta_r = beta_j - psi; k_x = k cos beta_r, k_y = k sin beta_r;
    P = j0(k_x L/2) j0(k_y B/2);
      X_j = -c_j L B P cos(beta_r) sin(theta_j),  Y_j = -c_j L B P sin(beta_r) sin(theta_j),
      N_j = c_j (L B / 2) [L sin(beta_r) j1(k_x L/2) j0(k_y B/2) - B cos(beta_r) j1(k_y B/2) j0(k_x L/2)]
            cos(theta_j) + x_b Y_j.
    Drift: Q_j = q_j [B cos b |cos b|, L sin b |sin b|, x_b L sin b |sin b|], b = beta_r;
    "newman": Re[A_Q conj(A)], A = sum a_j e^{i theta_j}, A_Q = sum a_j Q_j e^{i theta_j};
    "mean": sum a_j^2 Q_j; "off": 0.
    The sines and cosines use :func:`fast_sincos` (vectorised over components; its error, < 1e-15 for
    phases below 1e6 rad, grows like |theta| 1e-16 beyond, as the rounding of theta itself does).
    """
    if waves.shape[1] == 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    X1, Y1, N1, Xn, Yn, Xm, Ym = _wave_terms(ep, waves, t, x, y, psi)
    mode = int(ep[E_DRIFT_MODE])
    xb = ep[E_BOX_X]
    if mode == DRIFT_NEWMAN:
        return X1, Y1, N1, Xn, Yn, xb * Yn
    if mode == DRIFT_MEAN:
        return X1, Y1, N1, Xm, Ym, xb * Ym
    return X1, Y1, N1, 0.0, 0.0, 0.0
