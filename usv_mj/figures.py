"""The paper's Figures 1-7, drawn from finished runs (a RunRecord, live or read back from MCAP).

1. trajectory against the reference; 2-4. the funnel errors e1, e2 (Do & Pan coordinates, Eq. 14)
and e3 (Eq. 15) with the bounds +-rho_i (Eq. 9) and the PI baseline; 5-6. tau_u against Q(tau_u)
and tau_r against Q(tau_r); 7. the norms of the network weights.

Drawing is deterministic (no timestamps in the PNGs), so figures made from the log equal those made
from the live run. Every series is drawn through its min/max envelope (:mod:`usv_mj.decimate`:
the rows of the extremes in about 4000 buckets, read chunk by chunk), so a ten-hour run's figures
keep every spike and need little memory.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .decimate import decimate  # noqa: E402
from .record import RunRecord  # noqa: E402

FIGURES = {
    "fig1_trajectory.png": "Trajectory tracking",
    "fig2_error_x.png": "Tracking error e1 (x) with the funnel",
    "fig3_error_y.png": "Tracking error e2 (y) with the funnel",
    "fig4_error_psi.png": "Heading error e3 with the funnel",
    "fig5_tau_u.png": "Surge force tau_u and Q(tau_u)",
    "fig6_tau_r.png": "Yaw moment tau_r and Q(tau_r)",
    "fig7_weights.png": "Network weight norms",
}
_PNG_META = {"Software": None}
ZOOM_S = 2.0   # s: the first seconds of figures 5-6, drawn row by row


def _save(fig, path: Path) -> None:
    fig.savefig(path, dpi=110, metadata=_PNG_META)
    plt.close(fig)


def draw_figures(record: RunRecord, out_dir, baseline: RunRecord | None = None, obstacles=()) -> list[Path]:
    """Write the seven figures into ``out_dir`` and return their paths (obstacles, with their
    inflated safety boundaries, in the trajectory figure). A record whose controller declares no
    funnel (e, rho, z) gets no figures 2-4, one without the weight norms no figure 7."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    name = str(record.metadata.get("controller", "run")).upper()
    label = f"{name} ({record.metadata.get('plant', '?')} plant)"
    base_name = f"{str(baseline.metadata.get('controller', 'baseline')).upper()}" if baseline is not None else ""

    fig, ax = plt.subplots(figsize=(8, 5))
    ref = decimate(record, ("x_d", "y_d"))
    ax.plot(ref["x_d"], ref["y_d"], "k--", lw=1.2, label="reference")
    path = decimate(record, ("x", "y"))
    ax.plot(path["x"], path["y"], "C0", lw=1.5, label=label)
    if baseline is not None and len(baseline):
        bp = decimate(baseline, ("x", "y"))
        ax.plot(bp["x"], bp["y"], "C3", lw=1.0, alpha=0.8, label=f"{base_name} baseline")
    ax.plot(record.value("x", 0), record.value("y", 0), "o", color="C0", label="start")
    if obstacles:
        from .obstacles.display import draw_obstacles

        per = (record.metadata.get("obstacles") or {}).get("per_obstacle") or []
        inflation = [o.get("inflation_m") for o in per] if per else None
        draw_obstacles(ax, obstacles, inflation=inflation)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    ax.set_title("Fig. 1: trajectory tracking")
    paths.append(out / "fig1_trajectory.png")
    _save(fig, paths[-1])

    for axis, name_, unit, fname in ((1, "x", "m", "fig2_error_x.png"), (2, "y", "m", "fig3_error_y.png"),
                                      (3, "psi", "rad", "fig4_error_psi.png")):
        if not record.has_funnel:  # a controller without a funnel: the plain pose errors
            paths.append(_pose_error_figure(record, baseline, axis, name_, unit, out / fname))
            continue
        fig, ax = plt.subplots(figsize=(8, 4))
        f = decimate(record, ("t", f"rho{axis}"))
        rho = f[f"rho{axis}"]
        ax.fill_between(f["t"], -rho, rho, color="0.85", label=f"funnel ±rho{axis}")
        ax.plot(f["t"], rho, color="0.4", lw=0.8)
        ax.plot(f["t"], -rho, color="0.4", lw=0.8)
        e = decimate(record, ("t", f"e{axis}"))
        ax.plot(e["t"], e[f"e{axis}"], "C0", lw=1.3, label=f"e{axis}, {name}")
        if baseline is not None and len(baseline) and baseline.has_funnel:
            eb = decimate(baseline, ("t", f"e{axis}"))
            ax.plot(eb["t"], eb[f"e{axis}"], "C3", lw=1.0, alpha=0.85, label=f"e{axis}, {base_name}")
        ax.set_xlabel("t [s]")
        what = {"x": "e1 = x̄ - x̄_d", "y": "e2 = ȳ - ȳ_d", "psi": "e3 = ψ - ψ_a"}[name_]
        ax.set_ylabel(f"{what} [{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right")
        ax.set_title(f"Fig. {axis + 1}: tracking error of {name_} in the prescribed-performance funnel")
        paths.append(out / fname)
        _save(fig, paths[-1])

    dt = record.metadata.get("control_period_s") or 0.001
    n_zoom = min(len(record), int(round(ZOOM_S / dt)) + 1)   # rows with t <= 2 s
    zoom = decimate(_Rows(record, n_zoom), ("t", "tau_u", "q_tau_u", "tau_r", "q_tau_r"))
    for col, qcol, unit, fname, num in (("tau_u", "q_tau_u", "N", "fig5_tau_u.png", 5),
                                        ("tau_r", "q_tau_r", "N m", "fig6_tau_r.png", 6)):
        fig, (ax, axz) = plt.subplots(1, 2, figsize=(11, 4), gridspec_kw={"width_ratios": [2, 1]})
        c = decimate(record, ("t", col))
        ax.plot(c["t"], c[col], "C0", lw=0.8, label=col)
        q = decimate(record, ("t", qcol))
        ax.step(q["t"], q[qcol], "C1", lw=0.8, where="post", label=f"Q({col})")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"[{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right")
        axz.plot(zoom["t"], zoom[col], "C0", lw=1.0)
        axz.step(zoom["t"], zoom[qcol], "C1", lw=1.0, where="post")
        axz.set_xlabel("t [s] (first 2 s)")
        axz.grid(alpha=0.3)
        fig.suptitle(f"Fig. {num}: {FIGURES[fname]}")
        fig.tight_layout()
        paths.append(out / fname)
        _save(fig, paths[-1])

    weights = ("w_u_norm", "w_v_norm", "w_r_norm")
    fig, ax = plt.subplots(figsize=(8, 4))
    if all(c in record for c in weights):
        for col, lab in zip(weights, ("|W_u|", "|W_v|", "|W_r|")):
            w = decimate(record, ("t", col))
            ax.plot(w["t"], w[col], lw=1.2, label=lab)
        ax.set_ylabel("weight norm")
        ax.set_title("Fig. 7: neural network weight norms")
    else:  # another controller: its own declared diagnostics (beyond the funnel block)
        from .controllers.base import FUNNEL_FIELDS

        own = [c for c in record.diagnostic_fields if c not in FUNNEL_FIELDS][:8]
        for col in own:
            w = decimate(record, ("t", col))
            ax.plot(w["t"], w[col], lw=1.0, label=col)
        ax.set_ylabel("value")
        ax.set_title(f"Fig. 7: diagnostics declared by the {name} controller"
                     + ("" if own else " (none)"))
    ax.set_xlabel("t [s]")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best")
    paths.append(out / "fig7_weights.png")
    _save(fig, paths[-1])
    return paths


