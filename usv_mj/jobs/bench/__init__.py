"""The controller benchmark: every controller on the same tasks, seas and actuators, scored the same way.

    usv-mj bench [SUITE.toml] [--out DIR] [--workers N | --scheduler ADDRESS | --jobqueue slurm --jobs N]
                 [--resume] [--max-runs N]
    usv-mj bench [SUITE.toml] --out DIR --compare A B      # paired Wilcoxon test per metric

Without a suite: the default suite shipped in the package (``usv_mj/jobs/bench/suites/default.toml``).
The suite format is in :mod:`usv_mj.jobs.bench.suite`; the metrics in :mod:`usv_mj.jobs.bench.metrics`
(formulas: docs/metrics.md); the leaderboard in :mod:`usv_mj.jobs.bench.report`; a learned policy in
:mod:`usv_mj.jobs.bench.policy`.

The episodes are the runs of one sweep (:func:`usv_mj.jobs.sweep.runner.run_sweep`): a Dask task each on
a local cluster by default, rows streamed into ``DIR/results.parquet``, ``--resume`` running only
the missing ones. Every episode is seeded by its task and index, so the metrics are bit-identical on
1 or N workers. Python API::

    from usv_mj.jobs.bench import load_suite, run_bench
    suite = load_suite()                          # the default suite, drawn and validated
    result = run_bench(suite, "renders/bench", workers=2)   # results.parquet, report.md, figures/

The command ``usv-mj bench`` is :mod:`usv_mj.cli.bench`.
"""

from __future__ import annotations

from pathlib import Path

from usv_mj.core.errors import SweepError

__all__ = ["load_suite", "run_bench", "compare", "compare_table"]


def load_suite(path=None):
    """See :func:`usv_mj.jobs.bench.suite.load_suite`."""
    from usv_mj.jobs.bench.suite import load_suite as _load

    return _load(path)


def run_bench(suite, out, *, report: bool = True, draw: bool = True, **kwargs):
    """Run the suite's missing episodes on Dask (``kwargs``: those of
    :func:`usv_mj.jobs.sweep.runner.run_sweep`: ``workers``, ``scheduler``, ``jobqueue``, ``jobs``,
    ``resume``, ``max_runs``, ``client``, ``progress``, ``echo``) and, once every episode is in,
    write the leaderboard. Returns the sweep's :class:`SweepResult`."""
    from usv_mj.jobs.sweep.runner import run_sweep

    result = run_sweep(suite.plan, out, report=False, **kwargs)
    if report and result.complete:
        from usv_mj.jobs.bench.report import write_report

        write_report(out, result.rows, suite, draw=draw)
        from usv_mj.outputs.outdir import record

        record(Path(out), patterns=("leaderboard.json",))   # the report and figures are usv_mj's (--resume, reruns)
    return result


def compare(rows: list[dict], a: str, b: str, alpha: float = 0.05) -> list[dict]:
    """Paired comparison of controllers ``a`` and ``b`` per metric: the episodes that share task,
    condition, vessel and episode index; the Wilcoxon signed-rank test of the differences (two-sided,
    zero differences dropped, ``scipy.stats.wilcoxon``); for a rate (0/1 outcomes) the same test on
    the paired outcomes. Returns one dict per metric: ``metric, pairs, median_a, median_b,
    median_diff, p, verdict``."""
    import math

    import numpy as np
    from scipy.stats import wilcoxon

    from usv_mj.jobs.bench.episode import PREFIX
    from usv_mj.jobs.bench.metrics import METRICS

    known = {r["vary.controller"] for r in rows}
    for c in (a, b):
        if c not in known:
            raise SweepError(f"--compare: no controller {c!r} in the results; controllers: {', '.join(sorted(known))}")
    key = lambda r: (r["vary.task"], r["vary.condition"], r.get("vary.vessel"), r["vary.episode"])  # noqa: E731
    by_a = {key(r): r for r in rows if r["vary.controller"] == a}
    by_b = {key(r): r for r in rows if r["vary.controller"] == b}
    common = sorted(set(by_a) & set(by_b), key=repr)
    out = []
    for m in METRICS:
        col = PREFIX + m.column
        pairs = [(by_a[k].get(col), by_b[k].get(col)) for k in common]
        pairs = [(float(x), float(y)) for x, y in pairs if x is not None and y is not None
                 and math.isfinite(float(x)) and math.isfinite(float(y))]
        if not pairs:
            continue
        xa, xb = np.array(pairs).T
        d = xa - xb
        p = math.nan
        if np.count_nonzero(d) >= 1:
            p = float(wilcoxon(xa, xb, zero_method="wilcox", alternative="two-sided").pvalue)
        if not math.isfinite(p) or p >= alpha:
            verdict = "no difference" if math.isfinite(p) else "identical"
        else:
            a_lower = float(np.median(d)) < 0 if np.median(d) != 0 else float(np.mean(d)) < 0
            a_better = a_lower == (m.better == "lower")
            verdict = f"{a if a_better else b} better"
        out.append({"metric": m.column, "pairs": len(pairs), "median_a": float(np.median(xa)),
                    "median_b": float(np.median(xb)), "median_diff": float(np.median(d)), "p": p, "verdict": verdict})
    return out


def compare_table(result: list[dict], a: str, b: str) -> str:
    lines = [f"| metric | pairs | median {a} | median {b} | median diff ({a} - {b}) | Wilcoxon p | verdict |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in result:
        p = "-" if r["p"] != r["p"] else f"{r['p']:.3g}"
        lines.append(f"| {r['metric']} | {r['pairs']} | {r['median_a']:.4g} | {r['median_b']:.4g} | "
                     f"{r['median_diff']:+.4g} | {p} | {r['verdict']} |")
    return "\n".join(lines)
