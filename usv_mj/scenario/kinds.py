"""The registered kinds a scenario names, and what another process must import to find them.

A sweep's Dask worker rebuilds each run's scenario; a kind registered at runtime by an importable
module's decorator is found there only once that module is imported (:func:`worker_imports`).
"""

from __future__ import annotations

from usv_mj.core.registry import REGISTRIES


def scenario_kinds(scenario) -> list[tuple[str, str]]:
    """(registry section, kind) of every registered part ``scenario`` names."""
    out = [("controller", scenario.controller.kind), ("trajectory", scenario.trajectory.kind),
           ("plant", scenario.plant.kind)]
    if scenario.baseline.enabled:
        out.append(("controller", scenario.baseline.kind))
    return out


def worker_imports(scenario) -> tuple[str, ...]:
    """The modules another process (a sweep's Dask worker) must import to find the kinds of
    ``scenario`` that were registered at runtime by an importable module's decorator (built-ins,
    entry points and ``module:Name`` kinds need none: a worker finds them by import). A kind
    registered only in this process (in ``__main__``) raises :class:`usv_mj.core.errors.SweepError`."""
    from usv_mj.core.errors import SweepError

    modules = []
    for section, kind in scenario_kinds(scenario):
        registry = REGISTRIES[section]
        problem = registry.portable(kind)
        if problem is not None:
            raise SweepError(f"{scenario.source}: {section}.kind: {problem}")
        module = registry.module_to_import(kind)
        if module and module not in modules:
            modules.append(module)
    return tuple(modules)
