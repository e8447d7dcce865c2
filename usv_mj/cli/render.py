"""``usv-mj render RUN``: the video of a recorded run again (:func:`usv_mj.outputs.render.render_run`), or
its log replayed to Foxglove (--live)."""

from __future__ import annotations

import sys

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS


def add_arguments(p) -> None:
    p.add_argument("run", metavar="RUN", help="a run directory (holding run.mcap) or an .mcap file")
    flags.add_out_argument(p, "the .mp4 to write, or a folder that exists (the video goes in it as run.mp4, or "
                              "<stem>.mp4 for an .mcap file; default: beside the run)", metavar="OUT")
    flags.add_quiet_argument(p)
    flags.add_overwrite_argument(p, "the .mp4 and its .png still when usv_mj wrote them")
    flags.add_video_arguments(p)
    flags.add_live_arguments(p)   # --live: replay the log to Foxglove instead of drawing a video


@COMMANDS.register("render", arguments=add_arguments,
                   help="the video of a recorded run again (another size, speed or camera)",
                   description="Draw the video of a recorded run again from its run.mcap alone: another size, "
                   "frame rate,\nspeed-up or camera (top, chase, overview, chart). Writes video.mp4 and video.png.")
def run(args) -> int:
    """0 on success, 2 on bad input, 3 when no OpenGL backend starts."""
    from usv_mj.outputs.render.gl_backend import GLUnavailableError
    from usv_mj.outputs.render.video import load_run_log, output_path, render_run, stored_record

    try:
        stored = stored_record(args.run) if not getattr(args, "live", False) else None
        if stored is not None:   # a long run's record on disk: read lazily, only the rows drawn
            record, mcap = stored
            log = None
        else:
            log, mcap = load_run_log(args.run)
            record = log.record
    except (FileNotFoundError, ValueError, RuntimeError) as exc:
        print(f"usv-mj render: error: {exc}", file=sys.stderr)
        return 2
    if log is None and record.status != "completed":
        print(f"usv-mj render: warning: the run's record says {record.status}: {record.stop_reason}", file=sys.stderr)
    elif log is not None and log.notice:
        print(f"usv-mj render: warning: the log is incomplete, the video shows what was recovered: {log.notice}",
              file=sys.stderr)
    if getattr(args, "live", False):
        live = flags.live_server(args)
        n = live.replay(mcap)
        live.finish()
        print(f"usv-mj render: served {n} messages of {mcap} live")
        return 0
    out = output_path(args.out, args.run, mcap)
    try:
        from usv_mj.outputs.outdir import check_file, record_file

        check_file(out, args.overwrite)
    except ValueError as exc:
        print(f"usv-mj render: error: {exc}", file=sys.stderr)
        return 2
    fleet, domain = _fleet_of(log, args.run) if not getattr(args, "live", False) else (None, 0.0)
    if fleet is not None:   # a fleet's log: the own ship's record, every other vessel drawn beside it
        record = fleet.own_record
    try:
        result = render_run(record, out, progress=not args.quiet, fleet=fleet, domain=domain,
                            **flags.video_options(args))
        record_file(out)
    except GLUnavailableError as exc:
        print(f"usv-mj render: {exc}", file=sys.stderr)
        return 3
    except ValueError as exc:
        print(f"usv-mj render: error: {exc}", file=sys.stderr)
        return 2
    print(f"video {result['mp4']} ({result['frames']} frames, {result['width']}x{result['height']} at "
          f"{result['video_fps']:g} fps, {result['speedup']:.3g}x) and still {result['png']}")
    print(f"rendered {result['fps']:.1f} frames/s in {result['wall_s']:.1f} s on {result['workers']} "
          f"worker(s), GL {result['gl']} ({result['gl_renderer'] or 'unknown renderer'})")
    return 0


def _fleet_of(log, run_path):
    """(the FleetRecord, its safety domain [m]) of a fleet's log (usv_mj.jobs.fleet), else (None, 0)."""
    if log is None:
        return None, 0.0
    from usv_mj.outputs.log.fleet_log import fleet_of_log

    fleet = fleet_of_log(log)
    if fleet is None:
        return None, 0.0
    from usv_mj.record.encounters import encounter_summary

    return fleet, float(encounter_summary(fleet).get("safety_domain_m") or 0.0)
