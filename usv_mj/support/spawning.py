"""Worker processes that run only usv_mj code: spawned without re-importing the user's ``__main__``.

``multiprocessing``'s "spawn" start method makes every child import the parent's main module
first (as ``__mp_main__``), so that functions defined there can be unpickled. Our workers (the
video's renderers, the run log's writer) run functions of this package only, and that import
does harm: a script without an ``if __name__ == "__main__":`` guard runs again in every worker
(and its render or log there cannot start a process while bootstrapping), and a main module with no
file (``python -`` reading stdin) makes every worker fail before it starts, which a ``Pool``
answers by starting another, forever. :func:`spawn_context` is a "spawn" context whose processes
(a Pool's first workers and every replacement it starts later) are launched under
:func:`no_main_import`, which hides the main module from the preparation data for the moment of
the launch; the children then import only what they unpickle. (A process another library launches
in that same moment from another thread would miss the main module too: the window is the
launch's few milliseconds.)
"""

from __future__ import annotations

import contextlib
import multiprocessing.context
import sys
import threading

_LOCK = threading.Lock()
_MISSING = object()


@contextlib.contextmanager
def no_main_import():
    """Start spawned workers inside this block: they will not import ``__main__`` (module docstring)."""
    with _LOCK:
        main = sys.modules.get("__main__")
        if main is None:
            yield
            return
        saved_file = main.__dict__.get("__file__", _MISSING)
        saved_spec = main.__dict__.get("__spec__", _MISSING)
        main.__dict__.pop("__file__", None)
        main.__spec__ = None
        try:
            yield
        finally:
            if saved_file is not _MISSING:
                main.__file__ = saved_file
            if saved_spec is _MISSING:
                main.__dict__.pop("__spec__", None)
            else:
                main.__spec__ = saved_spec


class _Process(multiprocessing.context.SpawnProcess):
    """A spawned process launched without the main module's import (module docstring)."""

    @staticmethod
    def _Popen(process_obj):
        with no_main_import():
            return multiprocessing.context.SpawnProcess._Popen(process_obj)


class _Context(multiprocessing.context.SpawnContext):
    Process = _Process


_CONTEXT = _Context()


def spawn_context():
    """The "spawn" multiprocessing context of the package's workers: ``spawn_context().Pool(...)``,
    ``.Process(...)``, ``.Queue()`` as with ``multiprocessing.get_context("spawn")``."""
    return _CONTEXT
