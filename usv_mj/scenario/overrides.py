"""Overrides of a scenario as a nested dict: ``--set`` items and the ``--vessel`` shorthand.

Plain data transforms (no argparse): every command's flags end here, and so does the Python API's
``usv_mj.envs.load(vessel=...)``.
"""

from __future__ import annotations

import tomllib

from usv_mj.core.errors import ScenarioError


def parse_set(items: list[str]) -> dict:
    """``--set a.b=1`` items -> nested dict; values are TOML (numbers, strings, lists, true/false)."""
    out: dict = {}
    for item in items:
        if "=" not in item:
            raise ScenarioError(f"--set {item!r}: expected KEY=VALUE, e.g. controller.k1=5")
        key, value = item.split("=", 1)
        try:
            parsed = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            parsed = value  # a bare word: take it as a string
        node = out
        parts = key.strip().split(".")
        if parts[0] == "vessels" and len(parts) > 1:   # a list of tables: a dotted key cannot name one of them
            raise ScenarioError(f"--set {item!r}: [[vessels]] is a list of tables, which --set cannot reach into; "
                                f"change the vessel in the scenario file, or give the whole list "
                                f"(--set 'vessels=[{{name = \"own\", ...}}, ...]')")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ScenarioError(f"--set {item!r}: {part} was set to a value above, not a table")
        node[parts[-1]] = parsed
    return out


def with_vessel(kind, overrides: dict) -> dict:
    """``overrides`` (a nested dict of scenario values) with ``[vessel] kind`` = ``kind`` (None or
    "": unchanged), keeping the vessel's options given beside it: what --vessel does for every
    command, and ``usv_mj.envs.load(vessel=...)`` for the environments. ScenarioError when
    ``overrides`` make that impossible (a [vessel] that is not a table, the paper's [ship] options
    with another kind)."""
    if kind:
        if not isinstance(overrides.get("vessel", {}), dict):
            raise ScenarioError(f"--set vessel={overrides['vessel']!r}: [vessel] must be a table")
        if isinstance(overrides.get("ship"), dict) and kind != "paper":
            raise ScenarioError(f"--vessel {kind}: --set ship.* sets the paper vessel's parameters; "
                                f"give the vessel's own as --set vessel.KEY=VALUE")
        overrides = {**overrides, "vessel": {**overrides.get("vessel", {}), "kind": kind}}
    return overrides
