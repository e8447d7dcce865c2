"""A damaged numba disk cache is a cache miss, not an error for ever.

numba's ``cache=True`` keeps each compiled kernel in an index file (``.nbi``) and data files
(``.nbc``) beside its source: the package's ``__pycache__`` and the compiled loops' directory
(:func:`usv_mj.compiled_loop.cache_dir`). numba 0.5x-0.6x unpickles them without a guard, so a file
that was zeroed or cut (a full disk, a crash while it was written) makes every later run fail with
``EOFError: Ran out of input`` (or an UnpicklingError) until the user finds and deletes it.

:func:`install` wraps numba's ``IndexDataCacheFile._load_index`` and ``_load_data``: a file that
cannot be read is removed, one warning line names it, and the kernel is compiled again and saved
(a damaged index reads as empty, a damaged data file as not cached). It is installed when numba's
caching module is imported (or at once if it already is), from ``usv_mj/__init__.py``.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import sys

_DAMAGED = (EOFError, ValueError, TypeError, AttributeError, ImportError, IndexError, KeyError, MemoryError)


def _damaged(path: str, exc: BaseException) -> None:
    try:
        os.remove(path)
    except OSError:
        pass
    # one line on stderr (a warnings.warn would print its source line too)
    sys.stderr.write(f"usv_mj: warning: numba cache file {path} was damaged ({type(exc).__name__}"
                     f"{': ' + str(exc) if str(exc) else ''}); removed, its kernel is compiled again\n")


def install() -> None:
    """Wrap numba's cache readers (once)."""
    import pickle

    from numba.core import caching

    cls = caching.IndexDataCacheFile
    if getattr(cls, "_usv_mj_guarded", False):
        return
    load_index, load_data = cls._load_index, cls._load_data

    def _load_index(self):
        try:
            return load_index(self)
        except (pickle.UnpicklingError, *_DAMAGED) as exc:
            _damaged(self._index_path, exc)
            return {}

    def _load_data(self, name):
        try:
            return load_data(self, name)
        except (pickle.UnpicklingError, *_DAMAGED) as exc:
            _damaged(self._data_path(name), exc)
            return None

    cls._load_index, cls._load_data = _load_index, _load_data
    cls._usv_mj_guarded = True


class _InstallOnImport(importlib.abc.MetaPathFinder):
    """Runs :func:`install` right after ``numba.core.caching`` is imported."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "numba.core.caching":
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return None
        exec_module = spec.loader.exec_module

        def exec_and_install(module):
            exec_module(module)
            sys.modules[fullname] = module
            try:
                sys.meta_path.remove(self)
            except ValueError:
                pass
            install()

        spec.loader.exec_module = exec_and_install
        return spec


def install_when_imported() -> None:
    if "numba.core.caching" in sys.modules:
        install()
    elif not any(isinstance(f, _InstallOnImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _InstallOnImport())
