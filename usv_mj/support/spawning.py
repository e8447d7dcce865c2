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

A terminal's Ctrl-C or hang-up, ``timeout`` and ``kill -TERM -PGID`` signal every process of the
group, the workers too. :func:`start_sheltered` starts a worker that must outlive such a signal so
that the parent can finish with it (the run log's writer: the parent closes the log after the run
stopped): the worker is launched with SIGINT, SIGTERM and SIGHUP blocked, a mask it inherits
through ``exec``, and :func:`shelter_from_group_signals` (its first call) turns them into ignored
ones. ``multiprocessing``'s resource tracker, which every spawned worker shares, is started the
same way: it ignores SIGINT and SIGTERM itself but died of a SIGHUP, and every shared-memory
segment and semaphore released after that printed a KeyError traceback.
"""

from __future__ import annotations

import contextlib
import multiprocessing.context
import signal
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


#: the signals a terminal, ``timeout`` or ``kill -PGID`` send to a whole process group
GROUP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextlib.contextmanager
def group_signals_blocked(signals=GROUP_SIGNALS):
    """Block ``signals`` (SIGINT, SIGTERM and SIGHUP) in this thread while the block runs (a signal
    that comes meanwhile is delivered when it ends); a process or thread started inside inherits
    the mask, and keeps it."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, signals)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (if it is not running yet) with the group's signals
    blocked: it unblocks SIGINT and SIGTERM to ignore them, and SIGHUP stays blocked (module docstring)."""
    from multiprocessing import resource_tracker

    with group_signals_blocked():
        resource_tracker.ensure_running()


def shelter_from_group_signals() -> None:
    """In a worker started by :func:`start_sheltered`: ignore SIGINT, SIGTERM and SIGHUP, then
    unblock them (one sent meanwhile is dropped). The parent ends the worker by its own protocol."""
    for sig in GROUP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, GROUP_SIGNALS)


def start_sheltered(process) -> None:
    """``process.start()`` (a process of :func:`spawn_context` whose target calls
    :func:`shelter_from_group_signals` first) so that no signal sent to the group reaches it
    before it ignores them."""
    with group_signals_blocked():
        process.start()


class _Process(multiprocessing.context.SpawnProcess):
    """A spawned process launched without the main module's import (module docstring)."""

    @staticmethod
    def _Popen(process_obj):
        start_resource_tracker()
        with no_main_import():
            return multiprocessing.context.SpawnProcess._Popen(process_obj)


class _Context(multiprocessing.context.SpawnContext):
    Process = _Process


_CONTEXT = _Context()


def spawn_context():
    """The "spawn" multiprocessing context of the package's workers: ``spawn_context().Pool(...)``,
    ``.Process(...)``, ``.Queue()`` as with ``multiprocessing.get_context("spawn")``."""
    return _CONTEXT
