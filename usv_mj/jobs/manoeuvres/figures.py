"""The figures of a manoeuvre: the track with its measures marked, the time series, the spiral's loop.

Written into ``figures/`` beside the run's own seven (:mod:`usv_mj.outputs.figures`, whose ``save_figure`` they
share): ``manoeuvre_track.png``, ``manoeuvre_time.png`` and, for the spiral, ``manoeuvre_spiral.png``.
Axes in metres, degrees, seconds and rad/s; x east, y north (README, Conventions).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from usv_mj.physics.channels import RUDDER_ANGLE, YAW_MOMENT, Channel
from usv_mj.record.decimate import decimate
from usv_mj.outputs.figures import save_figure, plt

TITLES = {"turning": "Turning circle", "zigzag": "Zig-zag", "spiral": "Dieudonné spiral", "stopping": "Stopping test"}


def _track(ax, rec, execute: float, k: int):
    p = decimate(rec, ("x", "y"))
    ax.plot(p["x"], p["y"], "C0", lw=1.5, label="track")
    ax.plot(rec.value("x", k), rec.value("y", k), "ko", ms=5, label=f"execute (t = {execute:g} s)")
    ax.set_xlabel("x [m] (east)")
    ax.set_ylabel("y [m] (north)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)


def rudder_channel(measures: dict) -> Channel:
    """The channel the manoeuvre's "rudder" was in (usv_mj.jobs.manoeuvres.measure): a yaw moment, or
    a ruddered vessel's rudder angle."""
    d = measures.get("rudder_channel")
    return Channel.from_metadata(d) if isinstance(d, dict) else YAW_MOMENT


def ruddered(measures: dict) -> bool:
    """True when the manoeuvre's "rudder" is a rudder angle (a ruddered vessel)."""
    return rudder_channel(measures) == RUDDER_ANGLE


