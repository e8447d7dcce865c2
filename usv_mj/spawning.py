"""Worker processes that run only usv_mj code: spawned without re-importing the user's ``__main__``.

``multiprocessing``'s "spawn" start method makes every child import the parent's main module
first (as ``__mp_main__``), so that functions defined there can be unpickled. Our workers (the
video's renderers, the run log's writer) run functions of this package only, and that import
does harm: a script without an ``if __name__ == "__main__":`` guard runs again in every worker
(and its render or log there cannot start a process while bootstrapping), and a main module with no
file (``python -`` reading stdin) makes every worker fail before it starts, which a ``Pool``
answers by starting another, forever. :func:`no_main_import` hides the main module from the
preparation data while such workers are started; the children then import only what they unpickle.
"""

from __future__ import annotations

import contextlib
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
