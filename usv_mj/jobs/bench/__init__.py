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
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from usv_mj.core.errors import ScenarioError, SweepError

__all__ = ["load_suite", "run_bench", "compare", "add_arguments", "run_command"]


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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``usv-mj bench``."""
    parser.add_argument("suite", nargs="?", default=None,
                        help="the suite file (TOML: tasks, conditions, controllers; usv_mj.jobs.bench.suite); "
                             "default: the suite shipped in the package")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="output folder for results.parquet, report.md, leaderboard.json, figures/ "
                             "(default renders/bench-<suite name>)")
    parser.add_argument("--scheduler", default=None,
                        help="address of a running Dask scheduler (tcp://host:8786); default: a local cluster")
    parser.add_argument("--jobqueue", default=None, metavar="SYSTEM",
                        help="run on a batch system through dask-jobqueue (slurm, pbs, sge, lsf, ...)")
    parser.add_argument("--jobs", type=int, default=1, help="--jobqueue: number of batch jobs (default 1)")
    parser.add_argument("--workers", type=int, default=None,
                        help="local cluster: worker processes (default: the number of cores)")
    parser.add_argument("--resume", action="store_true", help="run only the episodes missing from DIR/results.parquet")
    from usv_mj.outputs.outdir import add_overwrite_argument

    add_overwrite_argument(parser, "--out whole when it holds an earlier usv_mj output (the new benchmark is "
                                   "staged: the old one stays until it ends)")
    parser.add_argument("--max-runs", type=int, default=None,
                        help="run at most N episodes now, then stop (--resume continues)")
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"), default=None,
                        help="do not run: test whether controller A beats B per metric over the paired episodes "
                             "of DIR/results.parquet (Wilcoxon signed-rank)")
    parser.add_argument("--no-figures", action="store_true", help="report.md and leaderboard.json without figures")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_command(args: argparse.Namespace) -> int:
    """``usv-mj bench``: 0 done, 2 bad input, 1 interrupted."""
    try:
        from usv_mj.jobs.bench.suite import describe
        from usv_mj.jobs.bench.suite import load_suite as _load

        suite = _load(args.suite)
        out = args.out or str(Path("renders") / f"bench-{suite.name}")
        if args.compare:
            from usv_mj.jobs.sweep.runner import RESULTS_FILE, read_results

            path = Path(out) / RESULTS_FILE
            if not path.is_file():
                raise SweepError(f"--compare: {path} does not exist: run the suite first (usv-mj bench --out {out})")
            rows, fingerprint = read_results(path)
            if fingerprint != suite.plan.fingerprint:
                raise SweepError(f"--compare: {path} holds the results of another suite than {suite.source}")
            a, b = args.compare
            result = compare(rows, a, b)
            print(f"{a} vs {b}: paired over the episodes of {path} ({len(rows)} of {len(suite.plan.runs)} "
                  f"episodes in), Wilcoxon signed-rank, two-sided, 5 %")
            print(compare_table(result, a, b))
            return 0
        from usv_mj.outputs.outdir import check_folder, results_folder

        if args.resume and args.overwrite:
            raise SweepError("--resume continues the benchmark in --out, --overwrite replaces it: give one of them")
        check_folder(out, args.overwrite, resume=args.resume)   # new, empty, this benchmark's (--resume) or --overwrite
        for name in ("workers", "max_runs"):
            v = getattr(args, name)
            if v is not None and v < 1:
                raise SweepError(f"--{name.replace('_', '-')} must be >= 1, got {v}")
        print(describe(suite), flush=True)
        with results_folder(out, args.resume) as folder:   # staged when it replaces an earlier output
            result = run_bench(suite, folder, scheduler=args.scheduler, workers=args.workers,
                               resume=args.resume, progress=not args.no_progress, max_runs=args.max_runs,
                               jobqueue=args.jobqueue, jobs=args.jobs, draw=not args.no_figures)
    except ScenarioError as exc:  # SweepError and the output checks
        print(f"usv-mj bench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\nusv-mj bench: interrupted: the episodes finished so far are in {out}/results.parquet; "
              f"run the same command with --resume to finish", file=sys.stderr)
        return 1
    if not result.complete:
        print(f"{len(result.rows)} of {len(suite.plan.runs)} episodes in {out}/results.parquet; run again with "
              f"--resume for the rest")
        return 0
    from usv_mj.jobs.bench.report import aggregate, printed_leaderboard

    print("\n".join(printed_leaderboard(aggregate(result.rows), [c.name for c in suite.controllers],
                                        suite.vessels != [""])))
    print(f"{len(result.rows)} episodes ({result.ran} run now), {result.failed} not ok; {out}/report.md, "
          f"{out}/leaderboard.json, {out}/figures/")
    return 0