def draw_manoeuvre_figures(record, kind: str, measures: dict, out_dir, execute: float, label: str) -> list[Path]:
    """Write the manoeuvre's figures into ``out_dir`` and return their paths (module docstring)."""
    # the tau_r channel: a yaw moment [N m], or a ruddered vessel's rudder angle [rad], drawn in deg
    ch = rudder_channel(measures)
    k_r, applied = ch.shown_factor, f"{ch.quantity} applied [{ch.display_unit}]"
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    m = measures["measures"]
    paths = []
    t = record["t"]
    k0 = int(np.searchsorted(t, execute))

    fig, ax = plt.subplots(figsize=(7, 6))
    _track(ax, record, execute, k0)
    if kind == "turning":
        p0 = np.array([record.value("x", k0), record.value("y", k0)])
        psi0 = record.value("psi", k0)
        e = np.array([math.cos(psi0), math.sin(psi0)])
        n = (1.0 if m["turn"] == "port" else -1.0) * np.array([-e[1], e[0]])
        if m.get("advance_m") is not None:
            p90 = p0 + m["advance_m"] * e + m["transfer_m"] * n
            ax.plot(*np.c_[p0, p0 + m["advance_m"] * e], "C1-", lw=2, label=f"advance {m['advance_m']:.2f} m")
            ax.plot(*np.c_[p0 + m["advance_m"] * e, p90], "C2-", lw=2, label=f"transfer {m['transfer_m']:.2f} m")
            ax.plot(*p90, "C2o")
        if m.get("tactical_diameter_m") is not None:
            q = np.array(m["position_180_m"])
            foot = p0 + float((q - p0) @ e) * e        # on the original course line
            ax.plot(*np.c_[foot, q], "C3--", lw=1.5, label=f"tactical diameter {m['tactical_diameter_m']:.2f} m")
            ax.plot(*q, "C3o")
        span = max(abs(m.get("advance_m") or 0), 1.0) * 1.3
        ax.plot(*np.c_[p0 - 0.2 * span * e, p0 + span * e], color="0.5", lw=0.8, ls="-.", label="original course")
        if m.get("steady_diameter_m") is not None:
            xc, yc = m["steady_centre_m"]
            a = np.linspace(0, 2 * math.pi, 200)
            rad = m["steady_diameter_m"] / 2
            ax.plot(xc + rad * np.cos(a), yc + rad * np.sin(a), "k:", lw=1,
                    label=f"fitted steady circle, D = {m['steady_diameter_m']:.2f} m")
    elif kind == "stopping" and m.get("track_reach_m") is not None:
        k = int(np.searchsorted(t, execute + m["time_to_stop_s"]))
        ax.plot(record.value("x", k), record.value("y", k), "C3s", label=f"stopped: track reach {m['track_reach_m']:.2f} m")
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"{TITLES[kind]}: track ({label})")
    fig.tight_layout()
    paths.append(out / "manoeuvre_track.png")
    save_figure(fig, paths[-1])

    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    psi0 = record.value("psi", 0)
    d = decimate(record, ("t", "psi", "r", "u", "v", "f_r"), derive=lambda c: {
        "t": c["t"], "dpsi": np.degrees(c["psi"] - psi0), "r": c["r"], "speed": np.hypot(c["u"], c["v"]),
        "f_r": k_r * c["f_r"]})
    if kind == "zigzag":
        axes[0].plot(d["t"], d["dpsi"], "C0", label="heading change [deg]")
        sw = measures["options"]["angle_deg"]
        ax2 = axes[0].twinx()
        ax2.plot(d["t"], d["f_r"], "C1", lw=1, label=applied)
        ax2.set_ylabel(applied)
        for level in (sw, -sw):
            axes[0].axhline(level, color="k", lw=0.6, ls=":")
        for te in m["executes_s"]:
            axes[0].axvline(te, color="C1", lw=0.5, alpha=0.5)
        axes[0].set_ylabel("heading change [deg]")
    else:
        axes[0].plot(d["t"], d["dpsi"], "C0")
        axes[0].set_ylabel("heading change [deg]")
    axes[0].grid(alpha=0.3)
    axes[1].plot(d["t"], d["r"], "C0", label="yaw rate r [rad/s]")
    axes[1].plot(d["t"], d["speed"], "C2", label="speed over ground [m/s]")
    handles = axes[1].get_lines()
    if kind != "zigzag":
        ax3 = axes[1].twinx()
        handles = handles + ax3.plot(d["t"], d["f_r"], "C1", lw=1, label=applied)
        ax3.set_ylabel(applied)
    axes[1].set_xlabel("t [s]")
    axes[1].legend(handles=handles, fontsize=8, loc="center right", framealpha=0.9)
    axes[1].grid(alpha=0.3)
    axes[0].set_title(f"{TITLES[kind]}: heading and yaw rate ({label})")
    fig.tight_layout()
    paths.append(out / "manoeuvre_time.png")
    save_figure(fig, paths[-1])

    if kind == "spiral":
        fig, ax = plt.subplots(figsize=(7, 5))
        for branch, style in (("down", "C0o-"), ("up", "C3s--")):
            pts = [p for p in m["points"] if p["branch"] == branch]
            ax.plot([p["command"] for p in pts], [p["yaw_rate"] for p in pts], style,
                    label=f"command stepped {branch}")
        ax.axhline(0, color="k", lw=0.6)
        ax.axvline(0, color="k", lw=0.6)
        unit = "deg" if ruddered(measures) else "N m"
        ax.set_xlabel("rudder angle delta [deg] (> 0 to port)" if ruddered(measures) else
                      "commanded yaw moment tau_r [N m] (the \"rudder\"; > 0 to port)")
        ax.set_ylabel("steady yaw rate r [rad/s]")
        if m["hysteresis"]:
            upper = m.get("loop_width_upper")
            width = f"{m['loop_width']:g} to {upper:g}" if upper is not None else f">= {m['loop_width']:g}"
            ax.set_title(f"Dieudonné spiral ({label}): hysteresis loop, width {width} {unit}")
        else:
            ax.set_title(f"Dieudonné spiral ({label}): no hysteresis loop")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        paths.append(out / "manoeuvre_spiral.png")
        save_figure(fig, paths[-1])
    return paths
