"""The controller benchmark: every controller on the same tasks, seas and actuators, scored the same way.

    usv-mj bench [SUITE.toml] [--out DIR] [--workers N | --scheduler ADDRESS | --jobqueue slurm --jobs N]
                 [--resume] [--max-runs N]
    usv-mj bench --out DIR --compare A B       # paired tests per cell and metric, Holm-corrected

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

import math
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


def _criterion_of(rows: list[dict]) -> str:
    """The criterion a controller's episodes were judged by (its words; "" when the rows do not say)."""
    seen = {str(r.get("criterion.description") or r.get("criterion.kind") or "") for r in rows}
    return " / ".join(sorted(seen))


def compare(rows: list[dict], a: str, b: str, alpha: float = 0.05) -> dict:
    """Paired comparison of controllers ``a`` and ``b`` in every cell (task, condition, vessel) and
    metric, over the episodes they share (same episode index: the same start pose and sea), with
    Holm's correction over all the tests (docs/metrics.md, "Comparing two controllers"):

    - a continuous metric: the Wilcoxon signed-rank test of the paired values (an episode that is
      not ok counts as the metric's worst value, after every finite one);
    - a time to an event (settling, time to the goal): the exact sign test over the pairs whose order
      is known (reached before not reached; two not reached: a tie), the episodes that did not reach
      it censored at their end, never averaged (:mod:`usv_mj.jobs.bench.stats`);
    - a 0/1 outcome: McNemar's exact test on the discordant pairs; ``passed`` only when both were
      judged by the same criterion, otherwise shown apart (``apart``: the two rates side by side).


    Holm's correction runs within each cell, over the metrics tested there: the family of one claim
    ("A differs from B on this task, in this condition, on this hull"); the counts over cells in
    ``summary`` are descriptive, not a further test.

    Returns ``{"a", "b", "alpha", "correction", "cells", "n_tests", "tests", "apart", "summary"}``:
    ``tests`` one dict per (cell, metric) with ``task, condition, vessel, metric, test, pairs, a, b,
    p, p_holm, family, verdict`` (``a`` / ``b``: the cell's median, or the share, or "k/n reached,
    median"; ``family`` the number of tests of its cell), ``summary`` per metric the cells where each
    is better and where neither is."""
    import numpy as np

    from usv_mj.jobs.bench.episode import PREFIX
    from usv_mj.jobs.bench.metrics import METRICS
    from usv_mj.jobs.bench.stats import censored_median, censored_pairs, holm, sign_test_p, wilcoxon_p

    known = {r["vary.controller"] for r in rows}
    for c in (a, b):
        if c not in known:
            raise SweepError(f"--compare: no controller {c!r} in the results; controllers: {', '.join(sorted(known))}")
    cells: dict = {}
    for r in rows:
        if r["vary.controller"] in (a, b):
            key = (r["vary.task"], r["vary.condition"], r.get("vary.vessel") or "default")
            cells.setdefault(key, {a: {}, b: {}})[r["vary.controller"]][r["vary.episode"]] = r
    tests, apart = [], []
    for (task, cond, vessel), by in cells.items():
        episodes = sorted(set(by[a]) & set(by[b]))
        if not episodes:
            continue
        ra, rb = [by[a][e] for e in episodes], [by[b][e] for e in episodes]
        where = {"task": task, "condition": cond, "vessel": vessel}
        for m in METRICS:
            col = PREFIX + m.column
            ok_a, ok_b = [r["status"] == "ok" for r in ra], [r["status"] == "ok" for r in rb]
            if m.reached:
                flag = PREFIX + m.reached
                # an episode that is not ok did not reach it (None: not measured, e.g. a task without a goal)
                fa = [None if r.get(flag) is None else (bool(r[flag]) and ok) for r, ok in zip(ra, ok_a)]
                fb = [None if r.get(flag) is None else (bool(r[flag]) and ok) for r, ok in zip(rb, ok_b)]
                keep = [i for i in range(len(episodes)) if fa[i] is not None and fb[i] is not None]
                if not keep:
                    continue
                ta = [ra[i].get(col) if fa[i] else None for i in keep]
                tb = [rb[i].get(col) if fb[i] else None for i in keep]
                first_a, first_b, ties = censored_pairs(ta, [fa[i] for i in keep], tb, [fb[i] for i in keep])
                p = sign_test_p(first_a, first_b)
                med = {c: censored_median([t if t is not None else math.inf for t in tt], ff)
                       for c, tt, ff in ((a, ta, [fa[i] for i in keep]), (b, tb, [fb[i] for i in keep]))}
                tests.append({**where, "metric": m.column, "test": "sign test, censored", "pairs": len(keep),
                              "a": _event_text(med[a]), "b": _event_text(med[b]), "p": p,
                              "direction": (first_a > first_b) - (first_a < first_b)})
                continue
            va, vb = [r.get(col) for r in ra], [r.get(col) for r in rb]
            if m.rate:
                keep = [i for i in range(len(episodes)) if va[i] is not None and vb[i] is not None]
                if not keep:
                    continue
                xa, xb = [bool(va[i]) for i in keep], [bool(vb[i]) for i in keep]
                if m.column == "passed":
                    ca, cb = _criterion_of(ra), _criterion_of(rb)
                    if ca != cb:
                        apart.append({**where, "metric": m.column, "a": f"{sum(xa)}/{len(xa)} ({ca})",
                                      "b": f"{sum(xb)}/{len(xb)} ({cb})", "why": "judged by different criteria"})
                        continue
                only_a = sum(x and not y for x, y in zip(xa, xb))
                only_b = sum(y and not x for x, y in zip(xa, xb))
                higher = (only_a > only_b) - (only_a < only_b)
                tests.append({**where, "metric": m.column, "test": "McNemar exact", "pairs": len(keep),
                              "a": sum(xa) / len(xa), "b": sum(xb) / len(xb), "p": sign_test_p(only_a, only_b),
                              "direction": higher if m.better == "lower" else -higher})
                continue
            worst = math.inf if m.better == "lower" else -math.inf
            pa = [v if ok else worst for v, ok in zip(va, ok_a)]
            pb = [v if ok else worst for v, ok in zip(vb, ok_b)]
            keep = [i for i in range(len(episodes)) if pa[i] is not None and pb[i] is not None
                    and not (isinstance(pa[i], float) and math.isnan(pa[i]))
                    and not (isinstance(pb[i], float) and math.isnan(pb[i]))]
            if not keep:
                continue
            xa = np.array([float(pa[i]) for i in keep])
            xb = np.array([float(pb[i]) for i in keep])
            finite = np.concatenate([xa[np.isfinite(xa)], xb[np.isfinite(xb)]])
            big = 10.0 * (float(np.max(np.abs(finite))) if finite.size else 1.0) + 1.0   # after every finite value
            xa, xb = np.where(np.isfinite(xa), xa, np.sign(xa) * big), np.where(np.isfinite(xb), xb, np.sign(xb) * big)
            d = xa - xb
            med = float(np.median(d))
            lower = med < 0 if med != 0 else float(np.mean(d)) < 0
            higher_a = (med > 0) if med != 0 else float(np.mean(d)) > 0
            direction = (1 if lower else -1 if higher_a else 0) if m.better == "lower" else \
                (1 if higher_a else -1 if lower else 0)
            tests.append({**where, "metric": m.column, "test": "Wilcoxon signed-rank", "pairs": len(keep),
                          "a": _median_text(pa, keep), "b": _median_text(pb, keep), "p": wilcoxon_p(xa, xb),
                          "direction": direction})
    # Holm within each cell: the family of one claim, "A differs from B on this task, in this condition,
    # on this hull", over the metrics tested there (docs/metrics.md)
    by_cell: dict = {}
    for t in tests:
        by_cell.setdefault((t["task"], t["condition"], t["vessel"]), []).append(t)
    for family in by_cell.values():
        for t, p_holm in zip(family, holm([t["p"] for t in family])):
            t["p_holm"], t["family"] = p_holm, len(family)
    summary: dict = {}
    for t in tests:
        p_holm = t["p_holm"]
        t["verdict"] = (f"{a} better" if t["direction"] > 0 else f"{b} better") \
            if p_holm < alpha and t["direction"] != 0 else "no difference"
        s = summary.setdefault(t["metric"], {a: 0, b: 0, "no difference": 0})
        s[t["verdict"].removesuffix(" better") if t["verdict"] != "no difference" else "no difference"] += 1
    return {"a": a, "b": b, "alpha": alpha, "correction": "Holm-Bonferroni within each cell", "cells": len(by_cell),
            "n_tests": len(tests), "tests": tests, "apart": apart, "summary": summary}


