"""``usv-mj compare``: the same scenario on the analytic and the MuJoCo plant (:mod:`usv_mj.jobs.compare`)."""

from __future__ import annotations

import math
import os
import sys

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError


def add_arguments(p) -> None:
    flags.add_scenario_arguments(p)
    flags.add_vessel_argument(p)
    flags.add_out_argument(p, "output folder (default renders/compare-<name>)")
    flags.add_overwrite_argument(p, "--out whole when it holds an earlier usv_mj output")
    flags.add_quiet_argument(p)


@COMMANDS.register(
    "compare", arguments=add_arguments,
    help="the same scenario on the analytic and the MuJoCo plant, with the differences",
    description="Run the same scenario on the analytic plant and the MuJoCo plant and report how far they\n"
                "differ: open loop under a rich thrust sequence (with a convergence study in the time step)\n"
                "and in closed loop with the scenario's controller. Writes compare.json, compare.md and\n"
                "figures into --out. Exit 1 when a difference is outside its tolerance.")
def run(args) -> int:
    """0 when every check of ``compare.json`` passes, 1 otherwise; bad input is a ScenarioError (exit 2)."""
    from usv_mj.jobs.compare import CompareInterrupted, compare_plants, report_lines, write_markdown
    from usv_mj.outputs.outdir import Staging, check_folder

    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise ScenarioError(f"--duration must be a number of seconds > 0, got {args.duration!r}")
    scenario = flags.scenario_from_args(args)
    name = os.path.splitext(os.path.basename(args.scenario))[0] if args.scenario else (args.preset or "paper")
    if getattr(args, "vessel", None):
        name += "-" + os.path.splitext(os.path.basename(args.vessel))[0]
    out = args.out or os.path.join("renders", f"compare-{name}")
    check_folder(out, args.overwrite)
    stage = Staging(out)
    try:
        result = compare_plants(scenario, str(stage.path), progress=not args.quiet)
    except CompareInterrupted as exc:  # compare.json (passed: false, what stopped) is put in place
        stage.commit()
        print(f"usv-mj compare: {exc}; nothing was judged (compare.json says passed: false)", file=sys.stderr)
        return 1
    except BaseException:
        stage.discard()
        raise
    lines = report_lines(result)
    for line in lines:
        print(line)
    try:
        write_markdown(os.path.join(str(stage.path), "compare.md"), scenario, lines)
    except OSError as exc:
        stage.discard()
        print(f"usv-mj compare: cannot write {out}/compare.md: {exc.strerror or exc}", file=sys.stderr)
        return 1
    stage.commit()
    print(f"written to {out}/compare.json, compare.md (+ open_loop.png, closed_loop.png, convergence.png)")
    return 0 if result["passed"] else 1
