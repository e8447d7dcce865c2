"""``DIR/report.md`` of a sweep, with its figures (matplotlib, Agg backend).

- the rate of runs that passed (status ok and the run passed the criterion its controller declares,
  :mod:`usv_mj.record.criteria`: for the paper's controller no sample with |z_i| >= 1, docs/model.md §2's funnel)
  with its Wilson 95 % score interval, overall and for each value of each grid axis, in the criterion's words;
- histograms of the maximum errors after the sweep's transient (x, y [m], psi [rad]);
- scatter plots of the worst position error after the transient against each varied value (runs that
  did not finish ok drawn at the top, as crosses);
- the failed and diverged runs with their parameters and reasons.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (Wilson 1927): (low, high); (0, 1) for n = 0.

    centre = (p + z^2 / 2n) / (1 + z^2 / n), half width = z sqrt(p (1 - p) / n + z^2 / 4n^2) / (1 + z^2 / n).
    """
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, got successes = {successes}, n = {n}")
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _numeric(values) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values if v is not None)


def criteria_of(rows: list[dict]) -> list[tuple[str, str]]:
    """The (noun, description) of every criterion the rows were judged by, in order of first
    appearance (one, unless the sweep varies the controller); failed runs carry none."""
    seen = {}
    for r in rows:
        if r.get("criterion.description"):
            seen.setdefault((r.get("criterion.noun") or "the criterion", r["criterion.description"]))
    return list(seen)


def passed_rate(rows: list[dict]) -> str:
    """"N of M passed: <description>" (the sweep's one line on its runs)."""
    kept = sum(bool(r.get("passed")) for r in rows)
    crits = criteria_of(rows)
    words = "; ".join(d for _, d in crits) if crits else "the controller's criterion (no run was judged)"
    if crits and all(r.get("criterion.kind") in ("not_judged", None) for r in rows):
        return f"0 of {len(rows)} passed: the runs are {words}"
    return f"{kept} of {len(rows)} passed: {words}"


