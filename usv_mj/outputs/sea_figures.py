"""Figures and summary fields of a run in a sea (docs/sea.md §3, §7), from a finished run and its
:class:`usv_mj.physics.sea.Environment`.

- :func:`spectrum_figure`: the spectrum the sampled components carry (a_j^2 / (2 dw) at w_j, docs/sea.md
  §3.2) against the target JONSWAP S(w) (§3.1), with Hs of both.
- :func:`loads_figure`: the environment loads over the run, body frame, evaluated on the recorded
  state (``Environment.loads_record``; pure in (t, eta, nu), so these are the loads that acted):
  s tau_wave1, s^2 tau_drift and tau_wind in X [N], Y [N], N [N m], and the elevation zeta at the
  hull [m] with the current speed [m/s].
- :func:`sea_summary`: ``{"sea": settings dict, "hs_at_hull_m": 4 std(zeta at the hull)}`` for
  summary.json.
- :func:`draw_sea_figures`: both figures into a folder.

Drawing is deterministic (no timestamps in the PNGs). ``record`` is a :class:`usv_mj.record.run_record.RunRecord`
(columns ``t, x, y, psi, u, v, r``), live or read back from a log.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from usv_mj.record.store import CHUNK_ROWS  # noqa: E402
from usv_mj.physics.sea import layout as lay  # noqa: E402

SPECTRUM_FIGURE = "sea_spectrum.png"
LOADS_FIGURE = "sea_loads.png"
MAX_LOAD_POINTS = 6000   # recorded rows drawn in the loads figure (decimated evenly)
_PNG_META = {"Software": None}


def _check_env(env, where: str):
    if env is None or not hasattr(env, "loads_record"):
        raise TypeError(f"{where}: env must be a usv_mj.physics.sea.Environment, got {type(env).__name__}")


def _strided(record, name: str, stride: int, lo: int = 0, hi: int | None = None) -> np.ndarray:
    """Rows lo, lo + stride, ... (< hi) of a column, read chunk by chunk (a stored record stays on disk)."""
    hi = len(record) if hi is None else hi
    out, at = [], 0
    for chunk in record.column_chunks(name):
        a, b = max(lo, at), min(hi, at + len(chunk))
        if a < b:
            first = a + (-(a - lo)) % stride
            out.append(chunk[first - at:b - at:stride])
        at += len(chunk)
        if at >= hi:
            break
    return np.ascontiguousarray(np.concatenate(out)) if out else np.empty(0)


def _state_columns(record, where: str, stride: int = 1, lo: int = 0, hi: int | None = None):
    n = len(record)
    if n == 0:
        raise ValueError(f"{where}: the record has no rows")
    ts = _strided(record, "t", stride, lo, hi)
    etas = np.ascontiguousarray(np.stack([_strided(record, c, stride, lo, hi) for c in ("x", "y", "psi")], axis=1))
    nus = np.ascontiguousarray(np.stack([_strided(record, c, stride, lo, hi) for c in ("u", "v", "r")], axis=1))
    finite = np.isfinite(ts) & np.all(np.isfinite(etas), axis=1) & np.all(np.isfinite(nus), axis=1)
    if not np.all(finite):  # a diverged run's last row, say: keep the rows before it
        bad = int(np.flatnonzero(~finite)[0])
        if bad == 0 and lo == 0:
            raise ValueError(f"{where}: the record's first row has a non-finite time or state")
        ts, etas, nus = ts[:bad], etas[:bad], nus[:bad]
    return ts, etas, nus


def hull_elevation(record, env) -> tuple[np.ndarray, np.ndarray]:
    """(t [s], zeta [m]): the elevation zeta(x(t), y(t), t) at the hull origin over the run (all rows)."""
    _check_env(env, "hull_elevation")
    ts, etas, _ = _state_columns(record, "hull_elevation")
    return ts, np.asarray(env.elevation(etas[:, 0], etas[:, 1], ts), dtype=float).reshape(ts.shape)


def sea_summary(record, env) -> dict:
    """The summary.json fields of a run in a sea.

    ``sea``: the settings as the nested ``[sea]`` dict (None without an environment);
    ``hs_at_hull_m``: 4 x the standard deviation of zeta at the hull position over the run [m]
    (docs/sea.md §3 elevation with its start-up ramp, evaluated at every recorded row, chunk by chunk:
    the mean, then the mean square deviation; 0 in calm water).
    """
    if env is None:
        return {"sea": None, "hs_at_hull_m": 0.0}
    _check_env(env, "sea_summary")
    settings = env.settings.to_dict()
    if env.components.n == 0 or len(record) == 0:
        return {"sea": settings, "hs_at_hull_m": 0.0}
    total, count, pieces = 0.0, 0, []
    for lo in range(0, len(record), CHUNK_ROWS):
        ts, etas, _ = _state_columns(record, "sea_summary", 1, lo, lo + CHUNK_ROWS)
        zeta = np.asarray(env.elevation(etas[:, 0], etas[:, 1], ts), dtype=float).reshape(ts.shape)
        pieces.append((lo, len(ts)))
        total, count = total + float(np.sum(zeta)), count + len(ts)
        if len(ts) < min(CHUNK_ROWS, len(record) - lo):   # a non-finite row: the rows before it
            break
    mean, square = total / count, 0.0
    for lo, m in pieces:   # second pass: the deviations from the mean (as np.std)
        ts, etas, _ = _state_columns(record, "sea_summary", 1, lo, lo + m)
        zeta = np.asarray(env.elevation(etas[:, 0], etas[:, 1], ts), dtype=float).reshape(ts.shape)
        square += float(np.sum((zeta - mean) ** 2))
    return {"sea": settings, "hs_at_hull_m": float(4.0 * np.sqrt(square / count))}


def spectrum_figure(env, path) -> Path | None:
    """Sampled against target spectrum [m^2 s/rad] over w [rad/s]; None (nothing written) without waves."""
    _check_env(env, "spectrum_figure")
    w_s, s_s = env.sampled_spectrum()
    if w_s.size == 0:
        return None
    ws = env.settings.waves
    wp = 2.0 * math.pi / ws.tp
    w = np.linspace(0.2 * wp, 5.0 * wp, 2000)
    target = env.spectrum(w)
    hs_target = 4.0 * math.sqrt(np.trapezoid(env.spectrum(np.linspace(0.01, 40.0, 200001)),
                                             np.linspace(0.01, 40.0, 200001)))
    hs_sampled = 4.0 * math.sqrt(float(np.sum(env.components.a ** 2) / 2.0))
    fig, ax = plt.subplots(figsize=(8, 4.8))
    ax.plot(w, target, "k", lw=1.6, label=f"target JONSWAP (Hs {hs_target:.3f} m)")
    ax.plot(w_s, s_s, ".", color="C0", ms=5,
            label=f"sampled, {w_s.size} components (Hs {hs_sampled:.3f} m)")
    ax.axvline(wp, color="0.6", ls=":", lw=1)
    ax.set_xlabel("w [rad/s]")
    ax.set_ylabel("S(w) [m^2 s/rad]")
    ax.set_title(f"Wave spectrum: Hs {ws.hs:g} m, Tp {ws.tp:g} s, gamma {ws.gamma:g}, "
                 f"{'cos^2 spread' if ws.spreading else 'long-crested'}, seed {ws.seed}")
    ax.legend(loc="upper right")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110, metadata=_PNG_META)
    plt.close(fig)
    return path


def loads_figure(record, env, path, max_points: int = MAX_LOAD_POINTS) -> Path:
    """The loads over the run on the recorded state (decimated to about ``max_points`` rows)."""
    _check_env(env, "loads_figure")
    stride = max(1, len(record) // max(1, int(max_points)))
    ts, etas, nus = _state_columns(record, "loads_figure", stride)
    loads = env.loads_record(ts, etas, nus)
    zeta = np.asarray(env.elevation(etas[:, 0], etas[:, 1], ts), dtype=float).reshape(ts.shape)
    current = np.hypot(loads[:, lay.L_NU_C], loads[:, lay.L_NU_C + 1])
    fig, axes = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
    for i, (name, unit) in enumerate((("X", "N"), ("Y", "N"), ("N", "N m"))):
        ax = axes[i]
        ax.plot(ts, loads[:, lay.L_WAVE1 + i], color="C0", lw=0.8, label="waves, first order")
        ax.plot(ts, loads[:, lay.L_DRIFT + i], color="C1", lw=1.0, label="wave drift")
        ax.plot(ts, loads[:, lay.L_WIND + i], color="C2", lw=1.0, label="wind")
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(True, alpha=0.3)
        if i == 0:
            ax.legend(loc="upper right", fontsize=8, ncol=3)
    ax = axes[3]
    ax.plot(ts, zeta, color="C0", lw=0.8, label="zeta at the hull [m]")
    ax.set_ylabel("zeta [m]")
    ax.grid(True, alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(ts, current, color="C3", lw=1.2, label="current speed [m/s]")
    ax2.set_ylabel("current [m/s]", color="C3")
    ax.set_xlabel("t [s]")
    hs = 4.0 * float(np.std(zeta))
    fig.suptitle(f"Environment loads on the hull, body frame (every {stride} rows; Hs at the hull "
                 f"{hs:.3f} m from these rows)")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110, metadata=_PNG_META)
    plt.close(fig)
    return path


def draw_sea_figures(record, env, out_dir) -> list[Path]:
    """Write :data:`SPECTRUM_FIGURE` (when there are waves) and :data:`LOADS_FIGURE` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    spec = spectrum_figure(env, out / SPECTRUM_FIGURE)
    if spec is not None:
        paths.append(spec)
    paths.append(loads_figure(record, env, out / LOADS_FIGURE))
    return paths
