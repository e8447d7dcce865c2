"""The leaderboard's figures (see :mod:`usv_mj.jobs.bench.report`): heat map, bars, worst episodes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from usv_mj.jobs.bench.episode import PREFIX
from usv_mj.jobs.bench.metrics import BY_COLUMN


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw_heatmap(scores: dict, controllers: list, vessels: bool, path: Path) -> None:
    """Controller x (task / condition): the mean normalised score (1 = the table's best)."""
    plt = _plt()
    keys = list(scores)
    names = [f"{k[0]} / {k[1]}" + (f" / {k[2]}" if vessels else "") for k in keys]
    ctrls = [c for c in controllers if any(c in scores[k] for k in keys)]
    m = np.array([[scores[k].get(c, math.nan) for k in keys] for c in ctrls])
    fig, ax = plt.subplots(figsize=(max(6.0, 0.42 * len(keys) + 2), 0.5 * len(ctrls) + 2.4))
    im = ax.imshow(m, cmap="viridis", vmin=0.0, vmax=1.0, aspect="auto")
    ax.set_xticks(range(len(keys)), names, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(len(ctrls)), ctrls, fontsize=8)
    for i in range(len(ctrls)):
        for j in range(len(keys)):
            if math.isfinite(m[i, j]):
                ax.text(j, i, f"{m[i, j]:.2f}", ha="center", va="center", fontsize=6,
                        color="white" if m[i, j] < 0.5 else "black")
    fig.colorbar(im, ax=ax, label="normalised score (1 = best of the table)", shrink=0.8)
    ax.set_title("benchmark: mean normalised score over the ranked metrics", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def draw_bars(agg: dict, controllers: list, metrics: tuple, vessels: bool, path: Path, task: str) -> None:
    """One task: for each of ``metrics`` a panel of bars (condition groups x controllers) with the
    95 % intervals as error bars."""
    plt = _plt()
    keys = list(agg)
    ctrls = [c for c in controllers if any(c in agg[k] for k in keys)]
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.3 * len(metrics), 3.4))
    width = 0.8 / max(1, len(ctrls))
    for ax, column in zip(np.atleast_1d(axes), metrics):
        spec = BY_COLUMN[column]
        scale = 100.0 if spec.rate else 1.0
        for i, c in enumerate(ctrls):
            x = np.arange(len(keys)) + (i - (len(ctrls) - 1) / 2) * width
            e = [agg[k][c][column] if c in agg[k] else None for k in keys]
            shown = [v if v is not None and v.n and math.isfinite(v.mean) else None for v in e]  # inf: not ok
            mean = np.array([v.mean * scale if v is not None else np.nan for v in shown])
            lo = np.array([v.lo * scale if v is not None else np.nan for v in shown])
            hi = np.array([v.hi * scale if v is not None else np.nan for v in shown])
            yerr = np.vstack([np.clip(mean - lo, 0, None), np.clip(hi - mean, 0, None)])
            ax.bar(x, mean, width, yerr=np.nan_to_num(yerr), capsize=2, label=c)
        ax.set_xticks(range(len(keys)), [k[1] + (f"/{k[2]}" if vessels else "") for k in keys], fontsize=7)
        unit = "%" if spec.rate else spec.unit
        ax.set_title(f"{spec.label}" + (f" [{unit}]" if unit else "") + (" ↓" if spec.better == "lower" else " ↑"),
                     fontsize=8)
        ax.tick_params(labelsize=7)
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.suptitle(f"task {task}: mean over episodes, 95 % intervals", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def worst_episodes(rows: list[dict]) -> dict:
    """``{controller: row}``: each controller's episode with the largest IAE_ct / simulated time."""
    out: dict = {}
    for r in rows:
        iae, t = r.get(PREFIX + "iae_cross_track"), r.get("simulated_s")
        if iae is None or not t:
            continue
        score = iae / t
        c = r["vary.controller"]
        if c not in out or score > out[c][0]:
            out[c] = (score, r)
    return {c: r for c, (_, r) in out.items()}


def rerun(run, options: dict | None = None):
    """The record of one planned episode, run again in this process (the same seeds: the same run)."""
    from usv_mj.loop.simulate import simulate
    from usv_mj.jobs.sweep.runner import resolve

    opts = {**(options or {}), **run.options}
    if opts.get("episode_fn"):
        return resolve(opts["episode_fn"])(run.scenario, opts)
    return simulate(run.scenario)


def draw_worst(rows: list[dict], suite, path: Path) -> None:
    """Each controller's worst episode (:func:`worst_episodes`): its track against its reference."""
    plt = _plt()
    worst = worst_episodes(rows)
    ctrls = [c.name for c in suite.controllers if c.name in worst]
    if not ctrls:
        return
    by_id = {r.run_id: r for r in suite.plan.runs}
    fig, axes = plt.subplots(1, len(ctrls), figsize=(4.2 * len(ctrls), 4.2), squeeze=False)
    for ax, c in zip(axes[0], ctrls):
        row = worst[c]
        try:
            rec = rerun(by_id[row["run_id"]])
        except Exception as exc:  # drawn as a note: the leaderboard stands without the figure
            ax.text(0.5, 0.5, f"could not run it again:\n{type(exc).__name__}: {exc}", ha="center", va="center",
                    fontsize=7, transform=ax.transAxes, wrap=True)
            continue
        ax.plot(rec["x_d"], rec["y_d"], "k--", lw=1, label="reference")
        ax.plot(rec["x"], rec["y"], lw=1.2, label=c)
        ax.plot(rec["x"][:1], rec["y"][:1], "go", ms=4, label="start")
        for ob in (rec.metadata.get("scenario") or {}).get("obstacles") or []:
            _draw_obstacle(ax, ob)
        ax.set_aspect("equal", adjustable="datalim")
        vessel = f" / {row['vary.vessel']}" if row.get("vary.vessel") else ""   # a suite over vessels
        ax.set_title(f"{c}: {row['vary.task']} / {row['vary.condition']}{vessel}, episode {row['vary.episode']}\n"
                     f"IAE e_ct {row[PREFIX + 'iae_cross_track']:.1f} m s over {row['simulated_s']:.0f} s, "
                     f"{row['status']}", fontsize=8)
        ax.set_xlabel("x [m]", fontsize=8)
        ax.set_ylabel("y [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _draw_obstacle(ax, ob: dict) -> None:
    from matplotlib.patches import Circle, Rectangle

    if ob.get("kind") == "circle":
        ax.add_patch(Circle(ob["center"], ob["radius"], color="0.6"))
    elif ob.get("kind") == "box":
        (cx, cy), (w, h) = ob["center"], ob["size"]
        ax.add_patch(Rectangle((cx - w / 2, cy - h / 2), w, h, color="0.6"))
