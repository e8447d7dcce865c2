"""Sweep files: a base scenario and what varies, sampled once on the client and validated.

A sweep file is TOML::

    base = "paper"              # a preset name, or a scenario file (relative to the sweep file)
    duration = 60.0             # s, optional: overrides the base's
    plant = "analytic"          # optional: "analytic" | "mujoco"
    samples = 200               # draws of the distributions for each point of the grid (default 1)
    seed = 7                    # np.random.default_rng(seed) draws every value (default 0)
    transient = 20.0            # s; errors after it feed the report's histograms (default 20)
    [set]                       # optional fixed overrides, by dotted path
    "controller.k1" = 3.0
    [vary]
    "initial.eta[0]" = { uniform = [-8.0, 8.0] }       # one element of a list
    "disturbance.scale" = [1e-4, 5e-4, 1e-3]           # a list is a grid axis
    "quantizer.u_min_u" = { loguniform = [1e-3, 1e-1] }

Paths
-----
A path is a dotted key into the scenario table of docs/model.md §7, with ``[i]`` for one element of a list
(``initial.eta[2]``, ``trajectory.points[1][0]``). Every key of the scenario format can vary:
``duration``, ``control_period``; ``initial.eta[0..2]`` (x m, y m, psi rad), ``initial.nu[0..2]``
(u m/s, v m/s, r rad/s); ``trajectory.kind|speed|heading_deg|radius|start[i]|center[i]|...``;
``disturbance.scale`` (s of docs/model.md §1) and ``disturbance.amplitudes[i]``...; ``ship.<parameter>``;
``quantizer.enabled|delta_u|u_min_u|delta_r|u_min_r``; ``funnel.rho_xy[0|1]``, ``funnel.rho_psi[0|1]``,
``funnel.rate``; ``plant.kind|substeps``; ``controller.kind`` and every PPC gain by its docs/model.md §3
name (``controller.k1``, ``controller.gamma_u``, ...); ``baseline.<PI gain>``; ``limits.*``; and the
sea state's ``sea.waves.hs|tp|gamma|from_deg|seed``, ``sea.current.speed|toward_deg|sigma``,
``sea.wind.speed|from_deg|gust_sigma`` (docs/sea.md; the old ``direction_deg`` still works). A path
the scenario does not know is rejected by :mod:`usv_mj.scenario.spec` itself, with its message (and its
"did you mean").

Distributions (one key in an inline table):

- ``{ uniform = [a, b] }``: uniform on [a, b), a < b;
- ``{ loguniform = [a, b] }``: exp(uniform(ln a, ln b)), 0 < a < b;
- ``{ normal = [mean, std] }``: std > 0;
- ``{ integers = [a, b] }``: integers a..b inclusive;
- ``{ choice = [v1, v2, ...] }``: one of the values, equally likely.

A plain list is a grid axis: the runs are the product of all grid axes (first axis slowest) times
``samples`` draws each. Run ids are ``grid_index * samples + sample_index``. All distributions are
drawn at once, in the order of the file, as vectors of length n_runs from
``np.random.default_rng(seed)``: the same file gives the same runs on any machine.

Validation
----------
Before anything is submitted, every sampled scenario is built by :func:`usv_mj.scenario.spec.from_dict`
(and for uniform / loguniform / integers both ends of the range too, so that a range that reaches
outside a key's domain is reported even if no draw happened to land there), and the reference path
of every distinct trajectory is built once. Any problem raises
:class:`SweepError` (a ``ValueError``) whose message names the sweep file, the path and the value;
the CLI turns it into exit code 2.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import hashlib
import itertools
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from usv_mj.scenario.spec import KIND_DEFAULTS, Scenario, ScenarioError, from_dict, load_scenario, preset_names, switched_kind
from usv_mj.support.toml_values import read_toml
from usv_mj.physics.sea.settings import replace_direction

DISTRIBUTIONS = ("uniform", "loguniform", "normal", "integers", "choice")
TOP_KEYS = ("base", "duration", "plant", "samples", "seed", "transient", "set", "vary", "name")
TEST_HOOKS_ENV = "USV_MJ_SWEEP_TEST_HOOKS"
"""When this environment variable is "1", a sweep file may carry ``test_hooks = { raise = [ids],
exit_worker = [ids], hold = [ids] }``: the runs with those ids raise / kill their worker process /
wait for a file (tests only; see :func:`usv_mj.jobs.sweep.runner.run_one`)."""

_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_PART = re.compile(rf"({_NAME})((?:\[\d+\])*)")


from usv_mj.core.errors import SweepError  # noqa: E402  (one error family: a ScenarioError)


# --- paths ----------------------------------------------------------------------------------------


def parse_path(path: str) -> tuple:
    """``"initial.eta[0]"`` -> ``("initial", "eta", 0)``; raise :class:`SweepError` on a malformed path."""
    if not isinstance(path, str) or not path:
        raise SweepError(f"a path must be a non-empty string, got {path!r}")
    out: list = []
    for part in path.split("."):
        m = _PART.fullmatch(part)
        if m is None:
            raise SweepError(f"path {path!r} is malformed at {part!r}: use dotted names with [index] for a "
                             f"list element, e.g. 'initial.eta[0]' or 'disturbance.scale'")
        out.append(m.group(1))
        out.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    return tuple(out)


def _dataclass_value(scenario: Scenario, keys: tuple) -> Any:
    """The scenario's value at ``keys`` by attribute (controller / baseline gains sit in ``.gains``)."""
    obj: Any = scenario
    for key in keys:
        if isinstance(key, int):
            obj = obj[key]
        elif hasattr(obj, key):
            obj = getattr(obj, key)
        elif hasattr(obj, "gains") and hasattr(obj.gains, key):
            obj = getattr(obj.gains, key)
        else:
            raise KeyError(key)
    return obj


