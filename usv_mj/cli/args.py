"""The flags the commands share, each declared here once, and the exit codes.

Every command module (:mod:`usv_mj.cli.run`, ...) builds its options from these functions, so that
a flag has one spelling, one help text and one meaning wherever it appears: the scenario's
(--preset, --scenario, --set, --duration, --sea), the hull's and the plant's (--vessel, --plant, whose
kinds come from the registries of :mod:`usv_mj.core.registry`), the outputs' (--out, --overwrite,
-q/--quiet, --debug, --log-rate), the video's (--size, --fps, --speedup, --camera, --workers, --gl,
--shadows), the live view's (--live, --live-port, --live-wait, --speed) and a cluster's (--scheduler,
--jobqueue, --jobs, --workers, --resume, --max-runs). Where a command says something of its own (what
--out holds, what --overwrite replaces, what --duration sets), it passes those words; the flag
itself stays the same. Old spellings are hidden aliases: --no-progress (-q), --video-size (--size),
--base (--scenario of capability).

Importing this module imports argparse, the registries and the standard library only: the values
the flags turn into (a scenario, a live server, the video's options) are made by the functions at
the end, which import the library when a command runs.
"""

from __future__ import annotations

import argparse
import math
import sys

from usv_mj.core.errors import ScenarioError, TooManyStepsError
from usv_mj.core.registry import PLANTS, VESSELS
from usv_mj.scenario.overrides import parse_set, with_vessel  # noqa: F401 (the commands' names)

#: the exit codes of every command: done, stopped early, bad input, no OpenGL (usv_mj.cli.main's docstring)
EXIT_OK, EXIT_STOPPED, EXIT_BAD_INPUT, EXIT_NO_GL = 0, 1, 2, 3


class Choices:
    """The choices of a flag, read from their module when first needed, so that building the parser
    imports none of them: ``name`` is a list or a dotted path to a callable that gives one
    (``Choices("usv_mj.core.registry", "MANOEUVRES.kinds")``). Two uses:

    - ``choices=Choices(...)`` (with a ``metavar``: argparse reads the choices of a flag without one
      when it is declared): read when a value is parsed or the command's --help is shown;
    - ``type=Choices(...)``: read only when a value is parsed, for a list whose module is heavy
      (``Choices("usv_mj.envs", "ALL_TASKS")``: usv_mj.envs imports gymnasium).

    A bad value is argparse's one line either way: ``invalid choice: 'x' (choose from ...)``."""

    def __init__(self, module: str, name: str):
        self.module, self.name = module, name
        self._values = None

    def values(self) -> tuple:
        if self._values is None:
            import importlib

            values = importlib.import_module(self.module)
            for attr in self.name.split("."):
                values = getattr(values, attr)
            self._values = tuple(values() if callable(values) else values)
        return self._values

    def __iter__(self):
        return iter(self.values())

    def __contains__(self, value) -> bool:
        return value in self.values()

    def __len__(self) -> int:
        return len(self.values())

    def __call__(self, value: str) -> str:
        if value not in self.values():
            raise argparse.ArgumentTypeError(f"invalid choice: {value!r} (choose from "
                                             f"{', '.join(map(repr, self.values()))})")
        return value


# --- value types (argparse's ``type=``) --------------------------------------------------------


