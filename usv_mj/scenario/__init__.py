"""Scenario: TOML -> typed, validated data (a preset plus overrides; docs/model.md §5 and §7).

A leaf of the package: its sections are resolved through the registries (:mod:`usv_mj.core.registry`),
never by importing the feature that runs them. ``from usv_mj.scenario import load_scenario`` is the
public door; the dataclasses and the loader live in :mod:`usv_mj.scenario.spec`.
"""

from usv_mj.scenario.spec import Scenario, ScenarioError, from_dict, load_scenario, preset_names  # noqa: F401

__all__ = ["Scenario", "ScenarioError", "load_scenario", "from_dict", "preset_names"]