def _plain(value):
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


def set_path(data: dict, keys: tuple, value: Any, scenario: Scenario, path: str, source: str) -> None:
    """Set ``value`` at ``keys`` in the nested TOML table ``data`` (in place).

    A list that the table does not hold yet (an element of a default value) is copied from the
    scenario's dataclass first, so ``initial.nu[1]`` works on a preset that leaves ``nu`` out.
    """
    node: Any = data
    for i, key in enumerate(keys[:-1]):
        nxt = keys[i + 1]
        if isinstance(key, int):
            if not isinstance(node, list) or key >= len(node):
                raise SweepError(f"{source}: path {path!r}: index [{key}] is out of range "
                                 f"(the list has {len(node) if isinstance(node, list) else 0} elements)")
            node = node[key]
            continue
        if not isinstance(node, dict):
            raise SweepError(f"{source}: path {path!r}: {'.'.join(map(str, keys[:i]))} is not a table")
        if key not in node:
            if isinstance(nxt, int):
                try:
                    node[key] = copy.deepcopy(_plain(_dataclass_value(scenario, keys[: i + 1])))
                except (KeyError, AttributeError, IndexError, TypeError):
                    raise SweepError(f"{source}: path {path!r}: the scenario has no list at "
                                     f"{_join(keys[: i + 1])!r}") from None
            else:
                node[key] = {}
        elif isinstance(node[key], tuple):
            node[key] = list(node[key])
        node = node[key]
    last = keys[-1]
    if isinstance(last, int):
        if not isinstance(node, list):
            raise SweepError(f"{source}: path {path!r}: {_join(keys[:-1])!r} is not a list")
        if last >= len(node):
            raise SweepError(f"{source}: path {path!r}: index [{last}] is out of range "
                             f"({_join(keys[:-1])!r} has {len(node)} elements)")
        node[last] = value
    else:
        if not isinstance(node, dict):
            raise SweepError(f"{source}: path {path!r}: {_join(keys[:-1])!r} is not a table")
        if len(keys) == 3 and keys[0] == "sea":  # a direction replaces the base's, whatever its spelling
            kept = replace_direction(keys[1], node, last)
            for gone in set(node) - set(kept):
                del node[gone]
        node[last] = value


def _join(keys: tuple) -> str:
    out = ""
    for k in keys:
        out += f"[{k}]" if isinstance(k, int) else (("." if out else "") + k)
    return out


def _is_kind(keys: tuple) -> bool:
    """The path of a section's ``kind`` whose other keys belong to it (``controller.kind``, ...)."""
    return len(keys) == 2 and keys[1] == "kind" and keys[0] in KIND_DEFAULTS


