"""usv-mj: the command line of usv_mj.

    usv-mj run                         the paper scenario on the MuJoCo plant: video, figures, log, report
    usv-mj run --preset harsh --plant analytic --duration 60 --no-video
    usv-mj run --scenario my.toml --set controller.k1=5 --out runs/k1-5
    usv-mj presets                     list the presets; `usv-mj presets paper` prints one
    usv-mj examples                    list the example scenarios and sweeps (--scenario harbour_gap)
    usv-mj compare                     the same scenario on both plants, with the differences
    usv-mj inspect RUN.mcap            what a run log holds
    usv-mj plot RUN.mcap               figures and report again, from the log alone
    usv-mj render RUN.mcap             the video again, at another size, speed or camera
    usv-mj sweep SWEEP.toml            many runs on a Dask cluster (local by default)
    usv-mj capability --load ...       the environment capability polar of the controller
    usv-mj bench [SUITE.toml]          the controller benchmark: a leaderboard with intervals (default suite)
    usv-mj env track --policy ppc      the USV as a dm_control task: roll out a policy, print returns, video
    usv-mj kinds                       every controller, trajectory, plant, disturbance kind and its options
    usv-mj run --live                  the run served to Foxglove as it runs (pip install "usv_mj[live]")
    usv-mj scene --out scene.xml       the scenario's MuJoCo scene (obstacles included) as one MJCF file
    usv-mj view [--manual]             MuJoCo's viewer on the scenario: water, sea, controller (or the arrow keys)
    usv-mj manoeuvre turning           a standard manoeuvre: turning, zigzag, spiral, stopping (IMO measures)

Exit codes: 0 done; 1 the run stopped early (diverged, failed, interrupted: the reason is printed and
recorded); 2 bad input (the message names the key and the file); 3 no OpenGL for the video (the
message names the Debian packages to install; --no-video skips the video; `usv-mj view`: no display);
141 the output pipe closed.
An --out that holds an earlier output is refused unless --overwrite, which replaces only what a usv_mj
command wrote (listed in the folder's .usv_mj-manifest.json); a folder holding anything else is refused.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import warnings


def _signal_while_starting(signum, frame):
    # nothing has been created yet: say so and end at once (no half-imported module to unwind)
    os.write(2, f"usv-mj: interrupted ({signal.Signals(signum).name}) while starting; nothing was written\n".encode())
    os._exit(1)


def _early_signal(signum, frame):
    from usv_mj.core.errors import Terminated

    raise Terminated(signal.Signals(signum).name)


_ARGV0 = sys.argv[0] if sys.argv else ""
if (__name__ == "__main__" or os.path.basename(_ARGV0) == "usv-mj"
        or _ARGV0.endswith(os.path.join("usv_mj", "cli", "__main__.py"))) \
        and threading.current_thread() is threading.main_thread():
    # the program itself, before the imports below (about a second): SIGTERM / SIGHUP while it starts
    # end it as Ctrl-C would, exit 1, instead of the default death (143)
    for _sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(_sig, _signal_while_starting)

import argparse  # noqa: E402
import importlib
import time
from pathlib import Path

from usv_mj.core.errors import PluginWarning, Terminated, one_line
from usv_mj.cli.args import (EXIT_BAD_INPUT, EXIT_NO_GL, EXIT_OK, EXIT_STOPPED,  # noqa: F401 (re-exported)
                           add_live_arguments, add_scenario_arguments, add_vessel_argument, live_server, parse_set,
                           scenario_from_args)
from usv_mj.scenario.spec import ScenarioError, load_scenario, preset_names


class _Formatter(argparse.RawDescriptionHelpFormatter):
    pass


class _Parser(argparse.ArgumentParser):
    """Bad options in one line, as every other bad input: ``usv-mj run: error: ... (see --help)``."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (usv-mj {self.prog.split()[-1]} --help)\n"
                  if self.prog != "usv-mj" else f"usv-mj: error: {message} (usv-mj --help)\n")


# --- run ---------------------------------------------------------------------------------------


