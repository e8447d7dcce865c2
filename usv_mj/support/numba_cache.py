"""A damaged numba disk cache is a cache miss, not an error for ever.

numba's ``cache=True`` keeps each compiled kernel in an index file (``.nbi``) and data files
(``.nbc``) beside its source: the package's ``__pycache__`` and the compiled loops' directory
(:func:`usv_mj.loop.compiled.cache_dir`). numba 0.5x-0.6x unpickles them without a guard, so a file
that was zeroed or cut (a full disk, a crash while it was written) makes every later run fail with
``EOFError: Ran out of input`` (or an UnpicklingError) until the user finds and deletes it.

:func:`install` wraps numba's ``IndexDataCacheFile._load_index`` and ``_load_data``: a file that
cannot be read is removed, one warning line names it, and the kernel is compiled again and saved
(a damaged index reads as empty, a damaged data file as not cached). It is installed when numba's
caching module is imported (or at once if it already is), from ``usv_mj/__init__.py``.

**A stale kernel is a cache miss too.** numba keys a cached kernel on its own source file only (its
stamp: that file's hash, size and time), but a kernel compiles in the constants and the inlined
njit functions of other modules (``usv_mj.physics.ship``'s packed layout ``P_*``, the callback's ``U_*``):
after a ``git pull`` that changes ``ship.py`` alone, the callback's kernel in ``__pycache__`` would
still load, with the old offsets, and the MuJoCo plant would silently integrate wrong forces (seen
once: the two plants metres apart). :func:`install` also adds :func:`package_stamp` (a digest of
the contents of every source file of the package and of ``controllers/``) to the stamp of every
kernel defined in them, so that any change of the package's source recompiles its kernels.
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


_ROOTS: tuple[str, ...] | None = None
_STAMP: str | None = None


def _roots() -> tuple[str, ...]:
    """The package's folder and the checkout's ``controllers/`` (a wheel has it inside the package)."""
    global _ROOTS
    if _ROOTS is None:
        from usv_mj.support.assets import PACKAGE_DIR

        here = PACKAGE_DIR
        roots = [here] + [p for p in (here.parent / "controllers",) if (p / "__init__.py").is_file()]
        _ROOTS = tuple(str(r) + os.sep for r in roots)
    return _ROOTS


def package_stamp(roots: tuple[str, ...] | None = None) -> str:
    """A digest of the contents of every ``.py`` file under ``roots`` (default: the package's),
    computed once per process for the default roots (about 5 ms)."""
    global _STAMP
    if roots is None and _STAMP is not None:
        return _STAMP
    import hashlib
    from pathlib import Path

    h = hashlib.sha256()
    for root in sorted(roots or _roots()):
        for path in sorted(Path(root).rglob("*.py")):
            h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    digest = h.hexdigest()[:16]
    if roots is None:
        _STAMP = digest
    return digest


def _ours(py_file) -> bool:
    path = os.path.realpath(str(py_file))
    return any(path.startswith(root) for root in _roots())


def install() -> None:
    """Wrap numba's cache readers, and the source stamp of the package's kernels (once)."""
    import pickle

    from numba.core import caching

    cls = caching.IndexDataCacheFile
    if getattr(cls, "_usv_mj_guarded", False):
        return
    mixin = caching._SourceFileBackedLocatorMixin
    source_stamp = mixin.get_source_stamp

    def get_source_stamp(self):
        own = source_stamp(self)
        return (own, package_stamp()) if _ours(self._py_file) else own

    mixin.get_source_stamp = get_source_stamp
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