def apply_values(base: Scenario, values: dict, source: str) -> Scenario:
    """``base`` with each ``path: value`` of ``values`` set, built and validated again. A path that
    switches a section's kind (``controller.kind = "los"`` on a base whose controller is ``ppc``)
    takes the new kind's keys only, as the scenario loader does for a preset.

    Raises :class:`SweepError` naming the sweep file, the path(s) and the value(s) if the scenario
    rejects the result.
    """
    data = copy.deepcopy(base.raw)
    parsed = {path: parse_path(path) for path in values}
    # a kind first: switching it drops the old kind's keys (usv_mj.scenario.spec.switched_kind, the
    # loader's own rule), then the values for the new kind are set
    for path in sorted(values, key=lambda p: not _is_kind(parsed[p])):
        keys = parsed[path]
        if _is_kind(keys) and isinstance(data.get(keys[0]), dict):
            try:
                data[keys[0]] = switched_kind(keys[0], data[keys[0]], values[path], base.source)
            except ScenarioError as exc:
                raise SweepError(f"{source}: {path} = {values[path]!r}: {exc}") from None
        set_path(data, keys, values[path], base, path, source)
    try:
        return from_dict(data, source=base.source)
    except ScenarioError as exc:
        shown = ", ".join(f"{p} = {v!r}" for p, v in values.items())
        raise SweepError(f"{source}: the scenario with {shown} is not valid: {exc}") from None