def parse_size(text: str) -> tuple[int, int]:
    """'1280x720' -> (1280, 720): the --size of a video."""
    from usv_mj.outputs.render.defaults import check_size

    try:
        w, h = (int(v) for v in str(text).lower().replace("*", "x").split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size {text!r}: expected WIDTHxHEIGHT, e.g. 1280x720") from None
    try:
        check_size(w, h)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--size {text!r}: {exc}") from None
    return w, h


def positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number")
    return v


def frame_rate(text: str) -> float:
    from usv_mj.outputs.render.defaults import MAX_FPS

    v = positive(text)
    if v > MAX_FPS:
        raise argparse.ArgumentTypeError(f"{text!r} is over {MAX_FPS:g} frames per second")
    return v


def count(text: str) -> int:
    """A whole number >= 1 (--workers)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be at least 1")
    return v


def _hidden_alias(p, flag: str, dest: str, **kwargs) -> None:
    """An old spelling of a flag: parsed into the same ``dest``, absent from --help."""
    p.add_argument(flag, dest=dest, default=argparse.SUPPRESS, help=argparse.SUPPRESS, **kwargs)


# --- the scenario ------------------------------------------------------------------------------


def add_scenario_arguments(p, *, duration_help: str | None = None, sea_note: str = "") -> None:
    """--preset, --scenario, --set, --duration, --sea: the scenario a command runs (:func:`scenario_from_args`)."""
    from usv_mj.scenario.presets import names

    p.add_argument("--preset", default=None, help=f"base preset ({', '.join(names())}); default paper")
    p.add_argument("--scenario", metavar="FILE", help="a scenario TOML file (a preset plus overrides; README, Scenarios)")
    add_set_argument(p)
    add_duration_argument(p, duration_help)
    p.add_argument("--sea", metavar="NAME", help="a sea preset on top of the scenario (moderate, steady-current, "
                   "breeze, varying-current): waves, current and wind of docs/sea.md; `usv-mj presets` lists them"
                   + sea_note)


def add_base_argument(p) -> None:
    """--scenario NAME_OR_FILE (default paper) of a command that takes a preset or a file in one flag
    (capability: its ``base``); --base is its old spelling."""
    p.add_argument("--scenario", dest="base", metavar="NAME_OR_FILE", default="paper",
                   help="a preset name or a scenario TOML file (default: paper)")
    _hidden_alias(p, "--base", "base")


def add_set_argument(p, whose: str = "scenario", example: str = "disturbance.scale=1e-3") -> None:
    p.add_argument("--set", metavar="KEY=VALUE", action="append", default=[],
                   help=f"override one value of the {whose} by dotted key, e.g. --set {example}")


def add_duration_argument(p, help: str | None = None) -> None:
    p.add_argument("--duration", type=float, default=None,
                   help=help or "simulated time [s] (default: the scenario's)")


def add_plant_argument(p, *, default: str | None = None, help: str = "which plant integrates the ship") -> None:
    """--plant KIND: a kind of the plant registry (``usv-mj kinds plant``)."""
    p.add_argument("--plant", choices=PLANTS.kinds(), default=default, help=help)


def only_mujoco(plant: str, what: str) -> None:
    """The --plant of a command that shows the MuJoCo plant itself (scene, view): mujoco, or a bad input."""
    if plant != "mujoco":
        raise ScenarioError(f"--plant {plant}: {what} (the only choice is mujoco)")


def add_vessel_argument(p, *, fleet: bool = False, use: str = "shorthand for --set vessel.kind=KIND") -> None:
    """--vessel KIND: a kind of the vessel registry or a vessel data file (``use``: what the command
    does with it, by default shorthand for --set vessel.kind=KIND); ``fleet``: also a list of kinds, or 'all'."""
    p.add_argument("--vessel", metavar="KIND", help=f"the hull: a vessel kind ({', '.join(VESSELS.kinds())}; "
                   f"`usv-mj kinds vessel`) or a vessel data file; {use}"
                   + ("; here also a list KIND,KIND,... or 'all' (every registered vessel): one run each into "
                      "--out/KIND/, and their tracks and measures side by side" if fleet else ""))


# --- outputs -----------------------------------------------------------------------------------


def add_out_argument(p, help: str, *, default: str | None = None, metavar: str = "DIR") -> None:
    """--out: where the command writes (``help``: what and the default)."""
    p.add_argument("--out", metavar=metavar, default=default, help=help)


def add_overwrite_argument(p, what: str) -> None:
    """--overwrite: replace ``what`` when a usv_mj command wrote it (usv_mj.outputs.outdir)."""
    from usv_mj.outputs.outdir import MANIFEST

    p.add_argument("--overwrite", action="store_true",
                   help=f"replace {what} (listed in its folder's {MANIFEST}); anything usv_mj did not "
                        "write is never replaced: such an output is refused")


def add_quiet_argument(p) -> None:
    """-q/--quiet (dest ``quiet``); --no-progress is its old spelling."""
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bars or progress messages (the result's summary lines are still printed)")
    _hidden_alias(p, "--no-progress", "quiet", action="store_true")


def add_debug_argument(p) -> None:
    p.add_argument("--debug", action="store_true", help="print the traceback of a crash (always in traceback.txt)")


def add_log_rate_argument(p, note: str = "") -> None:
    p.add_argument("--log-rate", type=float, metavar="HZ",
                   help=f"{note}log every n-th control step to the MCAP (e.g. 10: 10 Hz); default every step")


def add_json_argument(p) -> None:
    p.add_argument("--json", action="store_true", help="print the same facts as one JSON object")


# --- the video ---------------------------------------------------------------------------------


def add_size_argument(p, default: tuple[int, int] | None = None) -> None:
    """--size WxH (dest ``size``, a (width, height) tuple); --video-size is its old spelling."""
    from usv_mj.outputs.render.defaults import DEFAULT_HEIGHT, DEFAULT_WIDTH

    w, h = default or (DEFAULT_WIDTH, DEFAULT_HEIGHT)
    p.add_argument("--size", type=parse_size, default=(w, h), metavar="WxH", help=f"video size in pixels (default {w}x{h})")
    _hidden_alias(p, "--video-size", "size", type=parse_size, metavar="WxH")


def add_workers_argument(p, what: str) -> None:
    """--workers N (>= 1): ``what`` works in that many processes."""
    p.add_argument("--workers", type=count, default=None, metavar="N",
                   help=f"{what}: worker processes (default: one per core)")


def add_video_arguments(p) -> None:
    """The video's options (usv-mj run, render, manoeuvre): :func:`video_options` turns them into
    the keyword arguments of :func:`usv_mj.outputs.render.render_run`."""
    from usv_mj.outputs.render.defaults import CAMERAS_HELP, DEFAULT_FPS, MAX_FPS
    from usv_mj.outputs.render.gl_backend import BACKENDS

    g = p.add_argument_group("video")
    add_size_argument(g)
    g.add_argument("--fps", type=frame_rate, default=DEFAULT_FPS,
                   help=f"video frame rate, up to {MAX_FPS:g} (default {DEFAULT_FPS:g})")
    g.add_argument("--speedup", type=positive, default=None,
                   help="run seconds per video second (default: the run's duration / 30 s, at least 1)")
    g.add_argument("--camera", default="top", help=CAMERAS_HELP + " (default top)")
    add_workers_argument(g, "rendering")
    g.add_argument("--gl", choices=("auto", *BACKENDS), default=None,
                   help="OpenGL backend (default: $MUJOCO_GL, else EGL, else OSMesa)")
    g.add_argument("--shadows", action="store_true", help="draw shadows (about 2x slower on Mesa)")


def video_options(args) -> dict:
    """The keyword arguments of :func:`usv_mj.outputs.render.render_run` from :func:`add_video_arguments`'s flags."""
    w, h = args.size
    return {"width": w, "height": h, "fps": args.fps, "speedup": args.speedup, "camera": args.camera,
            "workers": args.workers, "gl": args.gl, "shadows": args.shadows}


# --- the live view -----------------------------------------------------------------------------


def add_speed_argument(p, *, default: float | None = None, help: str | None = None) -> None:
    p.add_argument("--speed", type=float, default=default, metavar="X",
                   help=help or "with --live: X times real time (1: real time; default: as fast as it runs)")


def add_live_arguments(p, speed: bool = True) -> None:
    """--live, --live-port, --live-wait (and --speed): usv_mj.outputs.log.live (README, Live ...)."""
    p.add_argument("--live", action="store_true", help="serve the run to Foxglove over its WebSocket protocol "
                   "as it runs (needs pip install \"usv_mj[live]\"); the log is still written in full")
    p.add_argument("--live-port", type=int, default=8765, metavar="PORT",
                   help="the live server's TCP port on 127.0.0.1 (default 8765; 0: any free port)")
    p.add_argument("--live-wait", type=float, default=None, metavar="S",
                   help="wait at most S seconds for a viewer before streaming (default: until one connects)")
    if speed:
        add_speed_argument(p)


def live_server(args):
    """The LiveServer of --live (None without it); ScenarioError naming the pip extra if it is missing."""
    if not getattr(args, "live", False):
        return None
    from usv_mj.outputs.log.live import LiveServer, layout_path

    server = LiveServer(port=args.live_port, speed=getattr(args, "speed", None), wait_s=args.live_wait)
    print(f"usv-mj {args.command}: live on {server.url} (Foxglove: Open connection, Foxglove WebSocket; "
          f"the layout: Layouts, Import from file, {layout_path()})", file=sys.stderr, flush=True)
    return server


# --- a cluster (sweep, capability, bench) ------------------------------------------------------


def add_cluster_arguments(p, *, batch: bool = True) -> None:
    """--scheduler, --workers (and with ``batch``: --jobqueue, --jobs): where the runs go (Dask)."""
    p.add_argument("--scheduler", default=None,
                   help="address of a running Dask scheduler (tcp://host:8786); default: a local cluster")
    if batch:
        p.add_argument("--jobqueue", default=None, metavar="SYSTEM",
                       help="run on a batch system through dask-jobqueue (slurm, pbs, sge, lsf, ...); job size "
                            "from ~/.config/dask/jobqueue.yaml")
        p.add_argument("--jobs", type=int, default=1, help="--jobqueue: number of batch jobs (default 1)")
    add_workers_argument(p, "local cluster")


def add_batch_argument(p, runs: str) -> None:
    """--batch N: up to N of the ``runs`` per Dask task, simulated together in one compiled batch
    (usv_mj.loop.batch; the same rows as one task per run)."""
    p.add_argument("--batch", type=count, default=1, metavar="N",
                   help=f"run up to N {runs} per task, together in one compiled batch (the same results; "
                        f"default 1)")


def add_resume_arguments(p, runs: str) -> None:
    """--resume and --max-runs of a job whose ``runs`` stream into DIR/results.parquet."""
    p.add_argument("--resume", action="store_true", help=f"run only the {runs} missing from DIR/results.parquet")
    p.add_argument("--max-runs", type=int, default=None,
                   help=f"run at most N {runs} now, then stop (--resume continues): a long job in chunks")


# --- from the flags to the library's values ------------------------------------------------------


def scenario_from_args(args):
    """The Scenario of :func:`add_scenario_arguments`'s flags (and --plant, --vessel where the command has them)."""
    from usv_mj.scenario.spec import load_scenario, merge_tables

    overrides = {}
    if getattr(args, "sea", None) is not None:
        overrides["sea"] = {"preset": args.sea}
    sets = parse_set(args.set)
    vessel = getattr(args, "vessel", None)
    # every value of the file and of --set is checked, even one that a flag below replaces; but the
    # step count (duration / control_period) only on the duration that runs: --duration's, if given.
    # --set vessel.KEY belongs to --vessel's kind, so that kind is in the check too
    try:
        load_scenario(args.scenario, preset=args.preset, overrides=with_vessel(vessel, merge_tables(overrides, sets))
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
    return load_scenario(args.scenario, preset=args.preset, overrides=with_vessel(vessel, overrides))


def report_failed(rows: list[dict], prog: str, noun: str, show: int = 5) -> int:
    """One line on stderr for each of the first ``show`` runs that failed (no result: raised, or its
    worker died), naming it and why; 1 when any did, else 0. (Diverged runs are results.)"""
    failed = [r for r in rows if r.get("status") == "failed"]
    for r in failed[:show]:
        print(f"{prog}: {noun} {r['run_id']} failed: {r.get('reason')}", file=sys.stderr)
    if len(failed) > show:
        print(f"{prog}: ... and {len(failed) - show} more failed {noun}s (report.md lists them)", file=sys.stderr)
    if failed:
        print(f"{prog}: {len(failed)} {noun}(s) failed; --resume --retry-failed runs them again", file=sys.stderr)
    return 1 if failed else 0
