"""Monte-Carlo sweeps and capability plots on Dask.

    usv-mj sweep SWEEP.toml --out DIR [--workers N | --scheduler ADDRESS | --jobqueue slurm --jobs N]
                 [--resume] [--keep-logs] [--max-runs N]
    usv-mj capability --load disturbance|current|wind|waves --out DIR [--base paper] [--duration S]

A sweep file names a base and what varies, by dotted path into the scenario (docs/model.md §7)::

    base = "paper"                 # preset or scenario file
    duration = 60.0
    samples = 50                   # draws per grid point
    seed = 7
    [vary]
    "initial.eta[0]" = { uniform = [-8.0, 8.0] }      # uniform, loguniform, normal, integers, choice
    "disturbance.scale" = [1e-4, 5e-4, 1e-3]          # a list is a grid axis

Every sampled scenario is validated before anything runs (a bad path or range: exit 2). Each run
is one Dask task; its row (varied values, status ok/diverged/failed and why, every summary.json
field) streams into DIR/results.parquet; --resume runs only the missing ones; DIR/report.md has the
rate of runs that passed their controller's criterion (Wilson 95 %), error histograms, scatter plots
and the failures. By default a local cluster with one worker process per core; --scheduler tcp://HOST:8786 uses any running Dask cluster
(``dask scheduler`` on one machine, ``dask worker tcp://HOST:8786 --nthreads 1 --nworkers N`` on
each other, every one with usv_mj installed); --jobqueue uses a batch system via dask-jobqueue.

Python API::

    from usv_mj.jobs.sweep import load_sweep, run_sweep, read_results
    plan = load_sweep("examples/sweeps/start_pose.toml")   # sampled and validated, nothing run yet
    result = run_sweep(plan, "out/start_pose", workers=2)   # DIR/results.parquet + DIR/report.md
    rows, _ = read_results("out/start_pose/results.parquet")

The sweep file format is in :mod:`usv_mj.jobs.sweep.spec`; the row columns in :mod:`usv_mj.jobs.sweep.runner`;
the capability search in :mod:`usv_mj.jobs.sweep.capability`.
"""

from __future__ import annotations

from usv_mj.core.errors import ScenarioError

import argparse

from usv_mj.jobs.sweep.spec import SweepError, SweepPlan, load_sweep, parse_path, plan_sweep

__all__ = ["SweepError", "SweepPlan", "load_sweep", "plan_sweep", "parse_path", "run_sweep", "read_results",
           "add_arguments", "run_command", "add_capability_arguments", "capability_command"]


def run_sweep(*args, **kwargs):
    """See :func:`usv_mj.jobs.sweep.runner.run_sweep` (imported lazily: Dask loads only when a sweep runs)."""
    from usv_mj.jobs.sweep.runner import run_sweep as _run

    return _run(*args, **kwargs)


