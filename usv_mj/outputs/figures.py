"""The paper's Figures 1-7, drawn from finished runs (a RunRecord, live or read back from MCAP).

1. trajectory against the reference; 2-4. the funnel errors e1, e2 (Do & Pan coordinates, Eq. 14)
and e3 (Eq. 15) with the bounds +-rho_i (Eq. 9) and the PI baseline; 5-6. tau_u against Q(tau_u)
and tau_r against Q(tau_r); 7. the norms of the network weights.

A run judged by another criterion than the funnel (:mod:`usv_mj.record.criteria`) gets in 2-4 the errors
its criterion judges, with the tolerance band from the settling time on (pose tolerance: x - x_d
and y - y_d with the position error norm, and the heading error; path tolerance: the along- and
cross-track errors and the heading error), and in 7 the diagnostics its controller declares;
:func:`figure_titles` gives the titles in each case.

Drawing is deterministic (no timestamps in the PNGs), so figures made from the log equal those made
from the live run. Every series is drawn through its min/max envelope (:mod:`usv_mj.record.decimate`:
the rows of the extremes in about 4000 buckets, read chunk by chunk), so a ten-hour run's figures
keep every spike and need little memory.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from usv_mj.record.decimate import decimate  # noqa: E402
from usv_mj.record.run_record import RunRecord  # noqa: E402

FIGURES = {
    "fig1_trajectory.png": "Trajectory tracking",
    "fig2_error_x.png": "Tracking error e1 (x) with the funnel",
    "fig3_error_y.png": "Tracking error e2 (y) with the funnel",
    "fig4_error_psi.png": "Heading error e3 with the funnel",
    "fig5_tau_u.png": "Surge force tau_u and Q(tau_u)",
    "fig6_tau_r.png": "Yaw moment tau_r and Q(tau_r)",
    "fig7_weights.png": "Network weight norms",
}
_OTHER_TITLES = {
    "pose_tolerance": ("Position error x - x_d with the position tolerance",
                       "Position error y - y_d with the position tolerance",
                       "Heading error with the heading tolerance"),
    "path_tolerance": ("Along-track error with the path tolerance", "Cross-track error with the path tolerance",
                       "Heading error psi - psi_d"),
}
_POSE_TITLES = ("Pose error x - x_d", "Pose error y - y_d", "Heading error psi - psi_d")
_PNG_META = {"Software": None}


def figure_titles(criterion_kind: str, weights: bool) -> dict:
    """The titles of the seven figures of a run judged by ``criterion_kind`` whose record has
    (``weights``) or lacks the network weight norms: :data:`FIGURES` for the paper's controller."""
    titles = dict(FIGURES)
    if criterion_kind != "funnel":
        for name, title in zip(("fig2_error_x.png", "fig3_error_y.png", "fig4_error_psi.png"),
                               _OTHER_TITLES.get(criterion_kind, _POSE_TITLES)):
            titles[name] = title
    if not weights:
        titles["fig7_weights.png"] = "Diagnostics declared by the controller"
    return titles


ZOOM_S = 2.0   # s: the first seconds of figures 5-6, drawn row by row


def save_figure(fig, path: Path, note: str = "") -> None:
    """Write the figure; ``note`` (a log cut or damaged: what was recovered) in red across its top."""
    if note:
        fig.subplots_adjust(top=min(fig.subplotpars.top, 0.84))
        fig.text(0.5, 0.995, textwrap.fill(f"LOG INCOMPLETE: {note}", 110), ha="center", va="top", fontsize=7,
                 color="C3")
    try:
        fig.savefig(path, dpi=110, metadata=_PNG_META)
    except (OverflowError, ValueError):
        huge = _largest_value(fig)
        title = next((ax.get_title() for ax in fig.axes if ax.get_title()), Path(path).stem)
        plt.close(fig)
        if not huge > DRAWABLE:
            raise
        # values near the float range (a reference at 1e308): matplotlib cannot place ticks on such a
        # span; the figure says so instead of the run's outputs stopping here (the record keeps them)
        fig, ax = plt.subplots(figsize=(8, 3))
        ax.axis("off")
        ax.text(0.5, 0.5, textwrap.fill(f"{title}: not drawn: its values reach {huge:.3g}, beyond the span a plot "
                                        f"can draw (|value| > {DRAWABLE:g}); the run's record holds them", 90),
                ha="center", va="center", fontsize=9, color="C3")
        fig.savefig(path, dpi=110, metadata=_PNG_META)
    plt.close(fig)


