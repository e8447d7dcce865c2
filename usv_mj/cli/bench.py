"""``usv-mj bench [SUITE.toml]``: the controller benchmark (:mod:`usv_mj.jobs.bench`), or --compare A B."""

from __future__ import annotations

import sys
from pathlib import Path

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError, SweepError, WorkerError


def add_arguments(p) -> None:
    p.add_argument("suite", nargs="?", default=None,
                   help="the suite file (TOML: tasks, conditions, controllers; usv_mj.jobs.bench.suite); "
                        "default: the suite shipped in the package")
    flags.add_out_argument(p, "output folder for results.parquet, report.md, leaderboard.json, figures/ "
                              "(default renders/bench-<suite name>)")
    flags.add_cluster_arguments(p)
    flags.add_resume_arguments(p, "episodes")
    flags.add_batch_argument(p, "episodes")
    flags.add_overwrite_argument(p, "--out whole when it holds an earlier usv_mj output (the new benchmark is "
                                    "staged: the old one stays until it ends)")
    p.add_argument("--compare", nargs=2, metavar=("A", "B"), default=None,
                   help="do not run: test A against B in every task/condition/vessel cell and metric over the "
                        "paired episodes of DIR/results.parquet (Wilcoxon, censored sign test, McNemar; Holm's "
                        "correction); the suite is the one the folder was run with (a SUITE given is checked "
                        "against it)")
    p.add_argument("--no-figures", action="store_true", help="report.md and leaderboard.json without figures")
    flags.add_quiet_argument(p)


@COMMANDS.register(
    "bench", arguments=add_arguments,
    help="the controller benchmark: every controller on the same tasks, seas and actuators, one leaderboard",
    description="Score controllers on a suite of tasks (trajectories, a harbour transit) in calm water, a\n"
                "moderate sea with current and with thrust limits, the same episodes for each; default: the\n"
                "suite shipped in the package. Episodes run on the sweep's Dask cluster and stream into\n"
                "results.parquet (--resume finishes); report.md is the leaderboard with 95 % intervals and\n"
                "figures. --compare A B tests A against B per cell and metric (paired tests, Holm-corrected),\n"
                "reading the suite from the results folder. docs/metrics.md.")
def run(args) -> int:
    """0 done, 2 bad input, 1 interrupted."""
    from usv_mj.jobs.bench import run_bench

    out = args.out or "renders/bench-default"
    try:
        from usv_mj.jobs.bench.suite import describe, load_suite

        if args.compare:
            return _compare(args)
        suite = load_suite(args.suite)
        out = args.out or str(Path("renders") / f"bench-{suite.name}")
        from usv_mj.outputs.outdir import check_folder, results_folder

        if args.resume and args.overwrite:
            raise SweepError("--resume continues the benchmark in --out, --overwrite replaces it: give one of them")
        check_folder(out, args.overwrite, resume=args.resume)   # new, empty, this benchmark's (--resume) or --overwrite
        if args.max_runs is not None and args.max_runs < 1:
            raise SweepError(f"--max-runs must be >= 1, got {args.max_runs}")
        print(describe(suite), flush=True)
        with results_folder(out, args.resume) as folder:   # staged when it replaces an earlier output
            result = run_bench(suite, folder, scheduler=args.scheduler, workers=args.workers,
                               resume=args.resume, progress=not args.quiet, max_runs=args.max_runs,
                               jobqueue=args.jobqueue, jobs=args.jobs, draw=not args.no_figures, batch=args.batch)
    except ScenarioError as exc:  # SweepError and the output checks
        print(f"usv-mj bench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        from usv_mj.jobs.sweep.runner import episodes_in

        print(f"\nusv-mj bench: interrupted: {episodes_in(Path(out))} of {len(suite.plan.runs)} episodes are in "
              f"{out}/results.parquet; run the same command with --resume to finish", file=sys.stderr)
        return 1
    except WorkerError as exc:
        print(f"usv-mj bench: stopped: {exc}; the episodes finished so far are in {out}/results.parquet "
              f"(--resume runs the rest)", file=sys.stderr)
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
    return flags.report_failed(result.rows, "usv-mj bench", "episode")


def _compare(args) -> int:
    """``--compare A B``: the paired tests over ``--out``'s results. The results folder knows its suite
    (``sweep.json``: its file and fingerprint, the fingerprint also in results.parquet), so no suite
    file is needed again; one that is given must be the folder's."""
    import json

    from usv_mj.jobs.bench import compare, compare_table
    from usv_mj.jobs.bench.suite import default_suite_path, load_suite
    from usv_mj.jobs.sweep.runner import RESULTS_FILE, read_results

    if args.compare[0] == args.compare[1]:   # a controller against itself: every test would say "no difference"
        raise SweepError(f"--compare {args.compare[0]} {args.compare[1]}: give two different controllers of the suite")
    if args.out is None:
        suite = load_suite(args.suite)   # the default folder is the suite's (renders/bench-<name>)
        out = str(Path("renders") / f"bench-{suite.name}")
    else:
        suite, out = None, args.out
    path = Path(out) / RESULTS_FILE
    if not path.is_file():
        raise SweepError(f"--compare: {path} does not exist: run the suite first (usv-mj bench "
                         f"{args.suite or ''}{' ' if args.suite else ''}--out {out})")
    rows, fingerprint = read_results(path)
    info = Path(out) / "sweep.json"
    ran = json.loads(info.read_text()) if info.is_file() else {}
    if ran.get("fingerprint") and ran["fingerprint"] != fingerprint:
        raise SweepError(f"--compare: {path} and {info} belong to different benchmarks")
    if args.suite is not None:
        suite = suite or load_suite(args.suite)
        if fingerprint != suite.plan.fingerprint:
            raise SweepError(f"--compare: {path} holds the results of another suite than {suite.source} "
                             f"(it was run with {ran.get('source', '?')}; leave the suite out to use that one)")
    source = ran.get("source") or (suite.source if suite is not None else str(default_suite_path()))
    a, b = args.compare
    result = compare(rows, a, b)
    print(f"{a} vs {b}: paired over the episodes of {path} (suite {source}, {len(rows)} episodes)")
    print(compare_table(result, a, b))
    return 0