def read_results(path):
    """See :func:`usv_mj.jobs.sweep.runner.read_results`: (rows sorted by run id, plan fingerprint)."""
    from usv_mj.jobs.sweep.runner import read_results as _read

    return _read(path)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``usv-mj sweep``."""
    parser.add_argument("sweep", help="the sweep file (TOML: base, duration, samples, seed, [set], [vary])")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="output folder for results.parquet, report.md, figures/ (default renders/sweep-<file name>)")
    parser.add_argument("--scheduler", default=None,
                        help="address of a running Dask scheduler (tcp://host:8786); default: a local cluster")
    parser.add_argument("--jobqueue", default=None, metavar="SYSTEM",
                        help="run on a batch system through dask-jobqueue (slurm, pbs, sge, lsf, ...); job size "
                             "from ~/.config/dask/jobqueue.yaml")
    parser.add_argument("--jobs", type=int, default=1, help="--jobqueue: number of batch jobs (default 1)")
    parser.add_argument("--workers", type=int, default=None,
                        help="local cluster: worker processes (default: the number of cores)")
    parser.add_argument("--resume", action="store_true", help="run only the runs missing from DIR/results.parquet")
    from usv_mj.outputs.outdir import add_overwrite_argument

    add_overwrite_argument(parser, "--out whole when it holds an earlier usv_mj output (the new sweep is "
                                   "written beside it and moved into place when it ends)")
    parser.add_argument("--retry-failed", action="store_true",
                        help="with --resume: run the failed runs again too (diverged ones are results and stay)")
    parser.add_argument("--keep-logs", action="store_true", help="write an MCAP log of every run to DIR/logs/")
    parser.add_argument("--log-rate", type=float, metavar="HZ",
                        help="with --keep-logs: log every n-th control step (e.g. 10: 10 Hz); default every step")
    parser.add_argument("--max-runs", type=int, default=None,
                        help="run at most N runs now, then stop (--resume continues): sweeps in chunks")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_command(args: argparse.Namespace) -> int:
    """``usv-mj sweep``: 0 when every run was recorded, 2 on a bad sweep file or option, 1 when interrupted."""
    import sys

    from pathlib import Path

    if args.out is None:
        args.out = str(Path("renders") / f"sweep-{Path(args.sweep).stem}")
    try:
        from usv_mj.outputs.outdir import check_folder, results_folder

        if args.resume and args.overwrite:
            raise SweepError("--resume continues the sweep in --out, --overwrite replaces it: give one of them")
        check_folder(args.out, args.overwrite, resume=args.resume)
        plan = load_sweep(args.sweep)
        if args.workers is not None and args.workers < 1:
            raise SweepError(f"--workers must be >= 1, got {args.workers}")
        if getattr(args, "retry_failed", False) and not args.resume:
            raise SweepError("--retry-failed goes with --resume")
        max_runs = getattr(args, "max_runs", None)
        if max_runs is not None and max_runs < 1:
            raise SweepError(f"--max-runs must be >= 1, got {max_runs}")
        log_rate = getattr(args, "log_rate", None)
        if log_rate is not None:
            from usv_mj.outputs.log.writer import log_every

            if not args.keep_logs:
                raise SweepError("--log-rate goes with --keep-logs")
            for run in plan.runs:   # every run's control period must allow the rate
                log_every(log_rate, run.scenario.control_period)
        print(f"{args.sweep}: {len(plan.runs)} runs, all validated", flush=True)
        with results_folder(args.out, args.resume) as folder:   # staged when it replaces an earlier output
            result = run_sweep(plan, folder, scheduler=args.scheduler,
                               workers=args.workers, resume=args.resume,
                               keep_logs=args.keep_logs, log_rate=log_rate,
                               progress=not getattr(args, "no_progress", False),
                               max_runs=max_runs, jobqueue=getattr(args, "jobqueue", None),
                               jobs=getattr(args, "jobs", 1), retry_failed=getattr(args, "retry_failed", False))
    except ScenarioError as exc:  # SweepError and the output checks
        print(f"usv-mj sweep: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\nusv-mj sweep: interrupted: the runs finished so far are in {args.out}/results.parquet; "
              f"run the same command with --resume to finish the sweep", file=sys.stderr)
        return 1
    if not result.complete:
        print(f"{len(result.rows)} of {len(plan.runs)} runs in {args.out}/results.parquet; run again with "
              f"--resume for the rest")
        return 0
    from usv_mj.jobs.sweep.report import passed_rate

    print(f"{len(result.rows)} runs ({result.ran} run now): {passed_rate(result.rows)}; {result.failed} diverged or "
          f"failed; {args.out}/results.parquet, {args.out}/report.md")
    return 0


def add_capability_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``usv-mj capability``."""
    from usv_mj.jobs.sweep.capability import add_capability_arguments as _add

    _add(parser)


def capability_command(args: argparse.Namespace) -> int:
    """``usv-mj capability``: 0 on success, 2 on bad input or a load that is not available yet."""
    from usv_mj.jobs.sweep.capability import capability_command as _cmd

    return _cmd(args)