def write_report(out: str | Path, rows: list[dict], plan) -> Path:
    """Write ``out/report.md`` and its figures for ``rows`` (the sweep's table) of ``plan``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    fig_dir = out / "figures"
    fig_dir.mkdir(exist_ok=True)
    n = len(rows)
    kept = sum(bool(r.get("passed")) for r in rows)
    crits = criteria_of(rows)
    noun = crits[0][0] if len(crits) == 1 else "the criterion"
    counts = {s: sum(r["status"] == s for r in rows) for s in ("ok", "diverged", "failed")}
    lo, hi = wilson_interval(kept, n)
    lines = [f"# Sweep report{': ' + plan.name if plan.name else ''}", "",
             f"Sweep file `{plan.source}`, base preset `{plan.base.preset}`, duration {plan.base.duration:g} s, "
             f"plant `{plan.base.plant.kind}`, controller `{plan.base.controller.kind}`, seed {plan.seed}, "
             f"{plan.samples} sample(s) per grid point, {len(plan.runs)} runs ({n} in the table).", "",
             "| varied path | how |", "| --- | --- |"]
    lines += [f"| `{a.path}` | {a.describe()} |" for a in plan.axes] or ["| (none) | |"]
    lines += ["", "## Passed", "",
              f"Runs that finished ok and passed: **{passed_rate(rows)}**"
              + (f"; {kept / n:.1%}, Wilson 95 % interval [{lo:.1%}, {hi:.1%}]." if n else "."),
              f"Status: {counts['ok']} ok, {counts['diverged']} diverged, {counts['failed']} failed.", ""]

    grid_axes = [a for a in plan.axes if a.kind == "grid"]
    if grid_axes:
        fig, axs = plt.subplots(1, len(grid_axes), figsize=(4.5 * len(grid_axes), 3.5), squeeze=False)
        for ax, axis in zip(axs[0], grid_axes):
            col = f"vary.{axis.path}"
            lines += [f"By `{axis.path}`:", "", "| value | passed | runs | rate | Wilson 95 % |",
                      "| --- | --- | --- | --- | --- |"]
            rates, errs_lo, errs_hi, labels = [], [], [], []
            for value in axis.args:
                sub = [r for r in rows if r.get(col) == value]
                k = sum(bool(r.get("passed")) for r in sub)
                a, b = wilson_interval(k, len(sub))
                rate = k / len(sub) if sub else float("nan")
                lines.append(f"| {_fmt(value)} | {k} | {len(sub)} | {rate:.1%} | [{a:.1%}, {b:.1%}] |")
                rates.append(rate)
                errs_lo.append(max(0.0, rate - a) if sub else 0)
                errs_hi.append(max(0.0, b - rate) if sub else 0)
                labels.append(_fmt(value))
            lines.append("")
            x = np.arange(len(rates))
            ax.bar(x, rates, color="tab:blue", alpha=0.7)
            ax.errorbar(x, rates, yerr=[errs_lo, errs_hi], fmt="none", ecolor="k", capsize=4)
            ax.set_xticks(x, labels, rotation=30)
            ax.set_ylim(0, 1.05)
            ax.set_xlabel(axis.path)
            ax.set_ylabel("passed (Wilson 95 %)")
        fig.tight_layout()
        fig.savefig(fig_dir / "passed_rate.png", dpi=110)
        plt.close(fig)
        lines += ["![passed rate by grid value](figures/passed_rate.png)", ""]

    lines += ["## Errors after the transient", "",
              f"Maximum |error| for t > {plan.transient:g} s of each run that finished ok.", ""]
    ok = [r for r in rows if r["status"] == "ok"]
    names = [("max_abs_error_after_transient.x", "max |x - x_d| [m]"),
             ("max_abs_error_after_transient.y", "max |y - y_d| [m]"),
             ("max_abs_error_after_transient.psi", "max |psi - psi_d| [rad]")]
    have = [r for r in ok if r.get("max_position_error_after_transient") is not None]
    if have:
        fig, axs = plt.subplots(1, 3, figsize=(12, 3.4))
        for ax, (col, label) in zip(axs, names):
            vals = np.array([r[col] for r in have if r.get(col) is not None], float)
            ax.hist(vals, bins=max(5, min(40, int(math.sqrt(len(vals))) * 2)), color="tab:green", alpha=0.8)
            ax.set_xlabel(label)
            ax.set_ylabel("runs")
        fig.tight_layout()
        fig.savefig(fig_dir / "error_histograms.png", dpi=110)
        plt.close(fig)
        lines += ["![histograms of the maximum errors after the transient](figures/error_histograms.png)", "",
                  "| error | median | 95th percentile | max |", "| --- | --- | --- | --- |"]
        for col, label in names + [("max_position_error_after_transient", "max hypot(x, y error) [m]")]:
            vals = np.array([r[col] for r in have if r.get(col) is not None], float)
            lines.append(f"| {label.replace('|', chr(92) + '|')} | {np.median(vals):.4g} | {np.percentile(vals, 95):.4g} | {vals.max():.4g} |")
        lines.append("")
    else:
        lines += [f"No run that finished ok went past t = {plan.transient:g} s (the runs are "
                  f"{plan.base.duration:g} s long): no histograms. Lower `transient` in the sweep file.", ""]

    numeric_axes = [a for a in plan.axes if _numeric([r.get(f"vary.{a.path}") for r in rows])]
    if numeric_axes and rows:
        ncols = min(3, len(numeric_axes))
        nrows = math.ceil(len(numeric_axes) / ncols)
        fig, axs = plt.subplots(nrows, ncols, figsize=(4.6 * ncols, 3.5 * nrows), squeeze=False)
        for extra in axs.flat[len(numeric_axes):]:
            extra.set_visible(False)
        worst = [r.get("max_position_error_after_transient") for r in rows]
        top = max([w for w in worst if w is not None], default=1.0) * 1.15 or 1.0
        for ax, axis in zip(axs.flat, numeric_axes):
            col = f"vary.{axis.path}"
            for group, color, marker in (("kept", "tab:blue", "o"), ("left", "tab:orange", "o"),
                                         ("not ok", "tab:red", "x")):
                xs, ys = [], []
                for r, w in zip(rows, worst):
                    g = "not ok" if r["status"] != "ok" else ("kept" if r.get("passed") else "left")
                    if g != group or r.get(col) is None:
                        continue
                    if group == "not ok" or w is None:
                        if group != "not ok":
                            continue
                        w = top
                    xs.append(r[col])
                    ys.append(w)
                label = {"kept": "passed", "left": "not passed", "not ok": "diverged / failed"}[group]
                if xs:
                    ax.scatter(xs, ys, s=14, c=color, marker=marker, label=label, alpha=0.8)
            if axis.kind == "loguniform" or (axis.kind == "grid" and min(axis.args) > 0
                                             and max(axis.args) / min(axis.args) > 50):
                ax.set_xscale("log")
            ax.set_xlabel(axis.path)
            ax.set_ylabel(f"max position error after {plan.transient:g} s [m]")
            ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(fig_dir / "worst_error_scatter.png", dpi=110)
        plt.close(fig)
        lines += ["## Worst error against each varied value", "",
                  "Diverged and failed runs are the red crosses at the top.", "",
                  "![worst error against the varied values](figures/worst_error_scatter.png)", ""]

    bad = [r for r in rows if r["status"] != "ok"]
    lines += ["## Runs that did not finish ok", ""]
    if bad:
        cols = [f"vary.{p}" for p in plan.paths]
        lines += ["| run | status | " + " | ".join(f"`{p}`" for p in plan.paths) + " | reason |",
                  "| --- | --- | " + " | ".join("---" for _ in plan.paths) + " | --- |"]
        for r in bad[:200]:
            reason = (r.get("reason") or "").replace("|", "/").replace("\n", " ")
            lines.append(f"| {r['run_id']} | {r['status']} | " + " | ".join(_fmt(r.get(c)) for c in cols)
                         + f" | {reason[:300]} |")
        if len(bad) > 200:
            lines.append(f"\n... and {len(bad) - 200} more (see results.parquet).")
    else:
        lines.append("None.")
    left = [r for r in rows if r["status"] == "ok" and not r.get("passed")]
    lines += ["", f"## Runs that finished but did not pass ({noun} lost or not judged)", ""]
    if left:
        cols = [f"vary.{p}" for p in plan.paths]
        lines += ["| run | first violation [s] | samples outside | " + " | ".join(f"`{p}`" for p in plan.paths)
                  + " |", "| --- | --- | --- | " + " | ".join("---" for _ in plan.paths) + " |"]
        for r in left[:100]:
            lines.append(f"| {r['run_id']} | {_fmt(r.get('criterion.first_violation_s'))} | "
                         f"{_fmt(r.get('criterion.violations'))} | "
                         + " | ".join(_fmt(r.get(c)) for c in cols) + " |")
        if len(left) > 100:
            lines.append(f"\n... and {len(left) - 100} more (see results.parquet).")
    else:
        lines.append("None.")
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