#: the largest |value| a figure draws; beyond it matplotlib's ticks overflow (a span near 1e308)
DRAWABLE = 1e150


def _largest_value(fig) -> float:
    """The largest |value| of the data the figure's axes hold (inf when any is not finite)."""
    worst = 0.0
    for ax in fig.axes:
        for line in ax.get_lines():
            for data in line.get_data():
                a = np.asarray(data, dtype=float)
                a = a[~np.isnan(a)]
                if a.size:
                    worst = max(worst, float(np.max(np.abs(a))))
        lim = ax.dataLim
        for v in (lim.x0, lim.x1, lim.y0, lim.y1):
            if not np.isnan(v):
                worst = max(worst, abs(float(v)))
    return worst


def draw_figures(record: RunRecord, out_dir, baseline: RunRecord | None = None, obstacles=(),
                 note: str = "") -> list[Path]:
    """Write the seven figures into ``out_dir`` and return their paths (obstacles, with their
    inflated safety boundaries, in the trajectory figure; ``note``, a log read back cut or damaged,
    across the top of each). A run judged by another criterion than the funnel gets its criterion's
    errors in figures 2-4 (module docstring), one without the weight norms its controller's own
    diagnostics in figure 7."""
    from usv_mj.record.criteria import criterion_of_record

    criterion = criterion_of_record(record)
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
        from usv_mj.scene.display import draw_obstacles

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
    save_figure(fig, paths[-1], note)

    for axis, name_, unit, fname in ((1, "x", "m", "fig2_error_x.png"), (2, "y", "m", "fig3_error_y.png"),
                                      (3, "psi", "rad", "fig4_error_psi.png")):
        if criterion.kind != "funnel" or not record.has_funnel:  # the errors its criterion judges
            paths.append(_criterion_error_figure(record, baseline, criterion, axis, out / fname, note))
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
        save_figure(fig, paths[-1], note)

    dt = record.metadata.get("control_period_s") or 0.001
    n_zoom = min(len(record), int(round(ZOOM_S / dt)) + 1)   # rows with t <= 2 s
    zoom = decimate(_Rows(record, n_zoom), ("t", "tau_u", "q_tau_u", "tau_r", "q_tau_r"))
    # a ruddered vessel's own channels (the metadata's channels, usv_mj.builder.channels_of: "rudder")
    # are its n_P and rudder angle; an allocated run's tau are forces, as the law gave them
    rudder = record.metadata.get("channels") == "rudder"
    units = (("1/s", "rad") if rudder else ("N", "N m"))
    titles = {"fig5_tau_u.png": "Propeller revolutions n_P (tau_u) and Q(tau_u)",
              "fig6_tau_r.png": "Rudder angle (tau_r) and Q(tau_r)"} if rudder else FIGURES
    for col, qcol, unit, fname, num in (("tau_u", "q_tau_u", units[0], "fig5_tau_u.png", 5),
                                        ("tau_r", "q_tau_r", units[1], "fig6_tau_r.png", 6)):
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
        fig.suptitle(f"Fig. {num}: {titles[fname]}")
        fig.tight_layout()
        paths.append(out / fname)
        save_figure(fig, paths[-1], note)

    weights = ("w_u_norm", "w_v_norm", "w_r_norm")
    fig, ax = plt.subplots(figsize=(8, 4))
    if all(c in record for c in weights):
        for col, lab in zip(weights, ("|W_u|", "|W_v|", "|W_r|")):
            w = decimate(record, ("t", col))
            ax.plot(w["t"], w[col], lw=1.2, label=lab)
        ax.set_ylabel("weight norm")
        ax.set_title("Fig. 7: neural network weight norms")
    else:  # another controller: its own declared diagnostics (beyond the funnel block)
        from usv_mj.controllers.base import FUNNEL_FIELDS

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
    save_figure(fig, paths[-1], note)
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



