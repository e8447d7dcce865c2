"""``usv-mj run``: one scenario end to end (:func:`usv_mj.jobs.run.run_job`): video, figures, MCAP log, report."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from usv_mj.cli import args as flags
from usv_mj.cli.args import EXIT_OK, EXIT_STOPPED
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError


def add_arguments(p) -> None:
    flags.add_scenario_arguments(p)
    flags.add_plant_argument(p)
    flags.add_vessel_argument(p)
    flags.add_out_argument(p, "output folder (default renders/<preset or scenario name>)")
    p.add_argument("--no-video", action="store_true", help="skip the video")
    p.add_argument("--no-baseline", action="store_true", help="skip the PI baseline run")
    p.add_argument("--no-log", action="store_true", help="skip the MCAP log")
    flags.add_log_rate_argument(p)
    flags.add_overwrite_argument(p, "--out whole when it holds an earlier usv_mj output")
    flags.add_debug_argument(p)
    flags.add_video_arguments(p)
    flags.add_live_arguments(p)
    flags.add_quiet_argument(p)


@COMMANDS.register("run", arguments=add_arguments, help="run a scenario: video, figures, MCAP log, report",
                   description="Run one scenario end to end. With no options: the paper scenario (docs/model.md "
                   "§4-5) on the MuJoCo plant for 300 s, then the PI baseline, writing summary.json, report.md, "
                   "figures/, run.mcap (baseline.mcap), video.mp4 and video.png into --out.")
def run(args) -> int:
    from usv_mj.jobs.run import RunFailed, one_screen_summary, run_job

    scenario = flags.scenario_from_args(args)
    render_options = flags.video_options(args)
    name = Path(args.scenario).stem if args.scenario else scenario.preset
    out = Path(args.out) if args.out is not None else Path("renders") / name
    if args.out is not None and args.out.strip() == "":
        raise ScenarioError("--out '': an empty path; name the output folder")
    if args.live and args.no_log:
        raise ScenarioError("--live serves the run log's messages: drop --no-log")
    live = flags.live_server(args)
    t0 = time.perf_counter()
    if scenario.vessels:   # several vessels in one sea: the fleet's job (usv_mj.jobs.fleet)
        return _run_fleet(args, scenario, out, live, t0)
    try:
        result = run_job(scenario, out, baseline=False if args.no_baseline else None, video=not args.no_video,
                         log=not args.no_log, progress=not args.quiet,
                         render_options=render_options, overwrite=args.overwrite, log_rate=args.log_rate,
                         live=live)
        if live is not None:
            live.finish()
    except RunFailed as exc:
        return _failed(args, exc, live)
    print(one_screen_summary(result, time.perf_counter() - t0))
    if result.summary.get("job_stopped"):
        print(f"usv-mj run: the job stopped early: {result.summary['job_stopped']}; missing outputs: "
              f"{', '.join(result.summary.get('missing_outputs') or []) or 'none'}", file=sys.stderr)
    elif result.summary["status"] != "completed":
        print(f"usv-mj run: the run {result.summary['status']}: {result.summary.get('stop_reason')}", file=sys.stderr)
    if result.summary["status"] != "completed" or result.summary.get("job_stopped"):
        return EXIT_STOPPED
    return EXIT_OK


def _failed(args, exc, live) -> int:
    """A job that failed (``RunFailed``): the live view closed, one line saying where its files are
    (with --debug, the traceback it kept first), exit 1."""
    if live is not None:
        live.close()
    if args.debug and exc.traceback is not None and Path(exc.traceback).is_file():
        sys.stderr.write(Path(exc.traceback).read_text())
    print(f"usv-mj run: {exc}", file=sys.stderr)
    return EXIT_STOPPED


def _run_fleet(args, scenario, out, live, t0) -> int:
    from usv_mj.jobs.fleet import one_screen_fleet_summary, run_fleet_job
    from usv_mj.jobs.run import RunFailed

    try:
        result = run_fleet_job(scenario, out, log=not args.no_log, progress=not args.quiet, overwrite=args.overwrite,
                               live=live, video=not args.no_video, render_options=flags.video_options(args))
    except RunFailed as exc:      # as a single run's: one line, where the files are, exit 1
        return _failed(args, exc, live)
    if live is not None:
        live.finish()
    print(one_screen_fleet_summary(result, time.perf_counter() - t0))
    if result.summary["status"] != "completed":
        print(f"usv-mj run: the run {result.summary['status']}: {result.summary.get('stop_reason')}", file=sys.stderr)
        return EXIT_STOPPED
    return EXIT_OK
