"""The Imazu tasks of a benchmark suite: a task whose episodes are Imazu situations (issue 35 item 5).

A suite's task with the key ``imazu`` (``usv_mj/jobs/bench/suites/imazu.toml``)::

    [[tasks]]
    name = "two-targets"
    base = "paper"
    set = { "control_period" = 0.02 }
    imazu = { cases = [5, 6, 7, 8, 9, 10, 11], k_R = 50.0, froude = 0.1361, duration_T = 2.0 }
    # or imazu = [5, 6, 7] (the other keys at their defaults)

Each listed case is one episode (its index in the list; the row's ``vary.situation`` is the case).
The situations are Imazu's 22 (Imazu 1987), with the geometry of Sawada, Sato and Majima (2021),
J. Mar. Sci. Technol. 26:509-524, Table 4, placed by :func:`usv_mj.scenario.imazu.imazu_situation`.

**The episode** (:func:`fleet_scenario`): the task's scenario under the condition, on the vessel and
with the controller of the episode is the **own ship**: it starts at the origin heading north at
the situation's speed U, its reference a straight line along that heading at U (its planned
route), and it is steered by the controller under test (a controller with a
``traffic(t, states, index, lengths)`` method sees the other vessels: ``sbmpc``, a plug-in; any
other follows its route blind, e.g. ``los``, the "no avoidance" baseline). Every target is the
same vessel kind, keeping course and speed (``steer = "keep"``: LOS on the straight line of its
start, at its speed ratio times U), on a course that meets the own ship at the collision point
C = R ahead at T = R / U if nobody manoeuvres. The scene (sea, plant, control period, limits) is
the task's; the episode lasts ``duration_T`` T.

**The scaling** (stated in docs/encounters.md §4): R = k_R L (k_R = 50: the closest start 8.7 L, the
slow target 15 L ahead), U = Fn sqrt(g L) with Fn = :data:`PAPER_FROUDE` (the paper hull's
0.6 m/s at L = 1.98 m, the speed of the manoeuvres and of tests/test_sbmpc.py, Froude-scaled to
every hull), so T = R / U = (k_R / Fn) sqrt(L / g): 165 s for the paper hull.

**Which vessels suit** (:func:`suits`, the rule the shipped suite's ``vessels`` follows): a vessel
that takes a surge force and a yaw moment (the commands of the avoidance laws: ``los``, ``sbmpc``)
and has a model of the sea (the suite's second condition). Of the built-in kinds: paper,
cybership2, otter, clarke83; not kvlcc2 (ruddered, and its MMG hull runs in calm water only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from usv_mj.core.errors import ScenarioError, SweepError
from usv_mj.scenario.imazu import IMAZU_CASES, K_R_DEFAULT, VARIANTS, ImazuSituation, imazu_situation
from usv_mj.scenario.spec import from_dict

G = 9.81
"""m/s^2: the gravity of the Froude number (the manoeuvres' scaling, usv_mj.scenario.manoeuvre)."""
PAPER_FROUDE = 0.6 / math.sqrt(G * 1.98)
"""-: Fn = U / sqrt(g L) of the paper hull (L = 1.98 m) at 0.6 m/s: 0.1361."""
IMAZU_KEYS = ("cases", "k_R", "froude", "duration_T", "variant")
#: the episode function and the row hook of an Imazu episode (usv_mj.jobs.sweep.runner.run_one)
FLEET_EPISODE = "usv_mj.jobs.bench.episode:fleet_episode"


@dataclass(frozen=True)
class ImazuOptions:
    """A task's ``imazu`` table (module docstring).

    Attributes
    ----------
    cases: the Imazu cases (1..22), one episode each, in this order.
    k_R: R = k_R L, the distance to the collision point in own-ship lengths [-].
    froude: Fn, the situation's speed U = Fn sqrt(g L) [-].
    duration_T: the episode's duration in T = R / U [-] (2: past the CPA by as long again, TUD_RL's).
    variant: "canonical" (case 12 with three targets) or "table4" (Sawada's Table 4 as transcribed).
    """

    cases: tuple = tuple(range(1, 23))
    k_R: float = K_R_DEFAULT
    froude: float = PAPER_FROUDE
    duration_T: float = 2.0
    variant: str = "canonical"


def imazu_options(spec, where: str) -> ImazuOptions:
    """The :class:`ImazuOptions` of a task's ``imazu`` value (a list of cases, or a table)."""
    table = {"cases": spec} if isinstance(spec, list) else spec
    if not isinstance(table, dict):
        raise SweepError(f"{where}: imazu must be a list of cases (1..22) or a table ({', '.join(IMAZU_KEYS)}), "
                         f"got {spec!r}")
    for key in table:
        if key not in IMAZU_KEYS:
            raise SweepError(f"{where}: imazu: unknown key {key!r}; known keys: {', '.join(IMAZU_KEYS)}")
    cases = table.get("cases", list(ImazuOptions.cases))
    if not (isinstance(cases, list) and cases and all(isinstance(c, int) and not isinstance(c, bool)
                                                      and c in IMAZU_CASES for c in cases)):
        raise SweepError(f"{where}: imazu.cases must be a non-empty list of Imazu cases 1..22, got {cases!r}")
    if len(set(cases)) != len(cases):
        raise SweepError(f"{where}: imazu.cases lists a case twice: {cases!r}")
    values = {}
    for key in ("k_R", "froude", "duration_T"):
        v = table.get(key, getattr(ImazuOptions, key))
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise SweepError(f"{where}: imazu.{key} must be a number > 0, got {v!r}")
        values[key] = float(v)
    variant = table.get("variant", "canonical")
    if variant not in VARIANTS:
        raise SweepError(f"{where}: imazu.variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    return ImazuOptions(tuple(cases), variant=variant, **values)


def situation_speed(length_m: float, froude: float = PAPER_FROUDE) -> float:
    """U = Fn sqrt(g L) [m/s]: the own ship's speed in the situations on a hull of length L [m]."""
    return froude * math.sqrt(G * length_m)


def suits(vessel) -> str | None:
    """Why ``vessel`` (a :class:`usv_mj.vessels.Vessel`) does not suit the Imazu suite, or None when it
    does (module docstring: it takes forces and it has a model of the sea)."""
    channels = getattr(vessel, "channels", None)
    if channels is not None and not channels.forces:
        return (f"it takes {channels.surge.quantity} and {channels.yaw.quantity}, not forces (the avoidance "
                f"laws command a surge force and a yaw moment)")
    why = (getattr(vessel, "limitations", None) or {}).get("sea")
    if why:
        return f"no sea: {why}"
    return None


def fleet_scenario(scenario, case: int, options: ImazuOptions, where: str) -> tuple:
    """(the fleet scenario of Imazu ``case`` for ``scenario``'s own ship, its :class:`ImazuSituation`):
    module docstring. ``scenario``: a single vessel's scenario (the task's, under the condition, on
    the vessel and with the controller of the episode)."""
    length = float(scenario.vessel.model.dimensions.L)
    speed = situation_speed(length, options.froude)
    sit: ImazuSituation = imazu_situation(case, length, speed, k_R=options.k_R, variant=options.variant)
    own = sit.own
    x0, y0, psi0 = own.eta
    route = {"kind": "line", "start": [x0, y0], "heading_deg": math.degrees(psi0), "speed": speed}
    vessels = [{"name": own.name, "own_ship": True, "initial": {"eta": list(own.eta), "nu": list(own.nu)},
                "trajectory": route}]
    for target in sit.targets:
        vessels.append({"name": target.name, "steer": "keep",
                        "initial": {"eta": list(target.eta), "nu": list(target.nu)}})
    data = {k: v for k, v in scenario.raw.items() if k not in ("vessels", "initial", "trajectory")}
    data["duration"] = options.duration_T * sit.T_cpa_s
    data["vessels"] = vessels
    try:
        return from_dict(data, source=scenario.source), sit
    except ScenarioError as exc:
        raise SweepError(f"{where}: Imazu case {case}: {exc}") from None


__all__ = ["ImazuOptions", "imazu_options", "situation_speed", "suits", "fleet_scenario", "PAPER_FROUDE",
           "FLEET_EPISODE"]
