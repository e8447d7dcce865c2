"""Several vessels in one scenario: the ``[[vessels]]`` tables (issue 35).

::

    duration = 120.0               # shared: the run, its sea, its obstacles, the plant kind, limits
    [plant]
    kind = "mujoco"

    [[vessels]]
    name = "own"
    own_ship = true                # at most one; the first vessel when none says so
    initial = { eta = [0.0, 0.0, 1.5708], nu = [1.0, 0.0, 0.0] }
    [vessels.vessel]               # any registered or data-file vessel kind, with its options
    kind = "otter"
    [vessels.controller]           # steer = "controller" (default): a controller with a reference
    kind = "los"
    [vessels.trajectory]
    kind = "line"
    start = [0.0, 0.0]
    heading_deg = 90.0
    speed = 1.0

    [[vessels]]
    name = "target"
    steer = "keep"                 # keep course and speed (the start's heading and speed), or
    initial = { eta = [0.0, 200.0, -1.5708], nu = [1.0, 0.0, 0.0] }
    # steer = "route" with route = [[x, y], ...] and speed: waypoints followed by LOS

Each entry is one vessel's own tables, merged over the scenario's top level: ``vessel``,
``initial``, ``controller``, ``trajectory``, ``actuators``, ``quantizer``, ``funnel`` and
``baseline`` may differ per vessel; ``duration``, ``control_period``, ``plant``, ``sea``,
``disturbance``, ``limits``, ``obstacles`` and ``guidance`` are the scene's and shared. Each vessel's
result is an ordinary, fully validated :class:`usv_mj.scenario.spec.Scenario` (``VesselEntry.scenario``):
everything a single run knows applies to each vessel unchanged.

Steering: ``"controller"`` (its ``[controller]`` and ``[trajectory]``), ``"route"`` (``route``:
waypoints [[x, y], ...] [m] from its start, followed at ``speed`` [m/s] by LOS guidance), ``"keep"``
(keep its start's course and ``speed``: LOS on the straight line from its start along its heading).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from usv_mj.core.errors import ScenarioError

#: what each [[vessels]] entry may set (the rest of the scenario is the scene's, shared)
OWN_TABLES = ("vessel", "ship", "initial", "controller", "trajectory", "actuators", "quantizer", "funnel", "baseline")
ENTRY_KEYS = ("name", "own_ship", "steer", "route", "speed") + OWN_TABLES
STEERS = ("controller", "route", "keep")


@dataclass(frozen=True)
class VesselEntry:
    """One vessel of a scenario's ``[[vessels]]`` (module docstring).

    Attributes
    ----------
    name: unique, the vessel's name in records, logs and figures ([A-Za-z0-9_-]).
    own_ship: the own ship (the vessel the encounter measures and scores are taken from).
    steer: "controller", "route" or "keep".
    scenario: the vessel's full scenario (the scene's tables with the vessel's own merged in).
    """

    name: str
    own_ship: bool
    steer: str
    scenario: Any


def _route_tables(entry: dict, steer: str, base_raw: dict, where: str) -> dict:
    """The [controller] and [trajectory] a "route" or "keep" vessel runs (LOS on its path)."""
    initial = entry.get("initial") if isinstance(entry.get("initial"), dict) else base_raw.get("initial", {})
    eta = initial.get("eta") if isinstance(initial, dict) else None
    if not (isinstance(eta, (list, tuple)) and len(eta) == 3 and all(isinstance(v, (int, float)) for v in eta)):
        raise ScenarioError(f"{where}: steer = {steer!r} needs the vessel's start: initial.eta = [x, y, psi]")
    speed = entry.get("speed")
    if speed is None:
        nu = initial.get("nu") if isinstance(initial, dict) else None
        speed = nu[0] if isinstance(nu, (list, tuple)) and nu else None
    if not (isinstance(speed, (int, float)) and not isinstance(speed, bool) and math.isfinite(speed) and speed > 0):
        raise ScenarioError(f"{where}: steer = {steer!r} needs speed > 0 m/s (or initial.nu's surge speed), got {speed!r}")
    if steer == "keep":
        trajectory = {"kind": "line", "start": [float(eta[0]), float(eta[1])],
                      "heading_deg": math.degrees(float(eta[2])), "speed": float(speed)}
    else:
        route = entry.get("route")
        if not (isinstance(route, (list, tuple)) and len(route) >= 1
                and all(isinstance(p, (list, tuple)) and len(p) == 2 for p in route)):
            raise ScenarioError(f"{where}: steer = 'route' needs route = [[x, y], ...] (at least one waypoint), "
                                f"got {route!r}")
        trajectory = {"kind": "waypoints", "points": [[float(eta[0]), float(eta[1])]] + [list(p) for p in route],
                      "speed": float(speed)}
    controller = entry.get("controller") if isinstance(entry.get("controller"), dict) else {"kind": "los"}
    return {"trajectory": trajectory, "controller": controller}


def vessels_from_tables(tables: Any, base_raw: dict, source: str, from_dict) -> tuple:
    """The :class:`VesselEntry` tuple of ``[[vessels]]`` (module docstring); ``base_raw``: the scenario's
    own table without ``vessels``; ``from_dict``: the scenario loader (each vessel is a scenario)."""
    if tables is None:
        return ()
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise ScenarioError(f"{source}: [[vessels]] must be a list of tables (one per vessel), got {tables!r}")
    if len(tables) < 2:   # one vessel is a single run: its [vessel], [controller] ... tables, not a list
        raise ScenarioError(f"{source}: [[vessels]] holds {len(tables)} vessel(s): give two or more, or describe one "
                            f"vessel with the scenario's own tables ([vessel], [initial], [controller], [trajectory])")
    out, names, own = [], set(), []
    for i, entry in enumerate(tables):
        name = entry.get("name", f"vessel_{i}")
        where = f"{source}: vessels[{i}]" + (f" ({name})" if isinstance(name, str) else "")
        if not (isinstance(name, str) and name and all(c.isalnum() or c in "_-" for c in name)):
            raise ScenarioError(f"{where}: name must be letters, digits, '_' or '-', got {name!r}")
        if name in names:
            raise ScenarioError(f"{where}: the name {name!r} is given twice; each vessel needs its own")
        names.add(name)
        for key in entry:
            if key not in ENTRY_KEYS:
                import difflib

                hint = difflib.get_close_matches(key, ENTRY_KEYS, n=1)
                raise ScenarioError(f"{where}: unknown key {key!r}" + (f" (did you mean {hint[0]!r}?)" if hint else "")
                                    + f"; a vessel's keys: {', '.join(ENTRY_KEYS)} (the scene's tables are "
                                    f"the scenario's top level)")
        steer = entry.get("steer", "controller")
        if steer not in STEERS:
            raise ScenarioError(f"{where}: steer must be one of {', '.join(map(repr, STEERS))}, got {steer!r}")
        own_ship = entry.get("own_ship", False)
        if not isinstance(own_ship, bool):
            raise ScenarioError(f"{where}: own_ship must be true or false, got {own_ship!r}")
        if own_ship:
            own.append(name)
        if "initial" not in entry:
            raise ScenarioError(f"{where}: give the vessel's start, initial = {{ eta = [x, y, psi] }} (vessels "
                                f"starting at one pose would collide)")
        data = dict(base_raw)    # the scene's tables and the scenario's defaults for the vessel's own ...
        data.update({k: entry[k] for k in OWN_TABLES if k in entry})   # ... which the entry's replace whole
        if steer != "controller":
            data.update(_route_tables(entry, steer, base_raw, where))
        data.setdefault("baseline", {})
        if isinstance(data["baseline"], dict):
            data["baseline"] = {**data["baseline"], "enabled": False}   # a fleet runs no baseline per vessel
        try:
            scenario = from_dict(data, source=f"{source} vessels[{i}] ({name})")
        except ScenarioError as exc:
            raise ScenarioError(str(exc)) from None
        out.append(VesselEntry(name, own_ship, steer, scenario))
    if len(own) > 1:
        raise ScenarioError(f"{source}: [[vessels]]: own_ship = true on {', '.join(own)}; at most one vessel is the "
                            f"own ship")
    starts = [(v.name, tuple(map(float, v.scenario.initial.eta[:2])), float(v.scenario.vessel.model.dimensions.L))
              for v in out]
    for a in range(len(starts)):
        for b in range(a + 1, len(starts)):
            (na, pa, la), (nb, pb, lb) = starts[a], starts[b]
            gap = math.hypot(pa[0] - pb[0], pa[1] - pb[1])
            if gap < (la + lb) / 2.0:   # the hulls would overlap at t = 0 (a collision before any step)
                raise ScenarioError(f"{source}: vessels {na!r} and {nb!r} start {gap:.3g} m apart, closer than their "
                                    f"half-lengths added ({(la + lb) / 2.0:.3g} m): their hulls overlap at t = 0; move one "
                                    f"(initial.eta)")
    if not own:   # the first vessel is the own ship when none says so
        first = out[0]
        out[0] = VesselEntry(first.name, True, first.steer, first.scenario)
    return tuple(out)
