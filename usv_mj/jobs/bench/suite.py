"""Benchmark suites: tasks x conditions x vessels x controllers x episodes, planned as one sweep.

A suite is TOML (the default: ``usv_mj/jobs/bench/suites/default.toml``)::

    name = "default"
    episodes = 10             # episodes of every (task, condition, vessel, controller); default 10 (docs/metrics.md)
    seed = 2026               # the start poses and sea seeds: np.random.default_rng([seed, task index])
    duration = 60.0           # s, a task's default
    plant = "analytic"        # optional: every task's plant
    controllers = ["ppc", "pi", "los",                       # registered kinds, plug-ins, module:Name
                   { name = "ppc-k1=4", kind = "ppc", set = { "controller.k1" = 4.0 } },
                   { name = "ppo", policy = "ppo_track.zip" }]   # a learned policy (usv_mj.jobs.bench.policy)
    # a policy's table also takes control_period (s, default 0.01: Track-v0's, the period it was
    # trained at; held over it, zero-order hold) and criterion (a usv_mj.record.criteria table, default:
    # the pose tolerance of its training reward's full-reward band, see usv_mj.jobs.bench.policy)
    vessels = []              # optional: each name becomes the override vessel.kind (empty: the task's hull);
                              # a data file ("boats/wamv.toml") is found next to the suite first

    [conditions.calm]                                     # every task runs in every condition
    [conditions.sea]
    set = { "sea.preset" = "moderate", "sea.current.speed" = 0.3 }
    [conditions.limited]
    actuators = "paper-limited"                           # a preset's [actuators] table

    [[tasks]]
    name = "circle-0.6"
    base = "paper"                                        # a preset, or a scenario file (next to the suite)
    duration = 60.0
    set = { "trajectory.kind" = "circle", "trajectory.speed" = 0.6 }
    vary = { "initial.eta[0]" = { uniform = [-2.0, 2.0] } } # the sweep's distributions (usv_mj.jobs.sweep.spec)
    settle_time_s = 20.0      # the metrics' options (docs/metrics.md); goal = [x, y] or "last_waypoint"

Each episode is a :class:`usv_mj.jobs.sweep.spec.RunSpec` whose ``values`` (the ``vary.*`` columns of
the results) are ``task``, ``condition``, ``vessel``, ``controller``, ``episode`` and the drawn
values; its ``options`` carry the metrics' options and, for a policy, the episode function and its
criterion. A policy's episode scenario is the task's with ``control_period`` = the policy's and
``plant.substeps`` = that period over the task's integration step (which must divide it), so the
plant integrates as for every controller and the policy's action is held over its own period. A
policy is not planned on a task with obstacles (its observation has no view of them): the suite's
``skipped`` says so, and the report. The draws depend on the task and the episode index only, so
every controller meets the same start poses and seas (the pairs of ``--compare``), on any number
of workers.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import hashlib
import json
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from usv_mj.core.errors import SweepError
from usv_mj.jobs.bench.metrics import MetricOptions
from usv_mj.scenario.spec import ScenarioError, from_dict, load_scenario
from usv_mj.jobs.sweep.spec import RunSpec, SweepPlan, apply_values, check_references, draw_values, load_base, parse_axis
from usv_mj.support.toml_values import read_toml

SUITE_KEYS = ("name", "episodes", "seed", "duration", "plant", "controllers", "vessels", "conditions", "tasks",
              "transient")
TASK_KEYS = ("name", "base", "duration", "set", "vary", "settle_time_s", "band_cross_track_m", "band_heading_deg",
             "goal", "goal_radius_m", "episodes")
CONDITION_KEYS = ("set", "actuators", "sea")
CONTROLLER_KEYS = ("name", "kind", "set", "policy", "control_period", "criterion")
POLICY_KEYS = ("control_period", "criterion")
MAX_EPISODES = 100_000
"""The most episodes a suite may plan (every task's episodes x conditions x vessels x controllers):
each planned episode holds its own scenario (about 20 kB) and takes about 10 ms to draw and
validate, so 100 000 are about 2 GB and a quarter of an hour before the first episode runs. A
bigger suite is refused before anything is drawn: split it into several suites."""
ROW_HOOK = "usv_mj.jobs.bench.episode:metrics_row"
#: episodes per cell unless a suite says: the fewest with which a 95 % interval and a paired test of
#: one cell can say something (docs/metrics.md, "How many episodes"): an exact paired test's smallest
#: two-sided p, 2 / 2^n, stays below 0.05 / 15 (Holm over a cell's 15 or so metrics) from n = 10 on,
#: and Wilson's interval of 10 kept out of 10 is [72, 100] % where 2 of 2 gave [34, 100] %
DEFAULT_EPISODES = 10
POLICY_EPISODE = "usv_mj.jobs.bench.policy:policy_episode"


def default_suite_path() -> Path:
    """The suite shipped in the package (``usv_mj/jobs/bench/suites/default.toml``)."""
    return Path(str(resources.files("usv_mj.jobs.bench") / "suites" / "default.toml"))


@dataclass(frozen=True)
class ControllerEntry:
    """A controller to score: ``name`` (its leaderboard row), a scenario ``kind`` with ``set``
    overrides, or a learned ``policy`` (a stable-baselines3 .zip or ``module:callable``)."""

    name: str
    kind: str | None = None
    set: dict = field(default_factory=dict)
    policy: str | None = None
    control_period: float | None = None   # s: a policy's (None: usv_mj.jobs.bench.policy.DEFAULT_CONTROL_PERIOD)
    criterion: dict | None = None         # a policy's criterion table (None: usv_mj.jobs.bench.policy.default_criterion)


@dataclass
class Suite:
    """A planned suite: the sweep plan of its episodes and what the report needs."""

    source: str
    name: str
    plan: SweepPlan
    tasks: list           # task names in file order
    conditions: list      # condition names in file order
    vessels: list         # vessel names ("" = the task's own hull)
    controllers: list     # ControllerEntry in file order
    episodes: dict        # task -> episodes
    skipped: list = field(default_factory=list)   # (task, controller, why): pairs not planned


def _check_keys(source, where, table, known):
    if not isinstance(table, dict):
        raise SweepError(f"{source}: {where} must be a table, got {table!r}")
    for key in table:
        if key not in known:
            hint = difflib.get_close_matches(key, known, n=1)
            raise SweepError(f"{source}: {where}: unknown key {key!r}" + (f" (did you mean {hint[0]!r}?)" if hint else "")
                             + f"; known keys: {', '.join(known)}")


def _controllers(source, items) -> list[ControllerEntry]:
    if not isinstance(items, list) or not items:
        raise SweepError(f"{source}: controllers must be a non-empty list of kinds or tables, got {items!r}")
    out = []
    for i, item in enumerate(items):
        where = f"controllers[{i}]"
        if isinstance(item, str) and item:
            out.append(ControllerEntry(item, kind=item))
            continue
        _check_keys(source, where, item, CONTROLLER_KEYS)
        if ("kind" in item) == ("policy" in item):
            raise SweepError(f"{source}: {where}: give one of kind (a controller kind) or policy (a .zip or "
                             f"module:callable), got {item!r}")
        name = item.get("name") or item.get("kind") or Path(str(item["policy"])).stem
        sets = item.get("set", {})
        if not isinstance(sets, dict):
            raise SweepError(f"{source}: {where}.set must be a table of path = value, got {sets!r}")
        extra = [k for k in POLICY_KEYS if k in item]
        if extra and "policy" not in item:
            raise SweepError(f"{source}: {where}: {', '.join(extra)} go with a policy, not a controller kind")
        if "policy" in item and sets:
            raise SweepError(f"{source}: {where}: set goes with a controller kind, not a policy")
        period = item.get("control_period")
        if period is not None and (isinstance(period, bool) or not isinstance(period, (int, float))
                                   or not math.isfinite(period) or not 0 < period <= 1.0):
            raise SweepError(f"{source}: {where}.control_period must be a number of seconds in (0, 1], got {period!r}")
        crit = item.get("criterion")
        if crit is not None:
            from usv_mj.record.criteria import criterion_from_dict

            if not isinstance(crit, dict):
                raise SweepError(f"{source}: {where}.criterion must be a table (kind = ..., its bounds), got {crit!r}")
            try:
                criterion_from_dict(crit)
            except ScenarioError as exc:
                raise SweepError(f"{source}: {where}.criterion: {exc}") from None
        out.append(ControllerEntry(str(name), item.get("kind"), dict(sets), item.get("policy"),
                                   None if period is None else float(period), None if crit is None else dict(crit)))
    names = [c.name for c in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise SweepError(f"{source}: controllers: the names {dup} appear twice (give each a name = ...)")
    return out


def _with_table(scenario, section: str, table: dict, source: str):
    """``scenario`` with its ``[section]`` replaced by ``table`` (validated again)."""
    data = copy.deepcopy(scenario.raw)
    data[section] = copy.deepcopy(table)
    try:
        return from_dict(data, source=scenario.source)
    except ScenarioError as exc:
        raise SweepError(f"{source}: [{section}] = {table!r}: {exc}") from None


def _condition(source, name, table, scenario, directory=None):
    """``scenario`` under condition ``name``: ``actuators`` (a preset whose [actuators] table is
    taken), ``sea`` (a sea preset name: ``sea.preset``), ``set`` (dotted paths)."""
    _check_keys(source, f"[conditions.{name}]", table, CONDITION_KEYS)
    if "actuators" in table:
        try:
            actuators = load_scenario(preset=table["actuators"]).raw.get("actuators")
        except ScenarioError as exc:
            raise SweepError(f"{source}: [conditions.{name}] actuators: {exc}") from None
        if not actuators:
            raise SweepError(f"{source}: [conditions.{name}] actuators: preset {table['actuators']!r} has no [actuators]")
        scenario = _with_table(scenario, "actuators", actuators, source)
    sets = _suite_files(dict(table.get("set", {})), directory)
    if "sea" in table:
        sets = {"sea.preset": table["sea"], **sets}
    return apply_values(scenario, sets, f"{source} [conditions.{name}]") if sets else scenario


def _controller(source, ctrl: ControllerEntry, scenario):
    """``scenario`` run by ``ctrl``: its kind (the base's [controller] table when the kind is the
    base's, else the kind's defaults), then its ``set`` overrides."""
    if (scenario.raw.get("controller") or {}).get("kind", "ppc") != ctrl.kind:
        scenario = _with_table(scenario, "controller", {"kind": ctrl.kind}, f"{source} controller {ctrl.name!r}")
    return apply_values(scenario, ctrl.set, f"{source} controller {ctrl.name!r}") if ctrl.set else scenario


def _goal(source, where, spec, scenario):
    if spec is None:
        return None
    if spec == "last_waypoint":
        points = getattr(scenario.trajectory.options, "points", None)
        if not points:
            raise SweepError(f"{source}: {where}: goal = \"last_waypoint\" needs a waypoints trajectory")
        return (float(points[-1][0]), float(points[-1][1]))
    if (isinstance(spec, list) and len(spec) == 2
            and all(isinstance(v, (int, float)) and math.isfinite(v) for v in spec)):
        return tuple(float(v) for v in spec)
    raise SweepError(f"{source}: {where}: goal must be [x, y] in m or \"last_waypoint\", got {spec!r}")


def _positive(source, where, v, default, *, integer=False):
    v = default if v is None else v
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0 \
            or (integer and not isinstance(v, int)):
        raise SweepError(f"{source}: {where} must be a {'whole' if integer else 'finite'} number > 0, got {v!r}")
    return v


def check_size(source, episodes: int, tasks: list, n_conditions: int, n_vessels: int, n_controllers: int) -> int:
    """The number of episodes the suite plans (every task's episodes x conditions x vessels x
    controllers; a policy left off a task with obstacles still counted), refused over
    :data:`MAX_EPISODES` before anything is drawn."""
    per_task = []
    for ti, task in enumerate(tasks):
        if not isinstance(task, dict):
            raise SweepError(f"{source}: [[tasks]] {ti} must be a table, got {task!r}")
        name = task.get("name", ti)
        per_task.append(_positive(source, f"task {name!r}: episodes", task.get("episodes"), episodes, integer=True))
    n = sum(per_task) * n_conditions * n_vessels * n_controllers
    if n > MAX_EPISODES:
        raise SweepError(f"{source}: {n} episodes ({sum(per_task)} over the tasks x {n_conditions} conditions x "
                         f"{n_vessels} vessels x {n_controllers} controllers) is over the limit of {MAX_EPISODES}: "
                         f"too many to plan (about 20 kB each); split the suite")
    return n


def load_suite(path: str | Path | None = None) -> Suite:
    """Read, sample and validate a suite file (default: the shipped one); see the module docstring."""
    path = Path(path) if path is not None else default_suite_path()
    if not path.is_file():
        raise SweepError(f"suite file {str(path)!r} does not exist")
    return plan_suite(read_toml(path, SweepError, "suite file"), str(path), path.parent)


def plan_suite(data: dict, source: str = "<suite>", directory: Path | None = None) -> Suite:
    """The :class:`Suite` of a parsed suite table: every episode drawn and validated, nothing run."""
    _check_keys(source, "the suite", data, SUITE_KEYS)
    episodes = _positive(source, "episodes", data.get("episodes"), DEFAULT_EPISODES, integer=True)
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SweepError(f"{source}: seed must be a whole number >= 0, got {seed!r}")
    duration = _positive(source, "duration", data.get("duration"), 60.0)
    controllers = _controllers(source, data.get("controllers", ["ppc", "pi", "los"]))
    for i, ctrl in enumerate(controllers):
        if ctrl.policy is not None:
            _check_policy(source, f"controllers[{i}] ({ctrl.name!r})", ctrl.policy, directory)
    vessels = data.get("vessels", [])
    if not isinstance(vessels, list) or not all(isinstance(v, str) and v for v in vessels):
        raise SweepError(f"{source}: vessels must be a list of vessel kinds, got {vessels!r}")
    vessel_files = {v: _suite_file(v, directory) for v in vessels}   # named as given, run from their file
    vessels = vessels or [""]
    conditions = data.get("conditions", {"calm": {}})
    if not isinstance(conditions, dict) or not conditions:
        raise SweepError(f"{source}: [conditions] must hold at least one table, got {conditions!r}")
    tasks = data.get("tasks")
    if not isinstance(tasks, list) or not tasks:
        raise SweepError(f"{source}: a suite needs at least one [[tasks]] table")
    check_size(source, episodes, tasks, len(conditions), len(vessels), len(controllers))
    runs, names, per_task, skipped = [], [], {}, []
    for ti, task in enumerate(tasks):
        _check_keys(source, f"[[tasks]] {ti}", task, TASK_KEYS)
        name = task.get("name")
        if not isinstance(name, str) or not name or name in names:
            raise SweepError(f"{source}: [[tasks]] {ti}: name must be a unique non-empty string, got {name!r}")
        bad = sorted({c for c in name if c in "/\\" or not c.isprintable()})
        if bad or name in (".", ".."):
            raise SweepError(f"{source}: [[tasks]] {ti}: name {name!r} cannot name a file (figures/bars-NAME.png): "
                             f"no {', '.join(map(repr, bad)) or 'name . or ..'}; use letters, digits, '-', '_', '.'")
        names.append(name)
        where = f"task {name!r}"
        base = load_base(f"{source} {where}", task.get("base", "paper"), directory)
        fixed = {"duration": _positive(source, f"{where}: duration", task.get("duration"), duration),
                 "baseline.enabled": False}
        if "plant" in data:
            fixed["plant.kind"] = data["plant"]
        sets = task.get("set", {})
        if not isinstance(sets, dict):
            raise SweepError(f"{source}: {where}: set must be a table of path = value, got {sets!r}")
        sets = _suite_files(sets, directory)
        base = apply_values(base, {**fixed, **sets}, f"{source} {where}")
        n_ep = _positive(source, f"{where}: episodes", task.get("episodes"), episodes, integer=True)
        per_task[name] = n_ep
        vary = task.get("vary", {})
        if not isinstance(vary, dict):
            raise SweepError(f"{source}: {where}: vary must be a table of path = distribution, got {vary!r}")
        axes = [parse_axis(f"{source} {where}", p, s) for p, s in vary.items()]
        if any(a.kind == "grid" for a in axes):
            raise SweepError(f"{source}: {where}: vary takes distributions ({{ uniform = [a, b] }}, ...), not grids")
        rng = np.random.default_rng([seed, ti])
        drawn = {a.path: draw_values(rng, a, n_ep) for a in axes}
        heading = task.get("band_heading_deg", 10.0)
        try:
            options = MetricOptions(
                settle_time_s=task.get("settle_time_s", 20.0), band_cross_track_m=task.get("band_cross_track_m", 1.0),
                band_heading_rad=math.radians(heading) if isinstance(heading, (int, float)) else heading,
                goal=_goal(source, where, task.get("goal"), base), goal_radius_m=task.get("goal_radius_m", 2.0))
        except ScenarioError as exc:
            raise SweepError(f"{source}: {where}: {exc}") from None
        metric_opts = dataclasses.asdict(options)
        for ctrl in controllers:
            if ctrl.policy and base.obstacles:
                skipped.append((name, ctrl.name, "a policy's Track observation has no view of the obstacles"))
        for cname, ctable in conditions.items():
            cond = _condition(source, cname, ctable or {}, base, directory)
            for vessel in vessels:
                ves = apply_values(cond, {"vessel.kind": vessel_files[vessel]}, f"{source} vessel {vessel!r}") \
                    if vessel else cond
                for ctrl in controllers:
                    if ctrl.policy and base.obstacles:
                        continue
                    scen = _policy_scenario(source, ctrl, ves) if ctrl.policy else _controller(source, ctrl, ves)
                    for ep in range(n_ep):
                        values = {a.path: drawn[a.path][ep] for a in axes}
                        scenario = apply_values(scen, values, f"{source} {where} episode {ep}") if values else scen
                        run_values = {"task": name, "condition": cname, "vessel": vessel or "default",
                                      "controller": ctrl.name, "episode": ep, **values}
                        options = {"row_hook": ROW_HOOK, "metrics": metric_opts}
                        if ctrl.policy:
                            options.update({"episode_fn": POLICY_EPISODE, "policy": _policy_path(ctrl.policy, directory),
                                            "criterion": _policy_criterion(ctrl, options["metrics"])})
                        runs.append(RunSpec(len(runs), run_values, scenario, options))
    if not runs:
        raise SweepError(f"{source}: nothing to run: "
                         + "; ".join(f"{c} not on {t} ({why})" for t, c, why in skipped))
    check_references(runs, source)
    plan = SweepPlan(source=source, base=runs[0].scenario, axes=[], runs=runs, samples=1, seed=seed,
                     transient=20.0, name=str(data.get("name", Path(source).stem)))
    doc = {"suite": data, "runs": [[r.run_id, r.values, r.scenario.raw, r.options] for r in runs]}
    plan.fingerprint = hashlib.sha256(json.dumps(doc, sort_keys=True, default=repr).encode()).hexdigest()
    return Suite(source, plan.name, plan, names, list(conditions), vessels, controllers, per_task, skipped)


def _suite_file(value, directory: Path | None):
    """A data file a suite names (a vessel ``kind = "boat.toml"``): relative to the suite's folder
    when it is there (as a task's ``base``), made absolute so every worker finds it; else as given
    (relative to the working folder, or a kind)."""
    if isinstance(value, str) and value.endswith(".toml") and directory is not None and not Path(value).is_absolute():
        candidate = directory / value
        if candidate.is_file():
            return str(candidate.resolve())
    return value


def _suite_files(sets: dict, directory: Path | None) -> dict:
    """``set`` overrides with the data files they name (``vessel.kind``) resolved as :func:`_suite_file`."""
    return {p: (_suite_file(v, directory) if p == "vessel.kind" else v) for p, v in sets.items()}


def _policy_scenario(source, ctrl: ControllerEntry, scenario):
    """``scenario`` at the policy's control period: ``plant.substeps`` = the period over the task's
    integration step ``control_period / plant.substeps`` (which must divide it)."""
    from usv_mj.jobs.bench.policy import DEFAULT_CONTROL_PERIOD

    period = ctrl.control_period or DEFAULT_CONTROL_PERIOD
    h = scenario.control_period / scenario.plant.substeps
    n = round(period / h)
    if n < 1 or abs(n * h - period) > 1e-9 * period:
        raise SweepError(f"{source}: controller {ctrl.name!r}: control_period {period:g} s is not a whole number "
                         f"of the task's integration steps of {h:g} s")
    return apply_values(scenario, {"control_period": period, "plant.substeps": n},
                        f"{source} controller {ctrl.name!r}")


def _policy_criterion(ctrl: ControllerEntry, metrics: dict) -> dict:
    """The criterion table a policy's episodes are judged by (its own, else the default of the task)."""
    from usv_mj.jobs.bench.policy import default_criterion

    return dict(ctrl.criterion) if ctrl.criterion else default_criterion(metrics["settle_time_s"]).to_dict()


def _check_policy(source, where: str, spec, directory: Path | None) -> None:
    """A policy that cannot be found is refused when the suite is planned, not in every episode (a
    bench whose episodes all failed to load it, exit 0): a ``.zip`` must exist, a
    ``package.module:callable``'s module must be importable (it is imported by the workers)."""
    import importlib.util

    if not isinstance(spec, str) or not spec:
        raise SweepError(f"{source}: {where}: policy must be a .zip or package.module:callable, got {spec!r}")
    if spec.endswith(".zip"):
        path = Path(_policy_path(spec, directory))
        if not path.is_file():
            raise SweepError(f"{source}: {where}: policy file {str(path)!r} does not exist"
                             + (" (a relative path is taken from the suite's folder)" if not Path(spec).is_absolute()
                                else ""))
        return
    module, _, attr = spec.partition(":")
    if not module or not attr:
        raise SweepError(f"{source}: {where}: policy {spec!r}: give a stable-baselines3 .zip or "
                         f"package.module:callable")
    try:
        found = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        found = None
    if found is None:
        raise SweepError(f"{source}: {where}: policy {spec!r}: no module {module!r} on the Python path")


def _policy_path(spec: str, directory: Path | None) -> str:
    """A ``.zip`` relative to the suite's folder becomes absolute (the workers run elsewhere)."""
    if spec.endswith(".zip") and directory is not None and not Path(spec).is_absolute():
        return str((directory / spec).resolve())
    return spec


def describe(suite: Suite) -> str:
    """One line: the suite's size."""
    n = len(suite.plan.runs)
    return (f"{suite.source}: {len(suite.tasks)} tasks x {len(suite.conditions)} conditions x "
            f"{len(suite.vessels)} vessel(s) x {len(suite.controllers)} controllers, "
            f"{sorted(set(suite.episodes.values()))} episodes each: {n} episodes, all validated"
            + "".join(f"; {c} not on {t} ({why})" for t, c, why in suite.skipped))


__all__ = ["Suite", "ControllerEntry", "load_suite", "plan_suite", "default_suite_path", "describe"]