def _add_run(sub):
    p = sub.add_parser("run", formatter_class=_Formatter, help="run a scenario: video, figures, MCAP log, report",
                       description="Run one scenario end to end. With no options: the paper scenario (docs/model.md §4-5) "
                       "on the MuJoCo plant for 300 s, then the PI baseline, writing summary.json, report.md, "
                       "figures/, run.mcap (baseline.mcap), video.mp4 and video.png into --out.")
    add_scenario_arguments(p)
    p.add_argument("--plant", choices=("mujoco", "analytic"), help="which plant integrates the ship")
    add_vessel_argument(p)
    p.add_argument("--out", metavar="DIR", help="output folder (default renders/<preset or scenario name>)")
    p.add_argument("--no-video", action="store_true", help="skip the video")
    p.add_argument("--no-baseline", action="store_true", help="skip the PI baseline run")
    p.add_argument("--no-log", action="store_true", help="skip the MCAP log")
    p.add_argument("--log-rate", type=float, metavar="HZ",
                   help="log every n-th control step to the MCAP (e.g. 10: 10 Hz); default every step")
    from usv_mj.outputs.outdir import add_overwrite_argument

    add_overwrite_argument(p, "--out whole when it holds an earlier usv_mj output")
    p.add_argument("--debug", action="store_true", help="print the traceback of a crash (always in traceback.txt)")
    from usv_mj.outputs.render import add_video_arguments

    add_video_arguments(p)
    add_live_arguments(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_run_command)


def _run_command(args) -> int:
    from usv_mj.jobs.run import RunFailed, one_screen_summary, run_job

    from usv_mj.outputs.render import video_options

    scenario = scenario_from_args(args)
    try:
        render_options = video_options(args)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    name = Path(args.scenario).stem if args.scenario else scenario.preset
    out = Path(args.out) if args.out is not None else Path("renders") / name
    if args.out is not None and args.out.strip() == "":
        raise ScenarioError("--out '': an empty path; name the output folder")
    if args.live and args.no_log:
        raise ScenarioError("--live serves the run log's messages: drop --no-log")
    live = live_server(args)
    t0 = time.perf_counter()
    try:
        result = run_job(scenario, out, baseline=False if args.no_baseline else None, video=not args.no_video,
                         log=not args.no_log, progress=not args.quiet,
                         render_options=render_options, overwrite=args.overwrite, log_rate=args.log_rate,
                         live=live)
        if live is not None:
            live.finish()
    except RunFailed as exc:
        if live is not None:
            live.close()
        if args.debug and exc.traceback is not None and Path(exc.traceback).is_file():
            sys.stderr.write(Path(exc.traceback).read_text())
        print(f"usv-mj run: {exc}", file=sys.stderr)
        return EXIT_STOPPED
    print(one_screen_summary(result, time.perf_counter() - t0))
    if result.summary.get("job_stopped"):
        print(f"usv-mj run: the job stopped early: {result.summary['job_stopped']}; missing outputs: "
              f"{', '.join(result.summary.get('missing_outputs') or []) or 'none'}", file=sys.stderr)
    elif result.summary["status"] != "completed":
        print(f"usv-mj run: the run {result.summary['status']}: {result.summary.get('stop_reason')}", file=sys.stderr)
    if result.summary["status"] != "completed" or result.summary.get("job_stopped"):
        return EXIT_STOPPED
    return EXIT_OK


# --- presets and plot --------------------------------------------------------------------------


def _add_presets(sub):
    p = sub.add_parser("presets", formatter_class=_Formatter, help="list the presets or print one",
                       description="Presets are TOML data shipped with the package; a scenario file names one "
                       "with `preset = \"...\"` and overrides any key.")
    p.add_argument("name", nargs="?", help="print this preset's TOML (a scenario preset or a sea preset)")
    p.set_defaults(func=_presets_command)


def _presets_command(args) -> int:
    from importlib import resources

    from usv_mj.physics.sea.settings import describe_directions, sea_preset_names, sea_preset_table

    if args.name is None:
        for name in preset_names():
            first = (resources.files("usv_mj.scenario.presets") / f"{name}.toml").read_text().splitlines()[0]
            print(f"{name:15s} {first.lstrip('# ')}")
        print("\nsea presets (--sea NAME; directions as in docs/sea.md: compass degrees clockwise from north):")
        for name in sea_preset_names():
            print(f"{name:15s} {describe_directions(sea_preset_table(name))}")
        return EXIT_OK
    if args.name in sea_preset_names():
        print((resources.files("usv_mj.physics.sea.presets") / f"{args.name}.toml").read_text())
        return EXIT_OK
    load_scenario(preset=args.name)  # validates the name with a helpful message
    print((resources.files("usv_mj.scenario.presets") / f"{args.name}.toml").read_text())
    return EXIT_OK


def _add_examples(sub):
    p = sub.add_parser("examples", formatter_class=_Formatter, help="list the example scenarios and sweeps",
                       description="The example scenarios and sweeps shipped with the package, each found by its "
                       "name: usv-mj run --scenario harbour_gap, usv-mj sweep quick (a path works too).")
    p.set_defaults(func=_examples_command)


def _examples_command(args) -> int:
    from usv_mj.support.example_files import listing

    print(listing())
    return EXIT_OK


