"""``usv-mj view`` (or ``python -m usv_mj.cli.view``): MuJoCo's interactive viewer on a running scenario
(:mod:`usv_mj.jobs.view`), ``--manual`` driven by the arrow keys. Without a display it says so in one
line and exits 3.
"""

from __future__ import annotations

import sys

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS

EXIT_NO_DISPLAY = 3

if __name__ == "__main__":   # python -m usv_mj.cli.view: the registered command (this module, imported by name)
    from usv_mj.cli.main import main

    sys.exit(main(["view", *sys.argv[1:]]))


def add_arguments(p) -> None:
    flags.add_scenario_arguments(p)
    flags.add_vessel_argument(p)   # as `usv-mj run --vessel` (README: view takes run's scenario flags)
    flags.add_plant_argument(p, default="mujoco", help="the viewer shows the MuJoCo plant (the only choice)")
    p.add_argument("--manual", action="store_true",
                   help="drive it yourself: arrows up/down surge, left/right yaw, space zero (open loop)")
    flags.add_speed_argument(p, default=1.0, help="X times real time (default 1)")


@COMMANDS.register(
    "view", arguments=add_arguments,
    help="MuJoCo's viewer on the scenario: water, sea and controller acting; --manual drives with the arrows",
    description="Open MuJoCo's interactive viewer on the scenario's scene with the hydrodynamics, the sea and\n"
                "the controller acting (needs a display; exit 3 without one). --manual: drive it yourself,\n"
                "arrow keys up/down for surge, left/right for yaw, space to zero the thrust.")
def run(args) -> int:
    from usv_mj.jobs.view import NoDisplay, check_speed, view

    flags.only_mujoco(args.plant, "the viewer shows the MuJoCo plant")
    check_speed(args.speed)   # before the scenario is read, as any bad flag
    scenario = flags.scenario_from_args(args)
    try:
        record, frames = view(scenario, manual=args.manual, speed=args.speed)
    except NoDisplay as exc:
        print(f"usv-mj view: {exc}", file=sys.stderr)
        return EXIT_NO_DISPLAY
    x = record.data[record.n_rows - 1] if record.n_rows else None
    where = f"; at t = {x[0]:.2f} s the hull is at ({x[1]:.2f}, {x[2]:.2f}) m" if x is not None else ""
    print(f"usv-mj view: {record.status} after {frames} frames{where}")
    return 0 if record.status in ("completed", "interrupted") else 1

