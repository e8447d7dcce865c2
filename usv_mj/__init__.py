"""usv_mj: the paper's adaptive prescribed-performance USV controller on an analytic and a MuJoCo plant.

Python API (see the README)::

    from usv_mj import load_scenario, simulate, summarize
    scenario = load_scenario(preset="paper", overrides={"duration": 60.0})
    record = simulate(scenario)
    print(summarize(record)["errors_at"])

The names below are imported on first use, so that ``usv_mj.physics.ship`` (the physics, which the
controllers use) can be imported without the rest of the package.
"""

import sys
from importlib.machinery import PathFinder
from pathlib import Path

from usv_mj.core import moved
from usv_mj.core.lazy_names import lazy_names
from usv_mj.support.numba_cache import install_when_imported

install_when_imported()     # a damaged numba cache file is compiled again, not EOFError for ever
moved.install()             # a plug-in's old module names (usv_mj.registry, usv_mj.ship, ...) still import

from usv_mj.core.version import __version__  # noqa: E402


class _CheckoutFinder:
    """In a checkout, ``controllers/`` and ``models/`` sit beside ``usv_mj/`` (the repository's
    layout) and are the subpackages ``usv_mj.controllers`` and ``usv_mj.models`` of an installed
    wheel (``package-dir`` in pyproject.toml). This finder gives a checkout the same names, so that
    a clone or a worktree runs its own files whether or not (and wherever) it is installed."""

    def __init__(self, root: Path):
        self.root = str(root)

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in ("usv_mj.controllers", "usv_mj.models"):
            return None
        from importlib.util import spec_from_file_location

        found = PathFinder.find_spec(fullname.rsplit(".", 1)[1], [self.root])
        if found is None:
            return None
        return spec_from_file_location(fullname, found.origin,
                                       submodule_search_locations=found.submodule_search_locations)


_ROOT = Path(__file__).resolve().parent.parent
if not (Path(__file__).resolve().parent / "controllers").is_dir() and (_ROOT / "controllers" / "__init__.py").is_file():
    sys.meta_path.insert(0, _CheckoutFinder(_ROOT))

_API = {
    "RunRecord": "usv_mj.record.run_record",
    "Scenario": "usv_mj.scenario.spec",
    "ScenarioError": "usv_mj.core.errors",
    "build": "usv_mj.builder",
    "Parts": "usv_mj.builder",
    "CONTROLLERS": "usv_mj.core.registry",
    "PLANTS": "usv_mj.core.registry",
    "TRAJECTORIES": "usv_mj.core.registry",
    "DISTURBANCES": "usv_mj.core.registry",
    "load_scenario": "usv_mj.scenario.spec",
    "simulate": "usv_mj.loop.simulate",
    "summarize": "usv_mj.record.summary",
    "run_job": "usv_mj.jobs.run",
    "attach_hydrodynamics": "usv_mj.plants.attach",
}
__getattr__, __dir__, _ = lazy_names(__name__, _API)
__all__ = [*_API, "__version__"]
