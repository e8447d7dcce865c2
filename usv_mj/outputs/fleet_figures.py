"""The figures of a run of several vessels, from its records (a run, or its log read back).

- ``fleet_tracks.png``: every vessel's track (its name at the start, its heading at the end), the
  own ship's safety domain drawn where the closest approach happened, the contacts marked;
- ``fleet_ranges.png``: the range between each pair of vessels over time with the DCPA predicted
  at each instant (:mod:`usv_mj.physics.encounters`), the safety domain, the contacts shaded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from usv_mj.outputs.figures import plt, save_figure
from usv_mj.physics.encounters import GEOMETRY_FIELDS
from usv_mj.record.encounters import encounter_summary, pair_series
from usv_mj.record.fleet import FleetRecord

FIGURES = ("fleet_tracks.png", "fleet_ranges.png")


def draw_fleet_figures(record: FleetRecord, out_dir, note: str = "", summary: dict | None = None) -> list[Path]:
    """Write :data:`FIGURES` into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = summary if summary is not None else encounter_summary(record)
    states = record.states()
    t = record.own_record["t"]
    paths = []

    fig, ax = plt.subplots(figsize=(8, 7))
    for v, name in enumerate(record.names):
        xy = states[:, v, :2]
        ok = np.all(np.isfinite(xy), axis=1)
        style = dict(lw=2.2 if name == record.own else 1.4)
        line, = ax.plot(xy[ok, 0], xy[ok, 1], label=f"{name}" + (" (own ship)" if name == record.own else ""), **style)
        if ok.any():
            first, last = np.flatnonzero(ok)[[0, -1]]
            ax.plot(*xy[first], "o", color=line.get_color(), ms=6)
            psi = states[last, v, 2]
            ax.annotate("", xy=(xy[last, 0] + np.cos(psi), xy[last, 1] + np.sin(psi)), xytext=tuple(xy[last]),
                        arrowprops=dict(arrowstyle="->", color=line.get_color(), lw=1.5))
            ax.text(xy[first, 0], xy[first, 1], f"  {name}", color=line.get_color(), fontsize=9, va="bottom")
    domain = summary.get("safety_domain_m")
    own_pairs = [e for e in summary["pairs"].values() if record.own in e["vessels"]]
    if domain and own_pairs:
        closest = min(own_pairs, key=lambda e: e["min_range_m"])
        k = int(np.argmin(np.abs(t - closest["t_min_range_s"])))
        o = record.names.index(record.own)
        ax.add_patch(plt.Circle(tuple(states[k, o, :2]), domain, fill=False, ls="--", color="C3",
                                label=f"own ship's safety domain ({summary['safety_domain_L']:g} L) at the closest "
                                      f"approach, t = {t[k]:.1f} s"))
    for e in summary["pairs"].values():
        for c in e["contacts"]:
            k = int(np.argmin(np.abs(t - c["t_s"])))
            i = record.names.index(e["vessels"][0])
            ax.plot(*states[k, i, :2], "X", color="k", ms=10)
    if any(e["contacts"] for e in summary["pairs"].values()):
        ax.plot([], [], "X", color="k", ms=8, label="contact between hulls")
    ax.set_xlabel("x [m] (east)")
    ax.set_ylabel("y [m] (north)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{len(record.names)} vessels: tracks (o start, arrow: heading at the end)")
    paths.append(out / FIGURES[0])
    save_figure(fig, paths[-1], note)

    fig, ax = plt.subplots(figsize=(9, 4.5))
    contacts = record.contact_rows()
    r_col, d_col = GEOMETRY_FIELDS.index("range_m"), GEOMETRY_FIELDS.index("dcpa_m")
    for p, (i, j) in enumerate(record.pairs):
        g = pair_series(record, i, j)
        line, = ax.plot(t, g[:, r_col], lw=1.4, label=f"range {record.pair_name(p)}")
        ax.plot(t, g[:, d_col], lw=0.8, ls=":", color=line.get_color(), label=f"DCPA {record.pair_name(p)}")
        on = contacts[:len(t), p] > 1e-6
        if on.any():
            ax.fill_between(t, 0, 1, where=on, transform=ax.get_xaxis_transform(), color=line.get_color(), alpha=0.15)
    if domain:
        ax.axhline(domain, color="C3", ls="--", lw=1, label=f"safety domain {domain:.3g} m")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("distance [m] (centre to centre)")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    ax.set_title("Range between vessels and the DCPA predicted at each instant (shaded: hulls in contact)")
    paths.append(out / FIGURES[1])
    save_figure(fig, paths[-1], note)
    return paths
