"""The sea as pure functions of (t, eta, nu): :class:`Environment` and its packed kernel (docs/sea.md §1).

All random numbers are drawn at construction: waves from ``SeedSequence(waves.seed).spawn(3)[0]``,
current from ``SeedSequence(waves.seed).spawn(3)[2]`` and gusts from
``SeedSequence(wind.seed).spawn(3)[1]`` (docs/sea.md §0: one stream each, so switching one load on never
changes another; the current has no seed key of its own and rides on the wave seed's third stream).
Nothing advances inside :func:`environment_loads`: RK4 stages, MuJoCo sub-steps and the renderer see
identical fields at identical times.

Calling from a native callback: take ``env.packed`` (after ``env.ensure_horizon(t_end)``) and call
``environment_loads(ep, waves, current_grid, wind_grid, t, eta, nu)`` or, for the whole right-hand
side, :func:`usv_mj.physics.sea.dynamics.sea_force` / ``sea_state_derivative``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from usv_mj.physics.ship import RigidBodySplit, ShipParams

from usv_mj.physics.sea import layout as lay
from usv_mj.physics.sea.current import CURRENT_GRID_STEP, OrnsteinUhlenbeckGrid, current_at
from usv_mj.physics.sea.settings import HullGeometry, SeaSettings
from usv_mj.physics.sea.waves import (WaveComponents, jonswap_spectrum, pack_waves, ramp_factor,
                    sample_wave_components, wave_loads)
from usv_mj.physics.sea.wind import BLENDERMANN_SPEED_BOAT, WIND_GRID_STEP, wind_load, wind_speed_at, wind_speed_record

DEFAULT_RAMP_TIME = 2.0  # s, tau_ramp of docs/sea.md §3 (as VRX)
_DRIFT_CODES = {"off": lay.DRIFT_OFF, "mean": lay.DRIFT_MEAN, "newman": lay.DRIFT_NEWMAN}


@njit(cache=True)
def _elevation_sum(a, w, kx, ky, eps, ts, xs, ys):
    """sum_j a_j cos(w_j t - kx_j x - ky_j y + eps_j) per point (one loop: about 10x faster per
    point than numpy's outer products, e.g. for every row of a log)."""
    out = np.empty(ts.shape[0])
    for i in range(ts.shape[0]):
        acc = 0.0
        for j in range(a.shape[0]):
            acc += a[j] * math.cos(ts[i] * w[j] - xs[i] * kx[j] - ys[i] * ky[j] + eps[j])
        out[i] = acc
    return out


class PackedEnvironment(NamedTuple):
    """The four arrays the kernels take (layout in :mod:`usv_mj.physics.sea.layout`)."""

    ep: np.ndarray
    waves: np.ndarray
    current_grid: np.ndarray
    wind_grid: np.ndarray


class EnvLoads(NamedTuple):
    """Environment at one (t, eta, nu), body frame (docs/sea.md §1).

    nu_c: current [u_c, v_c, 0] [m/s]; nu_c_dot: [r v_cb, -r u_cb, 0] + R^T v_c_dot [m/s^2];
    tau_wind [N, N, N m]; tau_wave1 = s(t) x first-order wave load; tau_drift = s(t)^2 x drift
    (the ramp is applied: these are the loads that act).
    """

    nu_c: np.ndarray
    nu_c_dot: np.ndarray
    tau_wind: np.ndarray
    tau_wave1: np.ndarray
    tau_drift: np.ndarray

    @property
    def tau_env(self) -> np.ndarray:
        """tau_wind + s tau_wave1 + s^2 tau_drift [N, N, N m]."""
        return self.tau_wind + self.tau_wave1 + self.tau_drift


@njit(cache=True)
def environment_loads(ep, waves, current_grid, wind_grid, t, eta, nu):
    """The 15-vector of :mod:`usv_mj.physics.sea.layout` (L_*): nu_c, nu_c_dot, tau_wind, s tau_wave1, s^2 tau_drift.

    nu_c = [R(psi)^T v_c(t); 0]; nu_c_dot = [r v_cb, -r u_cb, 0] + [R(psi)^T v_c_dot(t); 0];
    tau_wind from absolute nu; waves from the hull position (docs/sea.md §1, §3-5). Pure in (t, eta, nu).
    """
    out = np.zeros(lay.N_LOADS)
    psi = eta[2]
    if ep[lay.E_CURRENT_ON] != 0.0:
        c, s = math.cos(psi), math.sin(psi)
        vx, vy, ax, ay = current_at(ep, current_grid, t)
        ucb = c * vx + s * vy
        vcb = -s * vx + c * vy
        r = nu[2]
        out[lay.L_NU_C] = ucb
        out[lay.L_NU_C + 1] = vcb
        out[lay.L_NU_C_DOT] = r * vcb + (c * ax + s * ay)
        out[lay.L_NU_C_DOT + 1] = -r * ucb + (-s * ax + c * ay)
    if ep[lay.E_WIND_ON] != 0.0:
        wx, wy, wn = wind_load(ep, wind_grid, t, psi, nu[0], nu[1])
        out[lay.L_WIND] = wx
        out[lay.L_WIND + 1] = wy
        out[lay.L_WIND + 2] = wn
    if ep[lay.E_WAVES_ON] != 0.0:
        sr = ramp_factor(ep[lay.E_RAMP], t)
        x1, y1, n1, xd, yd, nd = wave_loads(ep, waves, t, eta[0], eta[1], psi)
        out[lay.L_WAVE1] = sr * x1
        out[lay.L_WAVE1 + 1] = sr * y1
        out[lay.L_WAVE1 + 2] = sr * n1
        s2 = sr * sr
        out[lay.L_DRIFT] = s2 * xd
        out[lay.L_DRIFT + 1] = s2 * yd
        out[lay.L_DRIFT + 2] = s2 * nd
    return out


@njit(cache=True)
def environment_loads_record(ep, waves, current_grid, wind_grid, ts, etas, nus):
    """environment_loads at many (t_i, eta_i, nu_i): rows of the 15-vector (for records and tests)."""
    n = ts.shape[0]
    out = np.empty((n, lay.N_LOADS))
    for i in range(n):
        out[i, :] = environment_loads(ep, waves, current_grid, wind_grid, ts[i], etas[i], nus[i])
    return out


class Environment:
    """Waves, current and wind as pure functions (docs/sea.md §1 API).

    Parameters
    ----------
    settings:
        :class:`SeaSettings` (calm by default).
    hull:
        :class:`HullGeometry` (docs/sea.md §2 defaults); its draft defaults to m_RB / (rho_w L B).
    ship:
        The ship whose rigid mass sets the equivalent draft (default :class:`ShipParams`).
    t_max:
        Horizon [s] the OU grids are generated to at once; :meth:`ensure_horizon` extends them (the
        Python methods extend on demand; the kernels hold the last value past the end).
    ramp_time:
        tau_ramp [s] of s(t) = 1 - exp(-t / tau_ramp) on the waves; 0 switches the ramp off.
    wave_components:
        Replaces the sampled components (e.g. :meth:`WaveComponents.regular`); the settings' drift
        mode still applies.
    """

    def __init__(self, settings: SeaSettings | None = None, *, hull: HullGeometry | None = None,
                 ship: ShipParams | None = None, t_max: float = 600.0,
                 ramp_time: float = DEFAULT_RAMP_TIME, wave_components: WaveComponents | None = None):
        self.settings = settings if settings is not None else SeaSettings()
        if not isinstance(self.settings, SeaSettings):
            raise TypeError(f"Environment: settings must be SeaSettings, got {type(self.settings).__name__}")
        self.hull = hull if hull is not None else HullGeometry()
        ship = ship if ship is not None else ShipParams()
        if not (math.isfinite(ramp_time) and ramp_time >= 0):
            raise ValueError(f"Environment: ramp_time must be >= 0 s, got {ramp_time!r}")
        if not (math.isfinite(t_max) and t_max >= 0):
            raise ValueError(f"Environment: t_max must be a finite number >= 0 s, got {t_max!r}")
        self.ramp_time = float(ramp_time)
        self.draft = self.hull.box_draft(RigidBodySplit().rigid_body(ship)[0])
        ws, cs, wi = self.settings.waves, self.settings.current, self.settings.wind
        wave_streams = np.random.SeedSequence(ws.seed).spawn(3)
        wind_streams = np.random.SeedSequence(wi.seed).spawn(3)

        if wave_components is None:
            wave_components = sample_wave_components(
                ws.hs, ws.tp, ws.gamma, math.radians(ws.direction_deg), ws.spreading, ws.components,
                np.random.default_rng(wave_streams[0]), g=self.hull.g)
        self.components = wave_components
        self._waves = pack_waves(wave_components, self.draft, self.hull.rho_water, self.hull.g,
                                 self.hull.diffraction_factor)
        self._current_ou = (OrnsteinUhlenbeckGrid(wave_streams[2], CURRENT_GRID_STEP, cs.time_constant, 2)
                            if cs.sigma > 0 else None)
        self._gust_ou = (OrnsteinUhlenbeckGrid(wind_streams[1], WIND_GRID_STEP, wi.gust_time_constant, 1)
                         if wi.gust_sigma > 0 else None)
        self._ep = self._pack_params()
        self._current_grid = np.zeros((0, 2))
        self._wind_grid = np.zeros((0, 1))
        self._horizon = -1.0
        self.ensure_horizon(t_max)
        self._grid_cache: dict = {}

    # --- packing ---------------------------------------------------------------------------------
    def _pack_params(self) -> np.ndarray:
        h, cs, wi = self.hull, self.settings.current, self.settings.wind
        ep = np.zeros(lay.N_ENV_PARAMS)
        ep[lay.E_LENGTH], ep[lay.E_BEAM], ep[lay.E_DRAFT] = h.length, h.beam, self.draft
        ep[lay.E_BOX_X] = h.box_center_x
        ep[lay.E_RAMP] = self.ramp_time
        ep[lay.E_DRIFT_MODE] = _DRIFT_CODES[self.settings.waves.drift]
        ep[lay.E_WAVES_ON] = 1.0 if self.components.n > 0 and np.any(self.components.a > 0) else 0.0
        ep[lay.E_CURRENT_ON] = 1.0 if cs.active else 0.0
        cdir = math.radians(cs.direction_deg)
        ep[lay.E_CURRENT_X] = cs.speed * math.cos(cdir)
        ep[lay.E_CURRENT_Y] = cs.speed * math.sin(cdir)
        ep[lay.E_CURRENT_DT] = CURRENT_GRID_STEP
        ep[lay.E_WIND_ON] = 1.0 if wi.active else 0.0
        ep[lay.E_WIND_MEAN] = wi.speed
        wdir = math.radians(wi.direction_deg)
        ep[lay.E_WIND_COS], ep[lay.E_WIND_SIN] = math.cos(wdir), math.sin(wdir)
        ep[lay.E_WIND_DT] = WIND_GRID_STEP
        ep[lay.E_RHO_AIR] = h.rho_air
        ep[lay.E_FRONTAL_AREA], ep[lay.E_LATERAL_AREA] = h.frontal_area, h.lateral_area
        ep[lay.E_LENGTH_OVERALL], ep[lay.E_LATERAL_CENTROID] = h.length_overall, h.lateral_centroid
        (ep[lay.E_CDT], ep[lay.E_CDLAF_AHEAD], ep[lay.E_CDLAF_ASTERN],
         ep[lay.E_DELTA]) = BLENDERMANN_SPEED_BOAT
        return ep

    def ensure_horizon(self, t_end: float) -> None:
        """Generate the OU grids to cover [0, t_end] (deterministic: earlier values never change).

        The arrays of :attr:`packed` are replaced when a grid grows: take them again afterwards.
        """
        if t_end <= self._horizon:
            return
        if self._current_ou is not None and self._current_ou.extend_to(t_end):
            self._current_grid = np.ascontiguousarray(self.settings.current.sigma * self._current_ou.values)
        if self._gust_ou is not None and self._gust_ou.extend_to(t_end):
            self._wind_grid = np.ascontiguousarray(self.settings.wind.gust_sigma * self._gust_ou.values)
        ends = [o.t_end for o in (self._current_ou, self._gust_ou) if o is not None]
        self._horizon = min(ends) if ends else math.inf

    @property
    def horizon(self) -> float:
        """Time [s] up to which the OU grids exist (inf without variation)."""
        return self._horizon

    @property
    def packed(self) -> PackedEnvironment:
        """(ep, waves, current_grid, wind_grid) for the kernels (:mod:`usv_mj.physics.sea.layout`)."""
        return PackedEnvironment(self._ep, self._waves, self._current_grid, self._wind_grid)

    @property
    def calm(self) -> bool:
        """True when no load is on (the dynamics then equal usv_mj.physics.ship's bit for bit)."""

        return bool(lay.is_calm(self._ep))

    @property
    def amplitude_bound(self) -> float:
        """A = sum_j a_j [m]: |zeta| <= A everywhere (the hfield scale of docs/sea.md §6)."""
        return float(np.sum(self.components.a))

    def ramp(self, t) -> np.ndarray | float:
        """s(t) of docs/sea.md §3 (vectorised)."""
        t = np.asarray(t, dtype=float)
        if self.ramp_time <= 0:
            return np.ones_like(t) if t.ndim else 1.0
        s = np.where(t > 0, -np.expm1(-np.maximum(t, 0.0) / self.ramp_time), 0.0)
        return s if s.ndim else float(s)

    def sampled_spectrum(self) -> tuple[np.ndarray, np.ndarray]:
        """(w_j [rad/s], a_j^2 / (2 dw) [m^2 s/rad]): the spectrum the components carry (for the
        figure of sampled against target spectrum); empty in calm water or for hand-made components."""
        c = self.components
        if c.n == 0 or c.dw <= 0:
            return np.zeros(0), np.zeros(0)
        order = np.argsort(c.w)
        return c.w[order], c.a[order] ** 2 / (2.0 * c.dw)

    def spectrum(self, w) -> np.ndarray:
        """The target JONSWAP S(w) [m^2 s/rad] of the settings (for the spectrum figure)."""
        ws = self.settings.waves
        return jonswap_spectrum(w, ws.hs, ws.tp, ws.gamma)

    def _check_time(self, t) -> None:
        if isinstance(t, (float, int)):
            if not math.isfinite(t):
                raise ValueError(f"Environment: time must be finite, got {t!r}")
            if t > self._horizon:
                self.ensure_horizon(t + 60.0)
            return
        t = np.asarray(t, dtype=float)
        if not np.all(np.isfinite(t)):
            raise ValueError(f"Environment: time must be finite, got {t!r}")
        tmax = float(np.max(t)) if t.size else 0.0
        if tmax > self._horizon:
            self.ensure_horizon(tmax + 60.0)

    # --- fields ----------------------------------------------------------------------------------
    def elevation(self, x, y, t):
        """zeta(x, y, t) = s(t) sum_j a_j cos(theta_j) [m]; x, y [m], t [s] broadcast together."""
        x, y, t = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float), np.asarray(t, float))
        shape = x.shape
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y)) and np.all(np.isfinite(t))):
            raise ValueError("Environment.elevation: x, y and t must be finite")
        xf, yf, tf = (np.ascontiguousarray(v.ravel()) for v in (x, y, t))
        out = np.zeros(xf.shape)
        c = self.components
        if c.n:
            kx, ky = c.k * np.cos(c.beta), c.k * np.sin(c.beta)
            out = _elevation_sum(np.ascontiguousarray(c.a, float), np.ascontiguousarray(c.w, float),
                                 np.ascontiguousarray(kx), np.ascontiguousarray(ky),
                                 np.ascontiguousarray(c.eps, float), tf, xf, yf) * self.ramp(tf)
        out = out.reshape(shape)
        return float(out) if out.ndim == 0 else out

    def elevation_grid(self, xs, ys, t: float, origin=(0.0, 0.0)) -> np.ndarray:
        """zeta on the grid (origin + (xs[i], ys[l])): array (len(ys), len(xs)), rows along +y [m].

        docs/sea.md §6 fast path: zeta = Re[(E_y diag(a_j e^{i(w_j t + eps_j - k_j . origin)})) E_x^T],
        E_x[i, j] = exp(-i k_j cos(beta_j) xs[i]), E_y[l, j] = exp(-i k_j sin(beta_j) ys[l]): one
        complex matmul a frame (E_x, E_y are cached per (xs, ys)). Equals :meth:`elevation`.
        """
        xs = np.ascontiguousarray(xs, dtype=float)
        ys = np.ascontiguousarray(ys, dtype=float)
        c = self.components
        if c.n == 0:
            return np.zeros((ys.size, xs.size))
        key = (xs.tobytes(), ys.tobytes())
        mats = self._grid_cache.get(key)
        if mats is None:
            kx, ky = c.k * np.cos(c.beta), c.k * np.sin(c.beta)
            ex = np.exp(-1j * np.outer(xs, kx))
            # Re[(E_y c) E_x^T] = [Re(E_y c), -Im(E_y c)] [Re E_x, Im E_x]^T: one real matmul
            ex_stack = np.ascontiguousarray(np.concatenate([ex.real, ex.imag], axis=1).T)
            mats = (ex_stack, np.exp(-1j * np.outer(ys, ky)), kx, ky)
            if len(self._grid_cache) > 8:
                self._grid_cache.clear()
            self._grid_cache[key] = mats
        ex_stack, ey, kx, ky = mats
        phase = c.w * t + c.eps - kx * origin[0] - ky * origin[1]
        coef = c.a * np.exp(1j * phase) * self.ramp(t)
        left = ey * coef
        return np.concatenate([left.real, -left.imag], axis=1) @ ex_stack

    def hfield_heights(self, xs, ys, t: float, origin=(0.0, 0.0)) -> np.ndarray:
        """MuJoCo hfield data (docs/sea.md §6): (zeta + A) / (2 A), A = sum a_j (never clipped), float32,
        shape (len(ys), len(xs)) with rows along +y; 0.5 everywhere in calm water."""
        a_bound = self.amplitude_bound
        if a_bound <= 0:
            return np.full((len(ys), len(xs)), 0.5, dtype=np.float32)
        zeta = self.elevation_grid(xs, ys, t, origin)
        return ((zeta + a_bound) / (2.0 * a_bound)).astype(np.float32)

    def current(self, t) -> tuple[np.ndarray, np.ndarray]:
        """(v_c, v_c_dot): current [m/s] and its derivative [m/s^2] in the earth frame (x, y)."""
        self._check_time(t)
        vx, vy, ax, ay = current_at(self._ep, self._current_grid, float(t))
        return np.array([vx, vy]), np.array([ax, ay])

    def wind(self, t) -> tuple[float, float]:
        """(V_w [m/s], beta_w [rad]): wind speed and going-to direction in the earth frame."""
        self._check_time(t)
        return (float(wind_speed_at(self._ep, self._wind_grid, float(t))),
                math.radians(self.settings.wind.direction_deg))

    def wind_speed(self, ts) -> np.ndarray:
        """V_w at many times [m/s] (vectorised over ``ts``)."""
        ts = np.asarray(ts, dtype=float)
        self._check_time(ts)
        flat = np.ascontiguousarray(ts.ravel())
        return wind_speed_record(self._ep, self._wind_grid, flat).reshape(ts.shape)

    def loads(self, t: float, eta, nu) -> EnvLoads:
        """Environment at (t, eta, nu) (docs/sea.md §1), body frame; see :class:`EnvLoads`."""
        eta = np.ascontiguousarray(eta, dtype=float)
        nu = np.ascontiguousarray(nu, dtype=float)
        if eta.shape != (3,) or nu.shape != (3,):
            raise ValueError(f"Environment.loads: eta and nu must be 3-vectors, got {eta.shape}, {nu.shape}")
        if not (np.all(np.isfinite(eta)) and np.all(np.isfinite(nu))):
            raise ValueError(f"Environment.loads: non-finite state eta={eta}, nu={nu}")
        self._check_time(t)
        out = environment_loads(self._ep, self._waves, self._current_grid, self._wind_grid, float(t), eta, nu)
        return EnvLoads(out[0:3], out[3:6], out[6:9], out[9:12], out[12:15])

    def loads_record(self, ts, etas, nus) -> np.ndarray:
        """The 15-vector of :func:`environment_loads` at many (t_i, eta_i, nu_i): array (n, 15).

        ``etas``, ``nus`` broadcast to (n, 3) (a single pose/velocity for a fixed hull is fine).
        """
        ts = np.ascontiguousarray(ts, dtype=float).ravel()
        etas = np.ascontiguousarray(np.broadcast_to(np.asarray(etas, float), (ts.size, 3)))
        nus = np.ascontiguousarray(np.broadcast_to(np.asarray(nus, float), (ts.size, 3)))
        self._check_time(ts)
        return environment_loads_record(self._ep, self._waves, self._current_grid, self._wind_grid,
                                        ts, etas, nus)


#: a run's sea is made a little past the run's end [s] (its slowly varying grids reach it)
RUN_MARGIN_S = 1.0


def run_sea(settings: SeaSettings, ship: ShipParams, duration: float):
    """The sea of a run of ``duration`` [s] on ``ship`` (its OU grids made to ``duration`` +
    :data:`RUN_MARGIN_S`), or None when ``settings`` is calm: what every plant of a run gets
    (:func:`usv_mj.builder.make_environment`, :func:`usv_mj.attach_hydrodynamics`)."""
    if settings.calm:
        return None
    return Environment(settings, ship=ship, t_max=float(duration) + RUN_MARGIN_S)
