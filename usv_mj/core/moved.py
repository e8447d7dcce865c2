"""The modules that moved into the layer folders (issue 33), still importable by their old names.

A user's plug-in written against an earlier usv_mj (``from usv_mj.registry import CONTROLLERS``,
``from usv_mj.ship import ShipParams``) keeps working: :class:`MovedFinder`, put on
``sys.meta_path`` by ``usv_mj/__init__.py``, answers an old name with the module at its new place
(the same module object under both names, so a registry or a class is never imported twice).
usv_mj's own code imports the new names only (tests/test_layers.py holds it to that).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys

#: old dotted name -> new dotted name (a package's modules follow it: usv_mj.sea.waves -> usv_mj.physics.sea.waves)
MOVED = {
    "usv_mj.errors": "usv_mj.core.errors",
    "usv_mj.registry": "usv_mj.core.registry",
    "usv_mj.kernels": "usv_mj.core.kernels",
    "usv_mj.lazy_names": "usv_mj.core.lazy_names",
    "usv_mj.numba_cache": "usv_mj.support.numba_cache",
    "usv_mj.spawning": "usv_mj.support.spawning",
    "usv_mj.assets": "usv_mj.support.assets",
    "usv_mj.toml_values": "usv_mj.support.toml_values",
    "usv_mj.example_files": "usv_mj.support.example_files",
    "usv_mj.obstacle_tables": "usv_mj.scenario.obstacles",
    "usv_mj.presets": "usv_mj.scenario.presets",
    "usv_mj.ship": "usv_mj.physics.ship",
    "usv_mj.mmg": "usv_mj.physics.mmg",
    "usv_mj.disturbances": "usv_mj.physics.disturbances",
    "usv_mj.actuators": "usv_mj.physics.actuators",
    "usv_mj.limits": "usv_mj.physics.limits",
    "usv_mj.sea": "usv_mj.physics.sea",
    "usv_mj.obstacles.compose": "usv_mj.scene.compose",
    "usv_mj.obstacles.display": "usv_mj.scene.display",
    "usv_mj.trajectories": "usv_mj.references.trajectories",
    "usv_mj.obstacles.planner": "usv_mj.references.planner",
    "usv_mj.obstacles.guided": "usv_mj.references.guided",
    "usv_mj.simulation": "usv_mj.loop.simulate",
    "usv_mj.compiled_loop": "usv_mj.loop.compiled",
    "usv_mj.record_store": "usv_mj.record.store",
    "usv_mj.summary": "usv_mj.record.summary",
    "usv_mj.criteria": "usv_mj.record.criteria",
    "usv_mj.decimate": "usv_mj.record.decimate",
    "usv_mj.figures": "usv_mj.outputs.figures",
    "usv_mj.sea_figures": "usv_mj.outputs.sea_figures",
    "usv_mj.report": "usv_mj.outputs.report",
    "usv_mj.render": "usv_mj.outputs.render",
    "usv_mj.runlog": "usv_mj.outputs.log",
    "usv_mj.outdir": "usv_mj.outputs.outdir",
    "usv_mj.gymnasium_hook": "usv_mj.envs.gymnasium_hook",
    "usv_mj.main_job": "usv_mj.jobs.run",
    "usv_mj.compare": "usv_mj.jobs.compare",
    "usv_mj.manoeuvres.options": "usv_mj.scenario.manoeuvre",
    "usv_mj.manoeuvres": "usv_mj.jobs.manoeuvres",
    "usv_mj.sweep": "usv_mj.jobs.sweep",
    "usv_mj.bench": "usv_mj.jobs.bench",
    "usv_mj.kinds": "usv_mj.cli.kinds",
    "usv_mj.command_args": "usv_mj.cli.args",
}


def new_name(fullname: str) -> str | None:
    """The module an old name stands for now (None: ``fullname`` did not move)."""
    if fullname in MOVED:
        return MOVED[fullname]
    head = fullname
    while "." in head:
        head = head.rsplit(".", 1)[0]
        if head in MOVED:
            return MOVED[head] + fullname[len(head):]
    return None


class _Alias(importlib.abc.Loader):
    def __init__(self, target: str):
        self.target = target

    def create_module(self, spec):
        return importlib.import_module(self.target)

    def exec_module(self, module):
        pass


class MovedFinder(importlib.abc.MetaPathFinder):
    """Finds an old module name (:data:`MOVED`) as the module at its new place."""

    def find_spec(self, fullname, path=None, target=None):
        if not fullname.startswith("usv_mj."):
            return None
        new = new_name(fullname)
        if new is None or importlib.util.find_spec(new) is None:
            return None
        return importlib.util.spec_from_loader(fullname, _Alias(new))


def install() -> None:
    """Put :class:`MovedFinder` on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(MovedFinder())