def _add_plot(sub):
    p = sub.add_parser("plot", formatter_class=_Formatter, help="figures and report again from a run's MCAP log",
                       description="Remake figures/ and report.md from RUN (an .mcap file or a run folder "
                       "holding run.mcap) without simulating.")
    p.add_argument("run", metavar="RUN", help="a run log (run.mcap) or the run folder that holds it")
    p.add_argument("--out", metavar="DIR", help="output folder (default: beside the log)")
    from usv_mj.outputs.outdir import add_overwrite_argument

    add_overwrite_argument(p, "report.md and figures/ in --out that usv_mj wrote")
    p.set_defaults(func=_plot_command)


def _plot_command(args) -> int:
    from usv_mj.record.criteria import criterion_of_record
    from usv_mj.outputs.figures import draw_figures
    from usv_mj.outputs.report import write_report
    from usv_mj.outputs.log import read_run
    from usv_mj.record.summary import summarize

    path = Path(args.run)
    if path.is_dir():
        path = path / "run.mcap"
    if not path.is_file():
        raise ScenarioError(f"{path}: no such run log" if not path.exists() else f"{path}: is not a regular file")
    try:
        log = read_run(path)
        record = log.record
    except (ValueError, KeyError, OSError) as exc:
        raise ScenarioError(f"{path}: not a readable run log ({exc})") from None
    if len(record) == 0:
        why = f": {log.problem}" if log.problem else ""
        raise ScenarioError(f"{path}: the log holds no rows of a run (nothing to plot){why}")
    out = Path(args.out) if args.out else path.parent
    from usv_mj.jobs.manoeuvres import record_outputs, spec_of_record
    from usv_mj.outputs.outdir import check_folder, record

    manoeuvre = ("manoeuvre.json",) if spec_of_record(log.record) is not None else ()
    check_folder(out, args.overwrite, writes=("report.md", "figures", *manoeuvre))
    out.mkdir(parents=True, exist_ok=True)
    if log.notice:
        print(f"usv-mj plot: warning: the log is incomplete: {log.notice}", file=sys.stderr)
    figures = draw_figures(log.record, out / "figures", log.baseline, note=log.notice)
    # a manoeuvre's figures, manoeuvre.json and its report section (nothing for another run)
    sections, manoeuvre_files, _ = record_outputs(log.record, out)
    figures = list(figures) + list(manoeuvre_files.get("manoeuvre_figures", []))
    summary = summarize(log.record)
    base = summarize(log.baseline, criterion_of_record(log.record)) if log.baseline is not None else None
    write_report(out / "report.md", summary, base,
                 log.metadata.get("step_check"),
                 extra_sections=sections + ([f"## The log is incomplete\n\n**{log.notice}.** The figures and numbers "
                                             "above are of what was recovered."] if log.notice else []) or None)
    record(out, ["report.md", *(["manoeuvre.json"] if sections else []),
                 *(Path(f).relative_to(out).as_posix() for f in figures)])
    print(f"figures and report from {path} written to {out}/" + (" (from an incomplete log, see above)"
                                                                 if log.notice else ""))
    return EXIT_OK


# --- commands that live in their own modules ---------------------------------------------------

# name -> (module, add_arguments, run_command, one-line help)
_EXTERNAL = {
    "compare": ("usv_mj.jobs.compare", "add_arguments", "run_command",
                "the same scenario on the analytic and the MuJoCo plant, with the differences"),
    "inspect": ("usv_mj.cli.inspect", "add_inspect_arguments", "inspect_command",
                "topics, message counts, duration and metadata of a run log (.mcap)"),
    "render": ("usv_mj.outputs.render", "add_arguments", "run_command",
               "the video of a recorded run again (another size, speed or camera)"),
    "sweep": ("usv_mj.jobs.sweep", "add_arguments", "run_command",
              "Monte-Carlo sweep of many runs on a Dask cluster (local by default)"),
    "capability": ("usv_mj.jobs.sweep", "add_capability_arguments", "capability_command",
                   "environment capability polar: the largest load at which the controller's criterion holds"),
    "bench": ("usv_mj.jobs.bench", "add_arguments", "run_command",
              "the controller benchmark: every controller on the same tasks, seas and actuators, one leaderboard"),
    "env": ("usv_mj.cli.env", "add_arguments", "run_command",
            "roll out a policy (ppc, random) in a dm_control task (track, track_waves, harbor): returns and a video"),
    "kinds": ("usv_mj.cli.kinds", "add_arguments", "run_command",
              "every controller, trajectory, plant and disturbance kind: where it comes from, its options"),
    "scene": ("usv_mj.cli.scene", "add_arguments", "run_command",
              "write the scenario's MuJoCo scene (obstacles included) as one MJCF file"),
    "view": ("usv_mj.cli.view", "add_arguments", "run_command",
             "MuJoCo's viewer on the scenario: water, sea and controller acting; --manual drives with the arrows"),
    "manoeuvre": ("usv_mj.cli.manoeuvre", "add_arguments", "run_command",
                  "a standard manoeuvre (turning circle, zig-zag, spiral, stopping): measures, IMO criteria, figures"),
}


