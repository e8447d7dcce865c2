"""``usv-mj sweep SWEEP.toml``: many runs of one scenario on a Dask cluster (:mod:`usv_mj.jobs.sweep`)."""

from __future__ import annotations

import sys
from pathlib import Path

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError, SweepError, WorkerError


def add_arguments(p) -> None:
    p.add_argument("sweep", help="the sweep file (TOML: base, duration, samples, seed, [set], [vary])")
    flags.add_out_argument(p, "output folder for results.parquet, report.md, figures/ (default "
                              "renders/sweep-<file name>)")
    flags.add_cluster_arguments(p)
    flags.add_resume_arguments(p, "runs")
    flags.add_batch_argument(p, "runs")
    flags.add_overwrite_argument(p, "--out whole when it holds an earlier usv_mj output (the new sweep is "
                                    "written beside it and moved into place when it ends)")
    p.add_argument("--retry-failed", action="store_true",
                   help="with --resume: run the failed runs again too (diverged ones are results and stay)")
    p.add_argument("--keep-logs", action="store_true", help="write an MCAP log of every run to DIR/logs/")
    flags.add_log_rate_argument(p, "with --keep-logs: ")
    flags.add_quiet_argument(p)


@COMMANDS.register(
    "sweep", arguments=add_arguments, help="Monte-Carlo sweep of many runs on a Dask cluster (local by default)",
    description="Run many variations of one scenario (a sweep file: a base scenario and what varies, by dotted\n"
                "path such as initial.eta[0] or sea.current.speed) on a Dask cluster, local by default.\n"
                "Results stream into results.parquet; report.md gives the rate of runs that passed\n"
                "the controller's criterion (the funnel for the paper's controller).\n"
                "--resume runs only what is missing.")
def run(args) -> int:
    """0 when every run was recorded and none failed, 2 on a bad sweep file or option, 1 when
    interrupted, stopped by its workers (a run that cannot be set up on one, none left) or when runs
    failed (one line each: the run and its reason)."""
    from usv_mj.jobs.sweep import load_sweep, run_sweep

    out = args.out if args.out is not None else str(Path("renders") / f"sweep-{Path(args.sweep).stem}")
    try:
        from usv_mj.outputs.outdir import check_folder, results_folder

        if args.resume and args.overwrite:
            raise SweepError("--resume continues the sweep in --out, --overwrite replaces it: give one of them")
        check_folder(out, args.overwrite, resume=args.resume)
        plan = load_sweep(args.sweep)
        if args.retry_failed and not args.resume:
            raise SweepError("--retry-failed goes with --resume")
        if args.max_runs is not None and args.max_runs < 1:
            raise SweepError(f"--max-runs must be >= 1, got {args.max_runs}")
        if args.log_rate is not None:
            from usv_mj.outputs.log.writer import log_every

            if not args.keep_logs:
                raise SweepError("--log-rate goes with --keep-logs")
            for one in plan.runs:   # every run's control period must allow the rate
                log_every(args.log_rate, one.scenario.control_period)
        print(f"{args.sweep}: {len(plan.runs)} runs, all validated", flush=True)
        with results_folder(out, args.resume) as folder:   # staged when it replaces an earlier output
            result = run_sweep(plan, folder, scheduler=args.scheduler, workers=args.workers, resume=args.resume,
                               keep_logs=args.keep_logs, log_rate=args.log_rate, progress=not args.quiet,
                               max_runs=args.max_runs, jobqueue=args.jobqueue, jobs=args.jobs,
                               retry_failed=args.retry_failed, batch=args.batch)
    except ScenarioError as exc:  # SweepError and the output checks
        print(f"usv-mj sweep: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\nusv-mj sweep: interrupted: the runs finished so far are in {out}/results.parquet; "
              f"run the same command with --resume to finish the sweep", file=sys.stderr)
        return 1
    except WorkerError as exc:
        print(f"usv-mj sweep: stopped: {exc}; the runs finished so far are in {out}/results.parquet "
              f"(--resume runs the rest)", file=sys.stderr)
        return 1
    if not result.complete:
        print(f"{len(result.rows)} of {len(plan.runs)} runs in {out}/results.parquet; run again with "
              f"--resume for the rest")
        return 0
    from usv_mj.jobs.sweep.report import passed_rate

    print(f"{len(result.rows)} runs ({result.ran} run now): {passed_rate(result.rows)}; {result.failed} diverged or "
          f"failed; {out}/results.parquet, {out}/report.md")
    return flags.report_failed(result.rows, "usv-mj sweep", "run")

