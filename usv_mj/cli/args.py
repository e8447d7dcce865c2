"""The options and helpers every command shares: the scenario options (--preset, --scenario, --set,
--duration, --sea, --vessel), the live options (--live, --live-port, --live-wait, --speed) and the
exit codes.

A command module (``compare``, ``view``, ``scene_export``, ``envs.cli``, ``render.video``,
``manoeuvres.cli``) imports them
from here, never from ``usv_mj.cli.main``: the command line imports the library, not the other way round.
``usv_mj.cli.main`` re-exports these names for code written against it.
"""

from __future__ import annotations

import argparse
import sys

from usv_mj.core.errors import TooManyStepsError
from usv_mj.scenario.overrides import parse_set, with_vessel  # noqa: F401 (the commands' names)
from usv_mj.scenario.spec import ScenarioError, load_scenario, merge_tables, preset_names

#: the exit codes of every command: done, stopped early, bad input, no OpenGL (usv_mj.cli.main's docstring)
EXIT_OK, EXIT_STOPPED, EXIT_BAD_INPUT, EXIT_NO_GL = 0, 1, 2, 3


def add_scenario_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", default=None, help=f"base preset ({', '.join(preset_names())}); default paper")
    p.add_argument("--scenario", metavar="FILE", help="a scenario TOML file (a preset plus overrides; README, Scenarios)")
    p.add_argument("--set", metavar="KEY=VALUE", action="append", default=[],
                   help="override one scenario value by dotted key, e.g. --set disturbance.scale=1e-3")
    p.add_argument("--duration", type=float, help="simulated time [s] (default: the scenario's)")
    p.add_argument("--sea", metavar="NAME", help="a sea preset on top of the scenario (moderate, steady-current, "
                   "breeze, varying-current): waves, current and wind of docs/sea.md; `usv-mj presets` lists them")


def add_vessel_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--vessel", metavar="KIND", help="the hull: a vessel kind (paper, cybership2, otter, clarke83, kvlcc2; "
                   "`usv-mj kinds vessel`) or a vessel data file; shorthand for --set vessel.kind=KIND")


def _with_vessel(args, overrides: dict) -> dict:
    """``overrides`` with --vessel's kind: shorthand for --set vessel.kind=X (docs/vessels.md)."""
    return with_vessel(getattr(args, "vessel", None), overrides)


def scenario_from_args(args):
    overrides = {}
    if getattr(args, "sea", None) is not None:
        overrides["sea"] = {"preset": args.sea}
    sets = parse_set(args.set)
    # every value of the file and of --set is checked, even one that a flag below replaces; but the
    # step count (duration / control_period) only on the duration that runs: --duration's, if given.
    # --set vessel.KEY belongs to --vessel's kind, so that kind is in the check too
    try:
        load_scenario(args.scenario, preset=args.preset, overrides=_with_vessel(args, merge_tables(overrides, sets))
                      or None)
    except ScenarioError as exc:
        if not (args.duration is not None and isinstance(exc, TooManyStepsError)):
            typed = list(args.set)[getattr(args, "implied_sets", 0):]   # not those a command adds itself
            if not sets or not typed:
                raise
            raise ScenarioError(f"--set {' --set '.join(typed)}: {exc}") from None
    overrides = merge_tables(overrides, sets)
    if args.duration is not None:
        overrides["duration"] = args.duration
    if getattr(args, "plant", None):
        if not isinstance(overrides.get("plant", {}), dict):
            raise ScenarioError(f"--set plant={overrides['plant']!r}: [plant] must be a table (with --plant "
                                "give --set plant.kind=... or drop one of them)")
        overrides.setdefault("plant", {})["kind"] = args.plant
    return load_scenario(args.scenario, preset=args.preset, overrides=_with_vessel(args, overrides))


def add_live_arguments(p, speed: bool = True) -> None:
    """--live, --live-port, --live-wait (and --speed): usv_mj.outputs.log.live (README, Live ...)."""
    p.add_argument("--live", action="store_true", help="serve the run to Foxglove over its WebSocket protocol "
                   "as it runs (needs pip install \"usv_mj[live]\"); the log is still written in full")
    p.add_argument("--live-port", type=int, default=8765, metavar="PORT",
                   help="the live server's TCP port on 127.0.0.1 (default 8765; 0: any free port)")
    p.add_argument("--live-wait", type=float, default=None, metavar="S",
                   help="wait at most S seconds for a viewer before streaming (default: until one connects)")
    if speed:
        p.add_argument("--speed", type=float, default=None, metavar="X",
                       help="with --live: X times real time (1: real time; default: as fast as it runs)")


def live_server(args):
    """The LiveServer of --live (None without it); ScenarioError naming the pip extra if it is missing."""
    if not getattr(args, "live", False):
        return None
    from usv_mj.outputs.log.live import LiveServer, layout_path

    server = LiveServer(port=args.live_port, speed=getattr(args, "speed", None), wait_s=args.live_wait)
    print(f"usv-mj {args.command}: live on {server.url} (Foxglove: Open connection, Foxglove WebSocket; "
          f"the layout: Layouts, Import from file, {layout_path()})", file=sys.stderr, flush=True)
    return server