# what each command's --help says first: for users, in plain text
_DESCRIPTIONS = {
    "compare": "Run the same scenario on the analytic plant and the MuJoCo plant and report how far they\n"
               "differ: open loop under a rich thrust sequence (with a convergence study in the time step)\n"
               "and in closed loop with the scenario's controller. Writes compare.json, compare.md and\n"
               "figures into --out. Exit 1 when a difference is outside its tolerance.",
    "inspect": "Say what a run log (.mcap) holds: its runs, topics, message counts, duration, status and\n"
               "metadata, and whether the file is complete. --json prints the same as one JSON object.",
    "render": "Draw the video of a recorded run again from its run.mcap alone: another size, frame rate,\n"
              "speed-up or camera (top, chase, overview, chart). Writes video.mp4 and video.png.",
    "sweep": "Run many variations of one scenario (a sweep file: a base scenario and what varies, by dotted\n"
             "path such as initial.eta[0] or sea.current.speed) on a Dask cluster, local by default.\n"
             "Results stream into results.parquet; report.md gives the rate of runs that passed\n"
             "the controller's criterion (the funnel for the paper's controller).\n"
             "--resume runs only what is missing.",
    "capability": "The environment capability polar (DNV style): for each direction, the largest current,\n"
                  "wind or wave load at which the controller's criterion holds (the funnel for the paper's\n"
                  "controller), found by bisection. With unlimited actuators it shows the control law's\n"
                  "limit, not the vessel's (use a preset with [actuators], e.g. --scenario paper-limited).",
    "scene": "Write the MuJoCo scene the scenario runs in (the hull, the harbour and its obstacles, the\n"
             "time step and the hull's inertial) as one MJCF file. MuJoCo alone sees no water in it:\n"
             "usv_mj.attach_hydrodynamics(model, data, scenario=...) attaches the hull forces and the sea.",
    "view": "Open MuJoCo's interactive viewer on the scenario's scene with the hydrodynamics, the sea and\n"
            "the controller acting (needs a display; exit 3 without one). --manual: drive it yourself,\n"
            "arrow keys up/down for surge, left/right for yaw, space to zero the thrust.",
    "bench": "Score controllers on a suite of tasks (trajectories, a harbour transit) in calm water, a\n"
             "moderate sea with current and with thrust limits, the same episodes for each; default: the\n"
             "suite shipped in the package. Episodes run on the sweep's Dask cluster and stream into\n"
             "results.parquet (--resume finishes); report.md is the leaderboard with 95 % intervals and\n"
             "figures. --compare A B tests A against B per metric (paired Wilcoxon). docs/metrics.md.",
    "env": "Roll out a policy (ppc: the paper's controller; random) in a dm_control task (track,\n"
           "track_waves, harbor, harbor_waves) and print the returns; --video writes the first episode;\n"
           "--vessel KIND runs it on another hull (as usv-mj run --vessel: plant, actuators, picture).",
    "kinds": "List every kind a scenario may name, registry by registry (controller, trajectory, plant,\n"
             "disturbance): where it comes from (built-in, an entry point's distribution, module:Name,\n"
             "registered at runtime) and its options (name, type, default, unit). --json for one object.",
    "manoeuvre": "Run a standard manoeuvre of the vessel (turning circle, 10/10 or 20/20 zig-zag, Dieudonne's\n"
                 "spiral, stopping test) on either plant, and write its measures (manoeuvre.json), the IMO\n"
                 "MSC.137(76) criteria beside them, figures, report.md and run.mcap into --out (a video with\n"
                 "--video). Options: --set manoeuvre.KEY=VALUE (README, Vessels and manoeuvres).",
}


