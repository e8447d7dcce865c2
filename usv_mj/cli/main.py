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

Exit codes: 0 done; 1 the run stopped early (diverged, failed, interrupted, or the file system refused
a write, such as a full disk: the reason and the path are printed and recorded); 2 bad input (the
message names the key and the file; an output folder that cannot be written, when that is known
before anything is written, is bad input too); 3 no OpenGL for the video (the message names the
Debian packages to install; --no-video skips the video; `usv-mj view`: no display); 141 the output
pipe closed.
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
        and threading.current_thread() is threading.main_thread() \
        and "--multiprocessing-fork" not in getattr(sys, "orig_argv", ()):
    # (not in a worker spawned by multiprocessing, such as a Dask worker: it is handed the program's
    # argv and imports the program again, but it is not the program and has nothing to say)
    # the program itself, before the imports below (the commands' modules; the library comes when a
    # command runs): SIGTERM / SIGHUP while it starts
    # end it as Ctrl-C would, exit 1, instead of the default death (143)
    for _sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(_sig, _signal_while_starting)

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402

from usv_mj.cli.args import EXIT_BAD_INPUT, EXIT_NO_GL, EXIT_OK, EXIT_STOPPED  # noqa: E402,F401 (re-exported)
from usv_mj.cli.commands import CommandUnavailable, load, names  # noqa: E402
from usv_mj.core.errors import PluginWarning, ScenarioError, one_line  # noqa: E402


class _Formatter(argparse.RawDescriptionHelpFormatter):
    pass


class _Parser(argparse.ArgumentParser):
    """Bad options in one line, as every other bad input: ``usv-mj run: error: ... (see --help)``."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (usv-mj {self.prog.split()[-1]} --help)\n"
                  if self.prog != "usv-mj" else f"usv-mj: error: {message} (usv-mj --help)\n")


def _build() -> tuple[argparse.ArgumentParser, dict[str, CommandUnavailable]]:
    """The parser of every registered command, and the commands that could not be loaded (each
    listed in --help with its cause; running one is its one-line error)."""
    parser = _Parser(prog="usv-mj", formatter_class=_Formatter, description=__doc__)
    from usv_mj.core.version import __version__

    parser.add_argument("--version", action="version", version=f"usv-mj {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    unavailable = {}
    for name in names():
        try:
            entry = load(name)
        except CommandUnavailable as exc:
            unavailable[name] = exc
            sub.add_parser(name, add_help=False, help=f"(cannot be loaded: `usv-mj {name}` says why)")
            continue
        p = sub.add_parser(name, formatter_class=_Formatter, help=entry.info.get("help"),
                           description=entry.info.get("description"))
        arguments = entry.info.get("arguments")
        if arguments is not None:
            arguments(p)
        p.set_defaults(func=entry.obj)
    return parser, unavailable


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``usv-mj``: one subcommand per registered command (:mod:`usv_mj.cli.commands`)."""
    return _build()[0]


def short_usage() -> str:
    """What bare ``usv-mj`` prints: the commands (from the registry) and where to read more."""
    import textwrap

    listed = textwrap.fill(", ".join(names()), width=104, initial_indent="commands: ", subsequent_indent=" " * 10)
    return ("usage: usv-mj COMMAND [options]\n\n" + listed + "\n"
            "  usv-mj run              the paper scenario on the MuJoCo plant: video, figures, MCAP log, report\n"
            "  usv-mj COMMAND --help   what a command does and its options; usv-mj --help for examples")


_PYTHON_WARNING = warnings.formatwarning


def _one_line_warning(message, category, filename, lineno, line=None):
    """usv_mj's own warnings (a plug-in's entry point not used) as one line, others as Python's."""
    if issubclass(category, PluginWarning):
        return f"usv-mj: warning: {message}\n"
    return _PYTHON_WARNING(message, category, filename, lineno, line)


def os_error_line(exc: OSError) -> str:
    """One line for an OSError: the path(s), the system's reason (``No space left on device``) and
    the notes the library added to it."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    paths = [str(f) for f in (exc.filename, exc.filename2) if f is not None]
    line = f"{' -> '.join(paths)}: {reason}" if paths else f"{reason} ({type(exc).__name__})"
    return "; ".join([line, *getattr(exc, "__notes__", ())])   # e.g. where the earlier output is (outdir)


def main(argv: list[str] | None = None) -> int:
    warnings.formatwarning = _one_line_warning
    if threading.current_thread() is threading.main_thread():
        # until a command installs its own handlers: SIGTERM / SIGHUP end it as Ctrl-C would (exit 1)
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, _early_signal)
    parser, unavailable = _build()
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:
        print(short_usage(), file=sys.stderr)
        return EXIT_BAD_INPUT
    named = next((a for a in argv if not a.startswith("-")), None)
    if named in unavailable:   # its module did not import: one line saying why, never "invalid choice"
        return unavailable[named].report()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0), or a bad option already said in one line (2)
        return int(exc.code or 0)
    from usv_mj.outputs.outdir import set_command

    set_command(["usv-mj", *argv])   # what the output folders' manifests record
    if not getattr(args, "func", None):
        print(short_usage(), file=sys.stderr)
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
    except OSError as exc:
        if getattr(args, "debug", False) or os.environ.get("USV_MJ_DEBUG") == "1":
            raise
        # the file system refused while the command wrote (a full disk, a folder made read-only):
        # not a defect of usv_mj and not bad input (what can be foreseen is refused before
        # anything is written, exit 2): the command stopped early, exit 1
        print(f"usv-mj {args.command}: {os_error_line(exc)}", file=sys.stderr)
        return EXIT_STOPPED
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
