"""The registry of the commands of ``usv-mj``: each command module registers itself, as dm_control's
suite registers its tasks::

    from usv_mj.cli.commands import COMMANDS

    def add_arguments(p): ...                     # its flags (usv_mj.cli.args for the shared ones)

    @COMMANDS.register("run", arguments=add_arguments, help="one line for usv-mj --help",
                       description="the paragraph of usv-mj run --help")
    def run(args) -> int: ...                     # calls the library, returns the exit code

:data:`BUILT_IN` names the module of each built-in command (in the order ``usv-mj --help`` lists
them), so that listing the commands imports none; a plug-in adds one by an entry point of the
group ``usv_mj.commands`` (as every registry of :mod:`usv_mj.core.registry`, whose class this is).
A command module imports argparse, this package and light modules at its top, and the library
inside its ``run``.

:func:`load` is how the program gets a command: a module that cannot be imported is a
:class:`CommandUnavailable`, which says so in one line (exit 1: a defect; exit 2: an optional
dependency to install), never a command that is missing.
"""

from __future__ import annotations

import os
import sys

from usv_mj.core.errors import EXTRAS, MissingExtra, missing_extra
from usv_mj.core.registry import Registry

#: the built-in commands, in the order of ``usv-mj --help``: name -> the module that registers it
BUILT_IN = {name: f"usv_mj.cli.{name}" for name in (
    "run", "presets", "examples", "compare", "inspect", "plot", "render", "sweep", "capability", "bench", "env",
    "kinds", "scene", "view", "manoeuvre")}

COMMANDS = Registry("command", BUILT_IN, "usv_mj.commands")


def names() -> list[str]:
    """Every command: the built-in ones in their order, then the others (plug-ins) sorted."""
    return [*BUILT_IN, *(k for k in COMMANDS.kinds() if k not in BUILT_IN)]


class CommandUnavailable(Exception):
    """The command ``name`` cannot be loaded; :meth:`report` says why in one line and gives the exit code."""

    def __init__(self, name: str, cause: BaseException):
        super().__init__(name, cause)
        self.name, self.cause = name, cause

    @property
    def missing(self) -> str | None:
        """The optional dependency (an import name of :data:`usv_mj.core.errors.EXTRAS`) whose absence is the cause."""
        cause = self.cause
        if isinstance(cause, ImportError) and not isinstance(cause, MissingExtra):
            top = (cause.name or "").split(".")[0]
            if top in EXTRAS:
                return top
        return None

    def line(self) -> str:
        """The one line: ``usv-mj NAME: error: ... pip install ...`` (an extra) or ``usv-mj NAME: internal error: ...``."""
        if isinstance(self.cause, MissingExtra):
            return f"usv-mj {self.name}: error: {self.cause}"
        if self.missing is not None:
            return f"usv-mj {self.name}: error: {missing_extra(self.missing, f'usv-mj {self.name}')}"
        why = " ".join(str(self.cause).split()) or type(self.cause).__name__
        return (f"usv-mj {self.name}: internal error: the command cannot be imported: {type(self.cause).__name__}: "
                f"{why} (a defect of usv_mj; USV_MJ_DEBUG=1 shows the traceback)")

    @property
    def code(self) -> int:
        """2 for an optional dependency to install (bad input of a kind), 1 for a defect."""
        return 2 if isinstance(self.cause, MissingExtra) or self.missing is not None else 1

    def report(self) -> int:
        if os.environ.get("USV_MJ_DEBUG") == "1":
            raise self.cause
        print(self.line(), file=sys.stderr)
        return self.code


def load(name: str):
    """The registry entry of command ``name`` (its ``obj`` is the run function; ``info`` holds
    ``arguments``, ``help``, ``description``); :class:`CommandUnavailable` if its module fails."""
    try:
        return COMMANDS.get(name, "usv-mj")   # a built-in's module is imported here: its own error comes out
    except Exception as exc:  # noqa: BLE001 - any failure of a command's import is reported the same way
        raise CommandUnavailable(name, exc) from exc