# --- the plan -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Axis:
    """One varied path: a grid axis (``values``) or a distribution (``kind``, ``args``)."""

    path: str
    kind: str  # "grid" or one of DISTRIBUTIONS
    args: tuple

    def describe(self) -> str:
        if self.kind == "grid":
            return f"grid {list(self.args)}"
        return f"{self.kind} {list(self.args)}"


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: its id, the varied values by path, the validated scenario, and options
    of its own for :func:`usv_mj.jobs.sweep.runner.run_one` (over the sweep's; a benchmark's episode
    function and metrics, :mod:`usv_mj.jobs.bench`)."""

    run_id: int
    values: dict
    scenario: Scenario = field(repr=False)
    options: dict = field(default_factory=dict, repr=False)


@dataclass
class SweepPlan:
    """Everything a sweep runs, sampled and validated on the client.

    Attributes
    ----------
    source: the sweep file.
    base: the base scenario with ``duration``, ``plant`` and ``[set]`` applied.
    axes: the varied paths in file order.
    runs: the runs in id order.
    samples, seed: as in the file.
    transient: s; the report's "after the transient" errors start here.
    test_hooks: {"raise": set of run ids, "exit_worker": set of run ids} (tests only).
    fingerprint: sha256 of the base table, the axes, the seed and every run's values: ``--resume``
        refuses results of another plan.
    """

    source: str
    base: Scenario
    axes: list
    runs: list
    samples: int
    seed: int
    transient: float
    name: str = ""
    test_hooks: dict = field(default_factory=dict)
    fingerprint: str = ""

    @property
    def paths(self) -> list[str]:
        return [a.path for a in self.axes]


def _number(source, where, value, *, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SweepError(f"{source}: {where} must be a finite number, got {value!r}")
    if integer and not isinstance(value, int):
        raise SweepError(f"{source}: {where} must be an integer, got {value!r}")
    return value


def parse_axis(source: str, path: str, spec: Any) -> Axis:
    """The ``[vary]`` entry ``path = spec`` as an :class:`Axis` (a list of values or a distribution
    table); SweepError naming ``source`` and the entry when it is malformed."""
    where = f"[vary] {path!r}"
    if isinstance(spec, list):
        if not spec:
            raise SweepError(f"{source}: {where}: a grid axis needs at least one value, got []")
        values = list(spec)
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            if any(isinstance(v, float) for v in values):
                values = [float(v) for v in values]
        return Axis(path, "grid", tuple(values))
    if not isinstance(spec, dict) or len(spec) != 1:
        raise SweepError(f"{source}: {where} must be a list (a grid axis) or a table with one of "
                         f"{', '.join(DISTRIBUTIONS)}, got {spec!r}")
    (kind, args), = spec.items()
    if kind not in DISTRIBUTIONS:
        hint = difflib.get_close_matches(kind, DISTRIBUTIONS, n=1)
        raise SweepError(f"{source}: {where}: unknown distribution {kind!r}"
                         + (f" (did you mean {hint[0]!r}?)" if hint else "")
                         + f"; distributions are {', '.join(DISTRIBUTIONS)}")
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise SweepError(f"{source}: {where}: choice needs a non-empty list of values, got {args!r}")
        return Axis(path, kind, tuple(args))
    if not isinstance(args, list) or len(args) != 2:
        raise SweepError(f"{source}: {where}: {kind} needs a list of two numbers, got {args!r}")
    a = _number(source, f"{where} {kind}[0]", args[0], integer=kind == "integers")
    b = _number(source, f"{where} {kind}[1]", args[1], integer=kind == "integers")
    if kind == "uniform" and not a < b:
        raise SweepError(f"{source}: {where}: uniform = [a, b] needs a < b, got [{a!r}, {b!r}]")
    if kind == "loguniform" and not 0 < a < b:
        raise SweepError(f"{source}: {where}: loguniform = [a, b] needs 0 < a < b, got [{a!r}, {b!r}]")
    if kind == "normal" and not b > 0:
        raise SweepError(f"{source}: {where}: normal = [mean, std] needs std > 0, got std = {b!r}")
    if kind == "integers" and not a <= b:
        raise SweepError(f"{source}: {where}: integers = [a, b] needs a <= b, got [{a!r}, {b!r}]")
    return Axis(path, kind, (a, b))


def draw_values(rng: np.random.Generator, axis: Axis, n: int) -> list:
    """``n`` values of the distribution axis ``axis`` drawn from ``rng``."""
    a = axis.args
    if axis.kind == "uniform":
        return [float(v) for v in rng.uniform(a[0], a[1], n)]
    if axis.kind == "loguniform":
        return [float(v) for v in np.exp(rng.uniform(math.log(a[0]), math.log(a[1]), n))]
    if axis.kind == "normal":
        return [float(v) for v in rng.normal(a[0], a[1], n)]
    if axis.kind == "integers":
        return [int(v) for v in rng.integers(a[0], a[1], n, endpoint=True)]
    idx = rng.integers(0, len(a), n)
    return [a[i] for i in idx]


def _range_ends(axis: Axis) -> list:
    if axis.kind in ("uniform", "loguniform", "integers"):
        return list(axis.args)
    if axis.kind == "normal":
        return [axis.args[0]]
    return list(axis.args)  # grid / choice: every value


def load_sweep(path: str | Path) -> SweepPlan:
    """Read, sample and validate a sweep file; see the module docstring for the format."""
    from usv_mj.support.example_files import resolve

    path = resolve(path, "sweeps")            # an example's name (quick) finds its file
    source = str(path)
    data = read_toml(path, SweepError, "sweep file")
    return plan_sweep(data, source=source, directory=path.parent)


def load_base(source: str, base: Any, directory: Path | None) -> Scenario:
    if not isinstance(base, str) or not base:
        raise SweepError(f"{source}: base must be a preset name or a scenario file, got {base!r}")
    candidate = Path(base) if directory is None else (directory / base)
    try:
        if base.endswith(".toml") or candidate.is_file():
            if not candidate.is_file():
                raise SweepError(f"{source}: base scenario file {str(candidate)!r} does not exist")
            return load_scenario(candidate)
        from usv_mj.support.example_files import find

        if base not in preset_names() and find(base, "scenarios") is not None:
            return load_scenario(find(base, "scenarios"))
        if base not in preset_names():
            hint = difflib.get_close_matches(base, preset_names(), n=1)
            raise SweepError(f"{source}: base {base!r} is neither a preset ({', '.join(preset_names())}) nor a "
                             f"scenario file" + (f" (did you mean {hint[0]!r}?)" if hint else ""))
        return load_scenario(preset=base)
    except ScenarioError as exc:
        raise SweepError(f"{source}: base {base!r}: {exc}") from None


def plan_sweep(data: dict, source: str = "<sweep>", directory: Path | None = None) -> SweepPlan:
    """Build the :class:`SweepPlan` of a sweep table (the parsed TOML): sample, then validate every run."""
    known = set(TOP_KEYS)
    hooks_allowed = os.environ.get(TEST_HOOKS_ENV) == "1"
    if hooks_allowed:
        known.add("test_hooks")
    for key in data:
        if key not in known:
            hint = difflib.get_close_matches(key, sorted(known), n=1)
            raise SweepError(f"{source}: unknown key {key!r}" + (f" (did you mean {hint[0]!r}?)" if hint else "")
                             + f"; known keys: {', '.join(sorted(known))}")
    base = load_base(source, data.get("base", "paper"), directory)
    if base.vessels:   # each run of a sweep is one vessel's simulate(); a fleet would be run as its first hull
        raise SweepError(f"{source}: base {data.get('base')!r} has [[vessels]] ({len(base.vessels)} vessels): a sweep "
                         f"runs one vessel per run, and several vessels in a sweep are not supported yet; sweep "
                         f"an encounter with usv-mj bench (a suite's imazu = [...] tasks) or run each variant with "
                         f"usv-mj run --scenario")
    fixed: dict = {}
    if "duration" in data:
        fixed["duration"] = _number(source, "duration", data["duration"])
    if "plant" in data:
        fixed["plant.kind"] = data["plant"]
    set_table = data.get("set", {})
    if not isinstance(set_table, dict):
        raise SweepError(f"{source}: [set] must be a table of path = value, got {set_table!r}")
    for p, v in set_table.items():
        parse_path(p)
        if isinstance(v, dict):
            raise SweepError(f"{source}: [set] {p!r} must be a value, got a table {v!r}; use dotted paths")
        fixed[p] = v
    if fixed:
        base = apply_values(base, fixed, source)
    samples = _number(source, "samples", data.get("samples", 1), integer=True)
    if samples < 1:
        raise SweepError(f"{source}: samples must be >= 1, got {samples!r}")
    seed = _number(source, "seed", data.get("seed", 0), integer=True)
    if seed < 0:
        raise SweepError(f"{source}: seed must be >= 0, got {seed!r}")
    transient = float(_number(source, "transient", data.get("transient", 20.0)))
    if transient < 0:
        raise SweepError(f"{source}: transient must be >= 0 s, got {transient!r}")
    name = data.get("name", "")
    if not isinstance(name, str):
        raise SweepError(f"{source}: name must be a string, got {name!r}")
    vary = data.get("vary", {})
    if not isinstance(vary, dict):
        raise SweepError(f"{source}: [vary] must be a table of path = list or distribution, got {vary!r}")
    axes = []
    for p, spec in vary.items():
        try:
            parse_path(p)
        except SweepError as exc:
            raise SweepError(f"{source}: [vary]: {exc}") from None
        axes.append(parse_axis(source, p, spec))
    # every value an axis can take, alone on the base: catches a bad path or a range outside a
    # key's domain before any sampling (the message names the path and the value)
    for axis in axes:
        for value in _range_ends(axis):
            try:
                apply_values(base, {axis.path: value}, source)
            except SweepError as exc:
                raise SweepError(f"{exc} (from [vary] {axis.path!r} = {axis.describe()})") from None
    grid = [a for a in axes if a.kind == "grid"]
    dists = [a for a in axes if a.kind != "grid"]
    points = list(itertools.product(*(a.args for a in grid))) or [()]
    n = len(points) * samples
    if n > 1_000_000:
        raise SweepError(f"{source}: {n} runs (grid {len(points)} x samples {samples}) is over 1e6: too many")
    rng = np.random.default_rng(seed)
    drawn = {a.path: draw_values(rng, a, n) for a in dists}
    runs = []
    for g, point in enumerate(points):
        for s in range(samples):
            run_id = g * samples + s
            values = {}
            for axis in axes:
                values[axis.path] = point[grid.index(axis)] if axis.kind == "grid" else drawn[axis.path][run_id]
            scenario = apply_values(base, values, source) if values else base
            runs.append(RunSpec(run_id, values, scenario))
    check_references(runs, source)
    hooks = {}
    if "test_hooks" in data:
        hooks = {k: set(int(i) for i in v) for k, v in data["test_hooks"].items()}
    plan = SweepPlan(source=source, base=base, axes=axes, runs=runs, samples=samples, seed=seed,
                     transient=transient, name=name, test_hooks=hooks)
    plan.fingerprint = _fingerprint(plan)
    return plan


def check_references(runs: list, source: str) -> None:
    """Build the reference path of every distinct (trajectory, duration) among ``runs``: the
    scenario format accepts some paths that :mod:`usv_mj.references.trajectories` refuses (a waypoint list of
    one point), and those must stop the sweep here, not fail every run on the workers."""
    from usv_mj.jobs.preflight import reference_error   # the same check usv-mj run makes before it starts

    seen = set()
    for run in runs:
        key = json.dumps([dataclasses.asdict(run.scenario.trajectory), run.scenario.duration], default=repr)
        if key in seen:
            continue
        seen.add(key)
        problem = reference_error(run.scenario)
        if problem is not None:
            shown = ", ".join(f"{p} = {v!r}" for p, v in run.values.items()) or "the base"
            raise SweepError(f"{source}: the reference path of run {run.run_id} ({shown}) cannot be built: "
                             f"{problem}")


def _fingerprint(plan: SweepPlan) -> str:
    doc = {
        "base": plan.base.raw, "axes": [dataclasses.asdict(a) for a in plan.axes], "seed": plan.seed,
        "samples": plan.samples, "transient": plan.transient,
        "runs": [[r.run_id, r.values] for r in plan.runs],
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=repr).encode()).hexdigest()
