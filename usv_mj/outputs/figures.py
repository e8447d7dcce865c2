"""The paper's Figures 1-7, drawn from finished runs (a RunRecord, live or read back from MCAP).

1. trajectory against the reference, with an inset that magnifies a stretch of the steady part
(where the controller's and the baseline's tracks lie within centimetres of each other and of the
reference); 2-4. the funnel errors e1, e2 (Do & Pan coordinates, Eq. 14) and e3 (Eq. 15) with the
bounds +-rho_i (Eq. 9) and the PI baseline, and below them the same errors once the funnel has
narrowed, on an axis zoomed to them; 5-6. tau_u against Q(tau_u) and tau_r against Q(tau_r), each
axis naming its quantity and unit; 7. the norms of the network weights, or the diagnostics the
controller declares, one panel per unit (its ``diagnostic_units``, :mod:`usv_mj.controllers.base`).

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

from usv_mj.physics.channels import RunChannels  # noqa: E402
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
    _steady_inset(ax, record, baseline, name, base_name, [(ref["x_d"], ref["y_d"]), (path["x"], path["y"])])
    paths.append(out / "fig1_trajectory.png")
    save_figure(fig, paths[-1], note)

    for axis, name_, unit, fname in ((1, "x", "m", "fig2_error_x.png"), (2, "y", "m", "fig3_error_y.png"),
                                      (3, "psi", "rad", "fig4_error_psi.png")):
        if criterion.kind != "funnel" or not record.has_funnel:  # the errors its criterion judges
            paths.append(_criterion_error_figure(record, baseline, criterion, axis, out / fname, note))
            continue
        f = decimate(record, ("t", f"rho{axis}"))
        rho = f[f"rho{axis}"]
        e = decimate(record, ("t", f"e{axis}"))
        eb = decimate(baseline, ("t", f"e{axis}")) if baseline is not None and len(baseline) and \
            baseline.has_funnel else None
        t_narrow = narrowed_time(f["t"], rho)
        if t_narrow is None:
            fig, ax = plt.subplots(figsize=(8, 4))
        else:
            fig, (ax, axz) = plt.subplots(2, 1, figsize=(8, 6.4), gridspec_kw={"height_ratios": [3, 2]})
        what = {"x": "e1 = x̄ - x̄_d", "y": "e2 = ȳ - ȳ_d", "psi": "e3 = ψ - ψ_a"}[name_]
        for a in (ax,) if t_narrow is None else (ax, axz):
            a.fill_between(f["t"], -rho, rho, color="0.85", label=f"funnel ±rho{axis}")
            a.plot(f["t"], rho, color="0.4", lw=0.8)
            a.plot(f["t"], -rho, color="0.4", lw=0.8)
            a.plot(e["t"], e[f"e{axis}"], "C0", lw=1.3, label=f"e{axis}, {name}")
            if eb is not None:
                a.plot(eb["t"], eb[f"e{axis}"], "C3", lw=1.0, alpha=0.85, label=f"e{axis}, {base_name}")
            a.set_ylabel(f"{what} [{unit}]")
            a.grid(alpha=0.3)
        ax.set_xlabel("t [s]")
        ax.legend(loc="upper right")
        ax.set_title(f"Fig. {axis + 1}: tracking error of {name_} in the prescribed-performance funnel")
        if t_narrow is not None:
            _zoom_after(axz, t_narrow, f["t"], rho, [e[f"e{axis}"]] + ([eb[f"e{axis}"]] if eb is not None else []),
                        [e["t"]] + ([eb["t"]] if eb is not None else []), axis, unit)
            fig.tight_layout()
        paths.append(out / fname)
        save_figure(fig, paths[-1], note)

    dt = record.metadata.get("control_period_s") or 0.001
    n_zoom = min(len(record), int(round(ZOOM_S / dt)) + 1)   # rows with t <= 2 s
    zoom = decimate(_Rows(record, n_zoom), ("t", "tau_u", "q_tau_u", "tau_r", "q_tau_r"))
    # the command's channels (usv_mj.physics.channels; a ruddered vessel's n_P and rudder angle, an
    # allocated run's forces as the law gave them): each figure names its quantity and unit
    command = RunChannels.from_metadata(record.metadata.get("channels")).command
    titles = dict(FIGURES) if command.forces else {
        "fig5_tau_u.png": f"{command.surge.quantity.capitalize()} {command.surge.symbol} (tau_u) and Q(tau_u)",
        "fig6_tau_r.png": f"{command.yaw.quantity.capitalize()} {command.yaw.symbol} (tau_r) and Q(tau_r)"}
    for col, qcol, channel, fname, num in (("tau_u", "q_tau_u", command.surge, "fig5_tau_u.png", 5),
                                           ("tau_r", "q_tau_r", command.yaw, "fig6_tau_r.png", 6)):
        unit = channel.unit
        fig, (ax, axz) = plt.subplots(1, 2, figsize=(11, 4), gridspec_kw={"width_ratios": [2, 1]})
        c = decimate(record, ("t", col))
        ax.plot(c["t"], c[col], "C0", lw=0.8, label=col)
        q = decimate(record, ("t", qcol))
        ax.step(q["t"], q[qcol], "C1", lw=0.8, where="post", label=f"Q({col})")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"{channel.quantity} {col}, Q({col}) [{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right")
        axz.plot(zoom["t"], zoom[col], "C0", lw=1.0)
        axz.step(zoom["t"], zoom[qcol], "C1", lw=1.0, where="post")
        axz.set_ylabel(f"{channel.quantity} [{unit}]")
        axz.set_xlabel("t [s] (first 2 s)")
        axz.grid(alpha=0.3)
        fig.suptitle(f"Fig. {num}: {titles[fname]}")
        fig.tight_layout()
        paths.append(out / fname)
        save_figure(fig, paths[-1], note)

    weights = ("w_u_norm", "w_v_norm", "w_r_norm")
    if all(c in record for c in weights):
        fig, ax = plt.subplots(figsize=(8, 4))
        for col, lab in zip(weights, ("|W_u|", "|W_v|", "|W_r|")):
            w = decimate(record, ("t", col))
            ax.plot(w["t"], w[col], lw=1.2, label=lab)
        ax.set_ylabel("weight norm |W_i| [-]")
        ax.set_title("Fig. 7: neural network weight norms")
        axes = [ax]
    else:  # another controller: its own declared diagnostics (beyond the funnel block), a panel per unit
        from usv_mj.core.layouts import FUNNEL_FIELDS

        own = [c for c in record.diagnostic_fields if c not in FUNNEL_FIELDS]
        groups = diagnostic_panels(own, record.metadata.get("diagnostic_units") or {})[:MAX_PANELS]
        shown = sum(len(cols) for _, cols in groups)
        fig, grid = plt.subplots(max(1, len(groups)), 1, figsize=(8, 4 if len(groups) <= 1 else 1.2 + 1.9 * len(groups)),
                                 sharex=True, squeeze=False)
        axes = list(grid[:, 0])
        for ax, (unit, cols) in zip(axes, groups):
            for col in cols:
                w = decimate(record, ("t", col))
                ax.plot(w["t"], w[col], lw=1.0, label=col)
            ax.set_ylabel(textwrap.fill(", ".join(cols), 24) + (f" [{unit}]" if unit is not None else
                                                                "\n[unit not declared]"), fontsize=8)
        axes[0].set_title(f"Fig. 7: diagnostics declared by the {name} controller"
                          + ("" if own else " (none)") + (", a panel per unit" if len(groups) > 1 else "")
                          + (f" (the first {shown} of {len(own)})" if shown < len(own) else ""))
    axes[-1].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    paths.append(out / "fig7_weights.png")
    save_figure(fig, paths[-1], note)
    return paths


MAX_PANELS = 6   # figure 7: at most this many panels of a controller's own diagnostics


def diagnostic_panels(fields, units: dict) -> list:
    """Figure 7's panels of a controller's own diagnostics: ``[(unit, [field, ...]), ...]``, one per
    declared unit in the order of the fields, and one for each field whose unit is not declared
    (unit None: fields of unknown units are never drawn on a shared axis)."""
    panels: list = []
    by_unit: dict = {}
    for f in fields:
        unit = units.get(f)
        if unit is None:
            panels.append((None, [f]))
        elif unit in by_unit:
            by_unit[unit].append(f)
        else:
            by_unit[unit] = [f]
            panels.append((unit, by_unit[unit]))
    return panels


NARROWED = 0.1   # the funnel has narrowed once rho - rho_end <= this fraction of rho(0) - rho_end


def narrowed_time(t, rho) -> float | None:
    """[s] The first time the funnel has narrowed (``NARROWED``; rho_end: its last value), if that is
    before the last third of the run (after it there is too little left to zoom on); else None."""
    import numpy as np

    t, rho = np.asarray(t, float), np.asarray(rho, float)
    if len(t) < 2 or not (np.all(np.isfinite(rho)) and rho[0] > rho[-1]):
        return None
    k = int(np.argmax(rho - rho[-1] <= NARROWED * (rho[0] - rho[-1])))
    return float(t[k]) if t[k] <= t[0] + (t[-1] - t[0]) * 2.0 / 3.0 else None


def _zoom_after(ax, t0, t_rho, rho, errors, times, axis, unit) -> None:
    """The lower panel of figures 2-4: the errors after ``t0`` on an axis zoomed to them."""
    import numpy as np

    peak = max(float(np.max(np.abs(e[tt >= t0]))) if np.any(tt >= t0) else 0.0 for e, tt in zip(errors, times))
    rho_end = float(rho[-1])
    lim = 1.3 * peak if peak > 0 else 0.1 * rho_end
    ax.set_xlim(t0, float(t_rho[-1]))
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("t [s]")
    inside = "" if lim < rho_end else "; the funnel's edge ±rho is drawn"
    ax.set_title(f"after t = {t0:.0f} s (the funnel within {NARROWED:.0%} of its final ±{rho_end:.3g} {unit}), "
                 f"zoomed: max |e{axis}| = {peak:.3g} {unit}, {peak / rho_end:.0%} of rho{axis}{inside}", fontsize=8)


def _emptiest_corner(curves, size=(0.34, 0.42), margin=0.04) -> tuple:
    """[x0, y0, w, h] in axes fractions: the corner of the axes (judged on the curves' bounding box)
    that the fewest of the curves' points fall in."""
    import numpy as np

    xs = np.concatenate([np.asarray(c[0], float) for c in curves])
    ys = np.concatenate([np.asarray(c[1], float) for c in curves])
    ok = np.isfinite(xs) & np.isfinite(ys)
    xs, ys = xs[ok], ys[ok]
    if len(xs) == 0:
        return (margin, margin, *size)
    u = (xs - xs.min()) / max(float(np.ptp(xs)), 1e-12)
    v = (ys - ys.min()) / max(float(np.ptp(ys)), 1e-12)
    w, h = size
    corners = [(margin, margin), (1 - margin - w, margin), (margin, 1 - margin - h), (1 - margin - w, 1 - margin - h)]
    count = [int(np.count_nonzero((u >= x0) & (u <= x0 + w) & (v >= y0) & (v <= y0 + h))) for x0, y0 in corners]
    x0, y0 = corners[int(np.argmin(count))]
    return (x0, y0, w, h)


def _steady_inset(ax, record, baseline, name: str, base_name: str, curves=()) -> None:
    """An inset of figure 1 that magnifies the tracks around the reference point at the middle of the
    run's steady part (from a quarter of the run, 20 s at least, to its end): a square about six times
    the larger of the two runs' distances from the reference there, 0.2 m at least, equal scales, and
    the square marked on the main axes. Nothing when the run is shorter than 40 s or has no reference."""
    import numpy as np

    n = len(record)
    dt = record.metadata.get("control_period_s") or 0.001
    t_end = (n - 1) * dt
    t_start = max(20.0, 0.25 * t_end)
    if n < 3 or t_end < 40.0:
        return
    kc = int(round(0.5 * (t_start + t_end) / dt))
    if not 0 <= kc < n:
        return
    cx, cy = record.value("x_d", kc), record.value("y_d", kc)
    if not (np.isfinite(cx) and np.isfinite(cy)):
        return
    runs = [(record, "C0", 1.5, name)] + ([(baseline, "C3", 1.0, base_name)] if baseline is not None and
                                          len(baseline) > kc else [])
    dev = max(np.hypot(r.value("x", kc) - cx, r.value("y", kc) - cy) for r, *_ in runs)
    half = max(0.2, 3.0 * float(dev))
    # the rows near kc that can be in the square: the time the reference takes to cross it, twice
    speed = max(0.05, float(np.hypot(record.value("x_d_dot", kc), record.value("y_d_dot", kc)))) \
        if "x_d_dot" in record else 0.6
    span = int(round(2.0 * half / speed / dt)) + 1
    rows = np.arange(max(0, kc - span), min(n, kc + span + 1))
    axins = ax.inset_axes(list(_emptiest_corner(curves)) if curves else [0.04, 0.05, 0.34, 0.42])
    axins.plot(record.take("x_d", rows), record.take("y_d", rows), "k--", lw=1.2)
    for r, colour, lw, _ in runs:
        rr = rows[rows < len(r)]
        axins.plot(r.take("x", rr), r.take("y", rr), color=colour, lw=lw)
    axins.set_xlim(cx - half, cx + half)
    axins.set_ylim(cy - half, cy + half)
    axins.set_box_aspect(1)   # a square box over equal x and y spans: equal scales
    axins.tick_params(labelsize=7)
    axins.grid(alpha=0.3)
    axins.set_title(f"t = {kc * dt:.0f} s, {2 * half:.2g} m across", fontsize=7)
    ax.indicate_inset_zoom(axins, edgecolor="0.3")


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