def _add_external(sub, name, spec):
    module_name, add_name, run_name, help_text = spec
    try:
        module = importlib.import_module(module_name)
        add, run = getattr(module, add_name), getattr(module, run_name)
    except (ImportError, AttributeError):
        return
    p = sub.add_parser(name, formatter_class=_Formatter, help=help_text, description=_DESCRIPTIONS[name])
    add(p)
    _harmonize(p)
    p.set_defaults(func=run)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="usv-mj", formatter_class=_Formatter, description=__doc__)
    from usv_mj.core.version import __version__

    parser.add_argument("--version", action="version", version=f"usv-mj {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_run(sub)
    _add_presets(sub)
    _add_examples(sub)
    _add_plot(sub)
    for name, spec in _EXTERNAL.items():
        _add_external(sub, name, spec)
    return parser


SHORT_USAGE = """usage: usv-mj COMMAND [options]

commands: run, presets, examples, compare, inspect, plot, render, sweep, capability, bench, env, kinds,
          scene, view, manoeuvre
  usv-mj run              the paper scenario on the MuJoCo plant: video, figures, MCAP log, report
  usv-mj COMMAND --help   what a command does and its options; usv-mj --help for examples"""


def _harmonize(p: argparse.ArgumentParser) -> None:
    """One flag name per concept in every command; the old spellings stay as hidden aliases."""
    by_flag = {o: a for a in p._actions for o in a.option_strings}
    for old, new, help_text in (("--no-progress", ("-q", "--quiet"), "no progress bars"),
                                ("--video-size", ("--size",), "video size in pixels, WxH"),
                                ("--base", ("--scenario",), "a preset name or a scenario TOML file")):
        action = by_flag.get(old)
        if action is None or any(n in by_flag for n in new):
            continue
        kwargs = {"dest": action.dest, "default": action.default, "help": help_text}
        if isinstance(action, argparse._StoreTrueAction):
            kwargs["action"] = "store_true"
        else:
            kwargs.update(metavar="WxH" if old == "--video-size" else "NAME_OR_FILE", type=action.type)
        action.help = argparse.SUPPRESS
        p.add_argument(*new, **kwargs)


_PYTHON_WARNING = warnings.formatwarning


def _one_line_warning(message, category, filename, lineno, line=None):
    """usv_mj's own warnings (a plug-in's entry point not used) as one line, others as Python's."""
    if issubclass(category, PluginWarning):
        return f"usv-mj: warning: {message}\n"
    return _PYTHON_WARNING(message, category, filename, lineno, line)


def main(argv: list[str] | None = None) -> int:
    warnings.formatwarning = _one_line_warning
    if threading.current_thread() is threading.main_thread():
        # until a command installs its own handlers: SIGTERM / SIGHUP end it as Ctrl-C would (exit 1)
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, _early_signal)
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:
        print(SHORT_USAGE, file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0), or a bad option already said in one line (2)
        return int(exc.code or 0)
    from usv_mj.outputs.outdir import set_command

    set_command(["usv-mj", *argv])   # what the output folders' manifests record
    if not getattr(args, "func", None):
        print(SHORT_USAGE, file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        return int(args.func(args) or 0)
    except ScenarioError as exc:
        print(f"usv-mj {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:  # the run commands record it themselves; here: stopped early, exit 1
        print(f"usv-mj {args.command}: interrupted", file=sys.stderr)
        return EXIT_STOPPED
    except BrokenPipeError:
        # the reader went away (usv-mj inspect run.mcap | head): stop quietly, as Unix tools do;
        # point stdout at /dev/null so that the interpreter's final flush does not fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except Exception as exc:
        from usv_mj.outputs.render import GLUnavailableError

        if isinstance(exc, GLUnavailableError):
            print(f"usv-mj {args.command}: {exc}", file=sys.stderr)
            return EXIT_NO_GL
        if getattr(args, "debug", False) or os.environ.get("USV_MJ_DEBUG") == "1":
            raise
        # a defect of usv_mj, not of the input: one line, the documented exit 1 (--debug or
        # USV_MJ_DEBUG=1 prints the traceback)
        where = exc.__traceback__
        while where is not None and where.tb_next is not None:
            where = where.tb_next
        at = f" at {Path(where.tb_frame.f_code.co_filename).name}:{where.tb_lineno}" if where is not None else ""
        print(f"usv-mj {args.command}: internal error: {one_line(exc)}{at} "
              "(a defect of usv_mj; USV_MJ_DEBUG=1 shows the traceback)", file=sys.stderr)
        return EXIT_STOPPED


def entry() -> int:
    """The program ``usv-mj``: :func:`main`, then the exit with every signal ignored, so that a
    Ctrl-C during the interpreter's clean-up (worker pools, the log writer) cannot turn the
    documented exit code into a death by the signal."""
    try:
        code = main()
    except KeyboardInterrupt:  # outside any command's own handling
        print("usv-mj: interrupted", file=sys.stderr)
        code = EXIT_STOPPED
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    return code


if __name__ == "__main__":
    sys.exit(entry())
