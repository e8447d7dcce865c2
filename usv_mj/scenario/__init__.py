"""Scenario: TOML -> typed, validated data (a preset plus overrides; docs/model.md §5 and §7).

A leaf of the package: its sections are resolved through the registries (:mod:`usv_mj.core.registry`),
never by importing the feature that runs them. ``from usv_mj.scenario import load_scenario`` is the
public door; the dataclasses and the loader live in :mod:`usv_mj.scenario.spec`. The names load on
first use, so that the light modules of the package (:mod:`.overrides`, :mod:`.presets`: what the
command line reads to build its flags) come without the physics.
"""

from usv_mj.core.lazy_names import lazy_names

__getattr__, __dir__, _ = lazy_names(__name__, {name: ".spec" for name in
                                                ("Scenario", "ScenarioError", "load_scenario", "from_dict",
                                                 "preset_names")})
__all__ = ["Scenario", "ScenarioError", "load_scenario", "from_dict", "preset_names"]
