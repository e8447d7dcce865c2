"""The error family of usv_mj (a leaf module: imports nothing of the package).

Every bad input (a scenario file, a sea table, an obstacle, a sweep file, a command-line value)
raises a :class:`ScenarioError`, whose message is one line that starts with the file or flag and
names the key: ``my.toml: quantizer.delta_u must be in (0, 1), got 1.5``. The command line turns
it into exit code 2 with no output written. Subclasses say which part of the input was wrong, so a
caller may catch the family or one member.
"""

from __future__ import annotations

import re


class UsvMjError(Exception):
    """Base of every error that usv_mj raises on purpose (never a bug)."""


class ScenarioError(UsvMjError, ValueError):
    """A scenario value, key or file is wrong; the message names the key and the source."""


class TooManyStepsError(ScenarioError):
    """duration / control_period is over the step cap (usv_mj.scenario.spec.Scenario); its own type so
    that a command whose --duration replaces the file's checks the count on the duration that runs."""


class SeaSettingsError(ScenarioError):
    """A ``[sea]`` value is wrong (waves, current, wind)."""


class SweepError(ScenarioError):
    """A sweep file (its base scenario, a varied path, a distribution) is wrong."""


class WorkerError(UsvMjError, RuntimeError):
    """A sweep's or a benchmark's Dask workers could not do their part (a run that cannot be set up on
    its worker, every worker gone): the job stops with the runs done so far written; exit 1."""


class WorkerSetupError(WorkerError):
    """Run ``run_id`` could not be set up on its worker: ``stage`` ("importing M", "unpickling its
    scenario", "building it") failed with ``cause`` (one line)."""

    def __init__(self, run_id: int, stage: str, cause: str, worker: str = ""):
        super().__init__(run_id, stage, cause, worker)   # the args rebuild it when it is unpickled
        self.run_id, self.stage, self.cause, self.worker = run_id, stage, cause, worker

    def __str__(self) -> str:
        where = f" on worker {self.worker}" if self.worker else ""
        return f"run {self.run_id} could not be set up{where} ({self.stage}): {self.cause}"


class UnknownKindError(ScenarioError):
    """A ``kind`` names no registered plant, controller, trajectory or disturbance."""


class PluginImportError(UnknownKindError):
    """A ``"package.module:Name"`` kind or an entry point could not be imported (the message names
    the kind, where it was named, and the import's own error)."""


class PluginContractError(ScenarioError):
    """A plug-in (a part named by ``package.module:Name``, an entry point, a class registered at
    runtime or handed to the API) breaks the contract of its sort (a factory that cannot take its
    arguments, a disturbance whose kernel is not a ``numba.njit`` function or whose ``as_array()`` is
    too long, ...): the message names the plug-in, the contract and the fix. Bad input of the user's
    (exit 2), not a defect of usv_mj."""


class ArgumentTypeError(UsvMjError, TypeError):
    """A public function was handed the wrong kind of object; the message names the function, the
    argument, what it takes and what it got: ``simulate: scenario must be ..., got NoneType``."""


class ArgumentValueError(UsvMjError, ValueError):
    """A public function was handed an argument of the right type but a value it cannot take; the
    message names the function, the argument, what it takes and what it got."""


def expected(where: str, name: str, what: str, value) -> ArgumentTypeError:
    """The :class:`ArgumentTypeError` of ``where``'s argument ``name`` that should be ``what``."""
    shown = repr(value) if isinstance(value, (str, bytes, int, float)) and len(repr(value)) <= 40 else None
    got = type(value).__name__ + (f" {shown}" if shown else "")
    return ArgumentTypeError(f"{where}: {name} must be {what}, got {got}")


class PluginWarning(UserWarning):
    """Something about the installed plug-ins the user should know but that does not stop the run
    (an entry point shadowed by a built-in kind, or named by two distributions)."""


class PluginExit(UsvMjError, RuntimeError):
    """A part of a run (a plug-in controller, reference, hook...) called ``sys.exit`` while the run
    was going: the run is recorded as failed with every row before it, and this is raised in
    place of the SystemExit (a plug-in stops a run by raising an exception, never by ending the
    program). The message names the module and line that called it."""

    @classmethod
    def during_run(cls, exc: SystemExit, t: float) -> "PluginExit":
        """The PluginExit of ``exc``, raised at time ``t`` [s] of a run (a single run's loop or a
        fleet's): its text is the run's stop reason."""
        tb = exc.__traceback__
        while tb is not None and tb.tb_next is not None:
            tb = tb.tb_next
        caller = "a part of the run" if tb is None else \
            f"{tb.tb_frame.f_globals.get('__name__', '?')} (line {tb.tb_lineno})"
        return cls(f"SystemExit at t = {t:.3f} s: {caller} called sys.exit({exc.code!r}) during the run "
                   "(a plug-in stops a run by raising an exception, not by ending the program)")


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised like Ctrl-C's KeyboardInterrupt (its text: the signal's name), so
    that every ending by a signal is recorded as an interruption."""


#: The optional dependencies (pyproject.toml's extras): import name -> (pip name, extra).
EXTRAS = {"gymnasium": ("gymnasium", "gym"), "shimmy": ("shimmy", "gym"), "dask_jobqueue": ("dask-jobqueue", "hpc"),
          "bokeh": ("bokeh", "hpc"), "stable_baselines3": ("stable-baselines3", "rl"), "pettingzoo": ("pettingzoo", "gym")}


class MissingExtra(UsvMjError, ImportError):
    """An optional dependency is not installed; the message names it and the pip command."""


def missing_extra(module: str, what: str) -> MissingExtra:
    """The one-line error for ``what`` needing the optional ``module``: ``pip install "usv_mj[gym]"``."""
    package, extra = EXTRAS[module]
    return MissingExtra(f"{what} needs {package}, which is not installed: pip install \"usv_mj[{extra}]\"")


_ANSI = re.compile(r"\x1b\[[0-9;?]*[ -/]*[@-~]")


def plain_text(text) -> str:
    """``text`` without terminal escape sequences (numba highlights its messages with them)."""
    return _ANSI.sub("", str(text))


def compiler_summary(text: str) -> str | None:
    """numba's compiler error (``Failed in nopython mode pipeline ...``, dozens of lines) as one
    line: what failed and the first source line it names (``file.py, line N``); None for text
    that is not one."""
    lines = [line.strip() for line in plain_text(text).splitlines()]
    if not any(line.startswith("Failed in ") for line in lines):
        return None
    body = [line for line in lines if line and not line.startswith(("Failed in ", "During:"))]
    what = ""
    for i, line in enumerate(body):
        if line.startswith("File "):
            break
        what = line
        if not line.endswith(":"):
            break
        what = " ".join(body[i:i + 2])
        break
    where = next((line[len("File "):].rstrip(":").replace('"', "") for line in body if line.startswith("File ")), "")
    return what + (f" ({where})" if where else "")


def message_line(exc: BaseException) -> str:
    """``exc``'s message on one line, escape sequences removed, a numba compiler error summarized."""
    text = compiler_summary(str(exc))
    return text if text is not None else " ".join(plain_text(exc).split())


def one_line(exc: BaseException) -> str:
    """``Type: message`` (:func:`message_line`)."""
    text = message_line(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
