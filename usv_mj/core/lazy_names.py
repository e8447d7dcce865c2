"""Names of a package imported from its submodules on first use (PEP 562 module ``__getattr__``).

Why: importing a package should not pull in what only some of its names need. The log writer's
process needs the record's field names, not the controllers' numba kernels; validating a scenario
needs no MuJoCo. A leaf module (imports nothing of the project).

Usage, in a package's ``__init__.py``::

    from usv_mj.core.lazy_names import lazy_names
    __getattr__, __dir__, __all__ = lazy_names(__name__, {"PPCController": ".ppc", ...})

A module name starting with "." is relative to the package.
"""

from __future__ import annotations

import sys
from importlib import import_module
from importlib.util import find_spec


def lazy_names(package: str, where: dict[str, str]):
    """(``__getattr__``, ``__dir__``, ``__all__``) for ``package``: name -> the module that defines it."""

    def __getattr__(name):
        if name not in where:
            if not name.startswith("__") and find_spec(f"{package}.{name}") is not None:
                return import_module(f"{package}.{name}")     # a submodule, as if imported eagerly
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(import_module(where[name], package), name)
        setattr(sys.modules[package], name, value)    # later lookups are plain attribute reads
        return value

    def __dir__():
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__, list(where)