def _median_text(values, keep) -> float:
    import numpy as np

    x = np.array([float(values[i]) for i in keep])
    return float(np.median(x))


def _event_text(m: dict) -> str:
    def t(v):
        return "> T" if math.isinf(v) else f"{v:.3g}"

    return f"{m['reached']}/{m['n']} reached, median {t(m['median'])} s"


def compare_table(result: dict, a: str, b: str) -> str:
    """What ``usv-mj bench --compare`` prints: the method, per metric the cells where each controller
    is better after Holm's correction, the significant cells, and the rates shown apart."""
    lines = [f"{result['n_tests']} paired tests in {result['cells']} task / condition / vessel cells; Holm-Bonferroni "
             f"within each cell over its metrics (family-wise alpha = {result['alpha']:g} per cell; the counts over "
             f"cells are descriptive); tests: Wilcoxon signed-rank (continuous), exact sign test with censoring "
             f"(settling, time to goal), McNemar exact (rates); docs/metrics.md.", "",
             f"| metric | cells `{a}` better | cells `{b}` better | cells no difference |", "| --- | --- | --- | --- |"]
    for metric, s in result["summary"].items():
        lines.append(f"| {metric} | {s[a]} | {s[b]} | {s['no difference']} |")
    significant = [t for t in result["tests"] if t["verdict"] != "no difference"]
    lines.append("")
    if not significant:
        lines.append(f"No metric differs in any cell after Holm's correction ({result['n_tests']} tests).")
    else:
        lines += [f"| task / condition / vessel | metric | test | pairs | `{a}` | `{b}` | p | Holm p (of m) | verdict |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for t in significant:
            fa = t["a"] if isinstance(t["a"], str) else f"{t['a']:.4g}"
            fb = t["b"] if isinstance(t["b"], str) else f"{t['b']:.4g}"
            lines.append(f"| {t['task']} / {t['condition']} / {t['vessel']} | {t['metric']} | {t['test']} | "
                         f"{t['pairs']} | {fa} | {fb} | {t['p']:.3g} | {t['p_holm']:.3g} ({t['family']}) | "
                         f"{t['verdict']} |")
    if result["apart"]:
        lines += ["", "Criterion pass rates not compared (judged by different criteria), shown apart:", "",
                  f"| task / condition / vessel | `{a}` | `{b}` |", "| --- | --- | --- |"]
        for t in result["apart"]:
            lines.append(f"| {t['task']} / {t['condition']} / {t['vessel']} | {t['a']} | {t['b']} |")
    return "\n".join(lines)
