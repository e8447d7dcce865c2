"""The package's kernels are recompiled when any of its source files changes (usv_mj.support.numba_cache).

numba keys a cached kernel on its own file only; a kernel that inlines another module's constants
(the callback's offsets from ship.py's packed layout) would load stale from __pycache__ after a
change of that other module alone, and the MuJoCo plant would integrate wrong forces.
"""

from __future__ import annotations

import os

from numba.core import caching

import usv_mj  # noqa: F401  (installs the guard)
from usv_mj.support import numba_cache


def _stamp_of(fn):
    py = fn.py_func
    loc = caching.InTreeCacheLocator.from_function(py, py.__code__.co_filename)
    return loc.get_source_stamp()


def test_a_package_kernel_is_stamped_with_every_source_file_of_the_package():
    from usv_mj.plants.mujoco_callback import mujoco_kernel  # noqa: F401  (a kernel that reads ship.py's layout)
    from usv_mj.physics.ship import hull_terms

    stamp = _stamp_of(hull_terms)
    assert isinstance(stamp, tuple) and stamp[1] == numba_cache.package_stamp()


def test_a_kernel_outside_the_package_keeps_numbas_own_stamp(tmp_path):
    src = tmp_path / "user_kernel.py"
    src.write_text("from numba import njit\n@njit(cache=True)\ndef f(x):\n    return x + 1\n")
    import importlib.util

    spec = importlib.util.spec_from_file_location("user_kernel", src)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert not (isinstance(_stamp_of(mod.f), tuple) and len(_stamp_of(mod.f)) == 2
                and _stamp_of(mod.f)[1] == numba_cache.package_stamp())


def test_the_package_stamp_follows_contents_not_times(tmp_path):
    root = tmp_path / "pkg"
    root.mkdir()
    a, b = root / "a.py", root / "b.py"
    a.write_text("P_X = 1\n")
    b.write_text("def f(): return 1\n")
    roots = (str(root) + os.sep,)
    before = numba_cache.package_stamp(roots)
    st = os.stat(a)
    a.write_text("P_X = 2\n")                       # same size, and the old times put back (a git checkout)
    os.utime(a, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert numba_cache.package_stamp(roots) != before
    a.write_text("P_X = 1\n")
    os.utime(a, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert numba_cache.package_stamp(roots) == before