_PANEL_COLUMNS = ("t", "x", "x_d", "y", "y_d", "psi", "psi_d", "x_d_dot", "y_d_dot")


def _panels(criterion, record) -> list:
    """Figures 2-4 of a run judged by ``criterion`` (not the funnel): per figure (label, unit, error,
    tolerance or None, the judged norm's label or None, the norm or None). ``record``: a record or
    a dict of column chunks (:data:`_PANEL_COLUMNS`)."""
    import math

    from usv_mj.record.summary import pose_errors

    e = pose_errors(record)
    heading = ("wrap(psi - psi_d)", "rad", e["psi"], None, None, None)
    if criterion.kind == "pose_tolerance":
        pos = criterion.errors(record)["position"]
        return [("x - x_d", "m", e["x"], criterion.position_m, "|p - p_d|", pos),
                ("y - y_d", "m", e["y"], criterion.position_m, "|p - p_d|", pos),
                heading[:3] + (math.radians(criterion.heading_deg), None, None)]
    if criterion.kind == "path_tolerance":
        pe = criterion.errors(record)
        along = criterion.along_track_m if math.isfinite(criterion.along_track_m) else None
        return [("along-track error", "m", pe["along"], along, None, None),
                ("cross-track error", "m", pe["cross"], criterion.cross_track_m, None, None), heading]
    return [("x - x_d", "m", e["x"], None, None, None), ("y - y_d", "m", e["y"], None, None, None), heading]


def _panel_series(record, criterion, axis) -> dict:
    """The kept rows (:func:`decimate`) of panel ``axis``'s error (``err``) and norm (``norm``), with t."""
    def derive(c):
        _, _, err, _, _, norm = _panels(criterion, c)[axis - 1]
        return {"t": c["t"], "err": err} if norm is None else {"t": c["t"], "err": err, "norm": norm}

    return decimate(record, _PANEL_COLUMNS, derive)


def _criterion_error_figure(record, baseline, criterion, axis, path, note=""):
    """Figure ``axis + 1`` of a run judged by ``criterion``: the error it judges, its tolerance band
    from the settling time on, the judged norm and the baseline's same error."""
    import numpy as np

    # the panel's words and bounds (the arrays come chunk by chunk from _panel_series)
    label, unit, _, bound, norm_label, _ = _panels(criterion, {c: np.empty(0) for c in _PANEL_COLUMNS})[axis - 1]
    kept = _panel_series(record, criterion, axis)
    t = kept["t"]
    fig, ax = plt.subplots(figsize=(8, 4))
    if bound is not None:
        band = t >= getattr(criterion, "settle_time_s", 0.0)
        ax.fill_between(t[band], -bound, bound, color="0.85", label=f"tolerance ±{bound:.3g} {unit}")
    if "norm" in kept:
        ax.plot(t, kept["norm"], color="0.45", lw=0.9, ls="--", label=norm_label)
    ax.plot(t, kept["err"], "C0", lw=1.3, label=label)
    if baseline is not None and len(baseline):
        kb = _panel_series(baseline, criterion, axis)
        ax.plot(kb["t"], kb["err"], "C3", lw=1.0, alpha=0.85, label="baseline")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{label} [{unit}]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    title = figure_titles(criterion.kind, True)[path.name]
    ax.set_title(f"Fig. {axis + 1}: {title[:1].lower() + title[1:]}")
    save_figure(fig, path, note)
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
    save_figure(fig, Path(path))
    return Path(path)


__all__ = ["FIGURES", "draw_figures", "figure_titles", "readme_figure"]