class _Rows:
    """The first ``n`` rows of a record (what :func:`decimate` reads): the zoom of figures 5-6."""

    def __init__(self, record, n: int):
        self.record, self.n = record, n

    def __len__(self):
        return self.n

    def column_chunks(self, name, rows):
        left = self.n
        for chunk in self.record.column_chunks(name, rows):
            if left <= 0:
                return
            yield chunk[:left]
            left -= len(chunk)


def _pose_error(record, name):
    """The kept rows of the pose error ``name`` (x - x_d, y - y_d or wrap(psi - psi_d)), with t."""
    from .summary import pose_errors

    return decimate(record, ("t", "x", "x_d", "y", "y_d", "psi", "psi_d"),
                    lambda c: {"t": c["t"], name: pose_errors(c)[name]})


def _pose_error_figure(record, baseline, axis, name, unit, path):
    """The pose error (x - x_d, y - y_d, wrap(psi - psi_d)) of a run whose controller has no funnel."""
    fig, ax = plt.subplots(figsize=(8, 4))
    err = _pose_error(record, name)
    ax.plot(err["t"], err[name], "C0", lw=1.3, label=f"{name} - {name}_d")
    if baseline is not None and len(baseline):
        eb = _pose_error(baseline, name)
        ax.plot(eb["t"], eb[name], "C3", lw=1.0, alpha=0.85, label="baseline")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"[{unit}]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    ax.set_title(f"Fig. {axis + 1}: pose error in {name} (the controller declares no funnel)")
    _save(fig, path)
    return path


def readme_figure(record: RunRecord, path, baseline: RunRecord | None = None) -> Path:
    """One compact picture for the README: trajectory plus the position funnel."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    ref, path_ = decimate(record, ("x_d", "y_d")), decimate(record, ("x", "y"))
    a.plot(ref["x_d"], ref["y_d"], "k--", lw=1.2, label="reference")
    a.plot(path_["x"], path_["y"], "C0", lw=1.5, label="PPC")
    a.set_aspect("equal", adjustable="datalim")
    a.set_xlabel("x [m]")
    a.set_ylabel("y [m]")
    a.legend()
    a.grid(alpha=0.3)
    f = decimate(record, ("t", "rho1"))
    b.fill_between(f["t"], -f["rho1"], f["rho1"], color="0.85", label="funnel ±rho")
    for col, lab in (("e1", "e1 (x)"), ("e2", "e2 (y)")):
        e = decimate(record, ("t", col))
        b.plot(e["t"], e[col], label=lab)
    if baseline is not None and len(baseline):
        eb = decimate(baseline, ("t", "e2"))
        b.plot(eb["t"], eb["e2"], "C3", alpha=0.7, lw=0.9, label="e2, PI")
    b.set_xlabel("t [s]")
    b.set_ylabel("[m]")
    b.legend()
    b.grid(alpha=0.3)
    fig.tight_layout()
    _save(fig, Path(path))
    return Path(path)


__all__ = ["FIGURES", "draw_figures", "readme_figure"]
