"""``usv-mj capability --load ...``: the environment capability polar of the controller
(:func:`usv_mj.jobs.sweep.capability.run_capability`)."""

from __future__ import annotations

import sys
from pathlib import Path

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError, WorkerError
from usv_mj.jobs.sweep.loads import LOADS


def add_arguments(p) -> None:
    p.add_argument("--load", required=True, choices=sorted(LOADS),
                   help="what to scale: disturbance (d(t) scale s), current, wind or waves (need the sea state)")
    flags.add_base_argument(p)
    flags.add_duration_argument(p, "run length in s (default: the base's)")
    flags.add_plant_argument(p, help="which plant integrates the ship; default: the base's (current, wind and waves "
                                     "need a plant that takes the sea state)")
    p.add_argument("--step", type=float, default=15.0, help="direction step in degrees (default 15)")
    p.add_argument("--min", dest="load_min", type=float, default=None, help="lower end of the search")
    p.add_argument("--max", dest="load_max", type=float, default=None, help="upper end of the search")
    p.add_argument("--tol", type=float, default=0.05, help="stop when (fails - holds) <= tol * fails (default 0.05)")
    flags.add_out_argument(p, "output folder for capability.md, capability.png, capability.json "
                              "(default renders/capability-<load>)")
    flags.add_overwrite_argument(p, "--out whole when it holds an earlier usv_mj output")
    flags.add_cluster_arguments(p, batch=False)
    flags.add_quiet_argument(p)


@COMMANDS.register(
    "capability", arguments=add_arguments,
    help="environment capability polar: the largest load at which the controller's criterion holds",
    description="The environment capability polar (DNV style): for each direction, the largest current,\n"
                "wind or wave load at which the controller's criterion holds (the funnel for the paper's\n"
                "controller), found by bisection. With unlimited actuators it shows the control law's\n"
                "limit, not the vessel's (use a preset with [actuators], e.g. --scenario paper-limited).")
def run(args) -> int:
    """0 on success, 2 on bad input or a load not available yet, 1 when interrupted."""
    from usv_mj.jobs.sweep.capability import run_capability
    from usv_mj.outputs.outdir import Staging, check_folder

    out = args.out if args.out is not None else str(Path("renders") / f"capability-{args.load}")
    try:
        check_folder(out, args.overwrite)
        stage = Staging(Path(out))
        try:
            results = run_capability(args.load, base=args.base, duration=args.duration, plant=args.plant,
                                     step=args.step, load_min=args.load_min, load_max=args.load_max, tol=args.tol,
                                     out=stage.path, scheduler=args.scheduler, workers=args.workers,
                                     progress=not args.quiet)
        except BaseException:
            stage.discard()
            raise
        stage.commit()
    except ScenarioError as exc:  # SweepError and the output checks
        print(f"usv-mj capability: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nusv-mj capability: interrupted", file=sys.stderr)
        return 1
    except WorkerError as exc:
        print(f"usv-mj capability: stopped: {exc}", file=sys.stderr)
        return 1
    for r in results:
        d = "any direction" if r.direction_deg is None else f"{r.direction_deg:g} deg"
        what = r.noun[4:] if r.noun.startswith("the ") else r.noun
        print(f"{d}: {what} holds up to {r.holds}, lost at {r.fails}" + (f" ({'; '.join(r.notes)})" if r.notes else ""))
    print(f"{out}/capability.md, {out}/capability.png")
    return 0
