"""Environment capability of the tracking controller, in the style of DNV-ST-0111.

DNV-ST-0111 draws, for each direction of the environment relative to the vessel, the largest
environment (wind speed, with the current and waves tied to it) in which a dynamic-positioning vessel
still keeps its position. Here the vessel tracks a path, and "keeps" means the criterion its
controller declares (:mod:`usv_mj.record.criteria`) holds: the run finishes ``ok`` and passes it (the sweep
row's ``passed``); for the paper's controller that is the funnel of docs/model.md §2, no sample with
|z_i| >= 1. For each direction, every ``--step`` degrees relative to the path's heading at t = 0
(going-to directions, counter-clockwise, as docs/sea.md §0), the largest load at which the
criterion holds is found by bisection between ``--min`` and ``--max``. A controller whose runs are
not judged (:class:`usv_mj.record.criteria.NotJudged`) has no capability: the command says so (exit 2).

Search: each round, every direction whose bracket [holds, fails] is still wider than ``--tol``
(relative to its upper end) gets m interior points, m = max(1, workers // open directions), all
submitted to Dask at once; the bracket shrinks by m + 1 a round (m = 1: bisection). Linear loads
are split evenly, the disturbance scale (which spans decades) geometrically. The search assumes the
criterion holds below some load and fails above it; a direction where a point held above a failing one
is flagged "not monotone" and the lowest failure is kept (the conservative answer).

Loads
-----
- ``disturbance``: s of docs/model.md §1 (``disturbance.scale``). The paper's d(t) acts on fixed body-frame
  axes (surge, sway, yaw) with fixed amplitudes: it has **no direction** to turn. So one search is
  done, on the scale alone, and the polar plot shows it as a circle; the table has one row marked
  "any direction". (Rotating the force would be a different disturbance than the paper's; we do not
  invent one.)
- ``current`` (``sea.current.speed`` m/s), ``wind`` (``sea.wind.speed`` m/s), ``waves``
  (``sea.waves.hs`` m), each with its direction set to path heading + relative direction, written as
  the going-to ``direction_deg`` (counter-clockwise from +x; it replaces the base's ``from_deg`` or
  ``toward_deg``, docs/sea.md §0):
  these need the sea-state keys (docs/sea.md) in the scenario format (a checkout whose
  :mod:`usv_mj.scenario.spec` does not accept them stops with exit code 2 and says so), and a plant
  that takes the sea state. A load of 0 is calm whatever its direction: it is run once.

Actuators: a capability plot is by definition the limit that the thrusters set. With a
base whose ``[actuators]`` limit the force (``--base paper-limited``: twin thrusters of a 2 m USV)
the search measures the vessel. With unlimited actuators (the ``paper`` presets) it measures only
the control law's arithmetic, which can ask for any force: the search still runs, but the figure,
``capability.md`` and ``capability.json`` (``actuators_unlimited``) say so, and the command prints
it.

A run that *fails* (raises, or its worker dies) is not an answer about the criterion: the search stops
with its reason (exit code 2), where a diverged run counts as the criterion lost.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from usv_mj.jobs.sweep.loads import LOADS, LoadKind  # noqa: F401 (the loads' table, named here too)
from usv_mj.jobs.sweep.spec import RunSpec, SweepError, load_base, apply_values


@dataclass
class DirectionResult:
    """The search in one direction: ``holds`` (largest load seen to keep the criterion), ``fails``
    (smallest seen not to), ``capability`` (= holds; None if even ``--min`` fails), and notes."""

    direction_deg: float | None
    holds: float | None = None
    fails: float | None = None
    notes: list = field(default_factory=list)
    runs: int = 0
    noun: str = "the criterion"  # what holds, in words ("the funnel")

    @property
    def capability(self) -> float | None:
        return self.holds

    def open(self, tol: float) -> bool:
        if self.holds is None or self.fails is None:
            return False
        return (self.fails - self.holds) > tol * self.fails


def path_heading_deg(scenario) -> float:
    """psi_d(0) of the scenario's reference in degrees: the direction 'along the path'."""
    from usv_mj.loop.simulate import make_reference

    return math.degrees(float(make_reference(scenario).evaluate(0.0)[2]))


def _interior(lo: float, hi: float, m: int, spacing: str) -> list[float]:
    if spacing == "log":
        a, b = math.log(lo), math.log(hi)
        return [math.exp(a + (b - a) * (i + 1) / (m + 1)) for i in range(m)]
    return [lo + (hi - lo) * (i + 1) / (m + 1) for i in range(m)]


class _Evaluator:
    """Runs (direction, load) points as sweep tasks on a Dask client and remembers every run."""

    def __init__(self, client, base, load: LoadKind, heading_deg: float, source: str, progress=None):
        self.client, self.base, self.load = client, base, load
        self.heading, self.source = heading_deg, source
        self.rows: list[dict] = []
        self.progress = progress

    def values(self, direction, value) -> dict:
        out = {self.load.path: float(value)}
        if self.load.direction_path is not None and direction is not None:
            out[self.load.direction_path] = float((self.heading + direction) % 360.0)
        return out

    def __call__(self, points: list[tuple]) -> dict:
        """``points``: (direction, load) pairs -> {(direction, load): row}."""
        from usv_mj.jobs.sweep.runner import gather_rows

        jobs = []
        keys = {}
        same = {}  # a zero load has no direction: one run stands for every direction
        for direction, value in points:
            canon = (None if value == 0 else direction, value)
            same.setdefault(canon, []).append((direction, value))
            if len(same[canon]) > 1:
                continue
            run_id = len(self.rows) + len(jobs)
            values = self.values(direction, value)
            scenario = apply_values(self.base, values, self.source)
            jobs.append((RunSpec(run_id, values, scenario), {"transient": 20.0}))
            keys[run_id] = canon
        out = {}

        def on_row(row):
            canon = keys[row["run_id"]]
            row["direction_deg"], row["load"] = same[canon][0]
            self.rows.append(row)
            for point in same[canon]:
                out[point] = row
            if self.progress is not None:
                self.progress.update(1)

        gather_rows(self.client, jobs, on_row, key_prefix="usv-capability")
        for (direction, value), row in out.items():
            if row["status"] == "failed":  # an error of the set-up, not an answer about the criterion
                where = "" if direction is None else f" toward {direction:g} deg"
                raise SweepError(f"{self.source}: the run with {self.load.path} = {value:g}{where} failed, so the "
                                 f"search cannot go on: {row['reason']}")
        return out


def search_capability(evaluate, directions: list, lo: float, hi: float, spacing: str, tol: float,
                      slots: int, max_rounds: int = 40, noun: str = "the criterion") -> list[DirectionResult]:
    """Parallel bisection / k-section of the largest load that keeps the criterion in each direction.

    ``evaluate(points)`` runs a list of (direction, load) and returns {(direction, load): row} with
    ``passed`` in each row. ``slots``: how many runs to have in flight a round (workers). ``noun``:
    the criterion in the notes ("the funnel").
    """
    results = {d: DirectionResult(d, noun=noun) for d in directions}
    first = [(d, lo) for d in directions] + [(d, hi) for d in directions]
    rows = evaluate(first)
    for d, res in results.items():
        res.runs += 2
        held_lo = bool(rows[(d, lo)]["passed"])
        held_hi = bool(rows[(d, hi)]["passed"])
        if not held_lo:
            res.fails = lo
            res.notes.append(f"{noun} does not hold even at the lower end {lo:g}")
        elif held_hi:
            res.holds = hi
            res.notes.append(f"{noun} holds at the upper end {hi:g}: the capability is at least that")
        else:
            res.holds, res.fails = lo, hi
    for _ in range(max_rounds):
        active = [r for r in results.values() if r.open(tol)]
        if not active:
            break
        m = max(1, slots // len(active))
        plan = {r.direction_deg: _interior(r.holds, r.fails, m, spacing) for r in active}
        rows = evaluate([(d, v) for d, vs in plan.items() for v in vs])
        for r in active:
            pts = plan[r.direction_deg]
            r.runs += len(pts)
            kept = [bool(rows[(r.direction_deg, v)]["passed"]) for v in pts]
            first_fail = next((i for i, k in enumerate(kept) if not k), None)
            if first_fail is None:
                r.holds = pts[-1]
            else:
                if any(kept[first_fail + 1:]):
                    above = pts[first_fail + 1 + kept[first_fail + 1:].index(True)]
                    r.notes.append(f"not monotone: held at {above:.4g} above a failure at {pts[first_fail]:.4g} "
                                   f"(the lower, conservative bracket is kept)")
                r.fails = pts[first_fail]
                if first_fail > 0:
                    r.holds = pts[first_fail - 1]
    else:
        for r in results.values():
            if r.open(tol):
                r.notes.append("bracket still open after the round limit")
    return [results[d] for d in directions]


UNLIMITED_NOTE = ("actuators UNLIMITED: this is the control law's limit, not the vessel's "
                  "(no thrust limit; see --base paper-limited)")


def draw_polar(results: list[DirectionResult], load: LoadKind, path: Path, title: str,
               note: str | None = None, noun: str = "the criterion") -> None:
    """The capability polar plot: radius = largest load that keeps the criterion (``noun``: "the
    funnel"), angle = direction relative to the path (0 = along the path, counter-clockwise, going-to)."""
    what = noun[4:] if noun.startswith("the ") else noun
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig = plt.figure(figsize=(5.8, 6.4))
    ax = fig.add_subplot(projection="polar")
    ax.set_theta_zero_location("N")
    if len(results) == 1 and results[0].direction_deg is None:
        r = results[0]
        theta = np.linspace(0, 2 * np.pi, 361)
        value = r.capability or 0.0
        ax.plot(theta, np.full_like(theta, value), color="tab:blue", lw=2, label=f"{what} holds: s <= {value:.3g}")
        if r.fails is not None:
            ax.plot(theta, np.full_like(theta, r.fails), color="tab:red", lw=1, ls="--",
                    label=f"{what} lost: s = {r.fails:.3g}")
        ax.set_rlim(0, (r.fails or value or 1.0) * 1.1)
        ax.text(0.5, -0.16, "d(t) acts on fixed body axes (docs/model.md §1): no direction, drawn as a circle",
                transform=ax.transAxes, ha="center", va="top", fontsize=8)
    else:
        theta = np.radians([r.direction_deg for r in results] + [results[0].direction_deg])
        caps = [r.capability or 0.0 for r in results]
        ax.plot(theta, caps + caps[:1], color="tab:blue", lw=2, label=f"{what} holds up to")
        bracketed = [i for i, r in enumerate(results) if r.fails is not None]
        open_top = [i for i, r in enumerate(results) if r.fails is None and r.holds is not None]
        ax.plot(theta[bracketed], [caps[i] for i in bracketed], ls="none", marker="o", ms=4, color="tab:blue")
        if open_top:
            ax.plot(theta[open_top], [caps[i] for i in open_top], ls="none", marker="^", ms=6, mfc="white",
                    color="tab:blue", label="held at the search's upper end (at least)")
        fails = [r.fails if r.fails is not None else np.nan for r in results]
        ax.plot(theta, fails + fails[:1], color="tab:red", lw=1, ls="--", label=f"{what} lost at")
        ax.text(0.5, -0.2, "angle: going-to direction relative to the path, counter-clockwise",
                transform=ax.transAxes, ha="center", va="top", fontsize=8)
    ax.set_title(title, fontsize=10, pad=18)
    if note:
        fig.text(0.5, 0.005, note, ha="center", va="bottom", fontsize=8, color="tab:red", wrap=True)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=2, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def run_capability(load_name: str, *, base: str = "paper", duration: float | None = None,
                   plant: str | None = None, step: float = 15.0, load_min: float | None = None,
                   load_max: float | None = None, tol: float = 0.05, out: str | Path = "capability",
                   scheduler: str | None = None, workers: int | None = None, client=None,
                   progress: bool = True, echo=print) -> list[DirectionResult]:
    """Find and draw the capability of ``load_name``; writes ``out/capability.{md,png,json}``.

    Raises :class:`SweepError` on bad input or a load the scenario format does not have yet.
    """
    echo = echo or (lambda s: None)
    if load_name not in LOADS:
        raise SweepError(f"--load must be one of {', '.join(sorted(LOADS))}, got {load_name!r}")
    load = LOADS[load_name]
    source = f"capability --load {load_name}"
    scenario = load_base(source, base, Path.cwd())
    fixed = {}
    if duration is not None:
        fixed["duration"] = duration
    if plant is not None:
        fixed["plant.kind"] = plant
    if fixed:
        scenario = apply_values(scenario, fixed, source)
    lo = load.default_min if load_min is None else float(load_min)
    hi = load.default_max if load_max is None else float(load_max)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise SweepError(f"{source}: need 0 <= --min < --max, got --min {lo!r}, --max {hi!r}")
    if load.spacing == "log" and lo <= 0:
        raise SweepError(f"{source}: the {load.name} search is geometric: --min must be > 0, got {lo!r}")
    if not (0 < tol < 1):
        raise SweepError(f"{source}: --tol must be in (0, 1), got {tol!r}")
    if not (0 < step <= 360):
        raise SweepError(f"{source}: --step must be in (0, 360] degrees, got {step!r}")
    probe = {load.path: hi}
    if load.direction_path:
        probe[load.direction_path] = 0.0
    probe = apply_values(scenario, probe, source)  # a bad base scenario or range stops here with its message
    criterion = _criterion(probe, source)
    directions = [None] if load.direction_path is None else [
        round(i * step, 9) for i in range(int(math.floor(360.0 / step + 1e-9)))]
    try:
        heading = path_heading_deg(scenario)
    except ValueError as exc:
        raise SweepError(f"{source}: the base's reference path cannot be built: {exc}") from None
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    from usv_mj.jobs.sweep.runner import describe_startup, open_client, warm_up, warm_workers

    bar = None
    t_start = time.perf_counter()
    # here first (a loop not in the disk cache yet is compiled once, not by every worker at once),
    # then on every worker before the first round: the start-up, said apart from the search
    startup = {"here": warm_up(probe), "cluster_s": 0.0}
    try:
        def search(cl):
            nonlocal bar
            startup["workers"] = warm_workers(cl, probe)
            startup["total_s"] = time.perf_counter() - t_start
            echo(describe_startup(startup))
            if progress:
                from tqdm import tqdm

                bar = tqdm(unit="run", desc=f"capability {load.name}", file=sys.stderr, dynamic_ncols=True)
            slots = max(1, sum(cl.nthreads().values()))
            evaluator = _Evaluator(cl, scenario, load, heading, source, bar)
            return evaluator, search_capability(evaluator, directions, lo, hi, load.spacing, tol, slots,
                                                noun=criterion.noun)

        if client is not None:
            evaluator, results = search(client)
        else:
            t_cluster = time.perf_counter()
            with open_client(scheduler, workers, echo) as cl:
                startup["cluster_s"] = time.perf_counter() - t_cluster
                evaluator, results = search(cl)
    finally:
        if bar is not None:
            bar.close()
    if scenario.actuators.unlimited:
        echo(f"note: {UNLIMITED_NOTE}")
    _write_outputs(out, results, load, scenario, heading, lo, hi, tol, evaluator.rows, criterion)
    return results


def _criterion(scenario, source: str):
    """The criterion the base's controller declares; one its runs are not judged by has no capability."""
    from usv_mj.builder import make_controller
    from usv_mj.record.criteria import criterion_of

    criterion = criterion_of(make_controller(scenario))
    if criterion.kind == "not_judged":
        raise SweepError(f"{source}: the {scenario.controller.kind} controller's runs are {criterion.describe()}: "
                         f"there is no criterion whose largest load could be searched")
    return criterion


def _write_outputs(out, results, load, scenario, heading, lo, hi, tol, rows, criterion=None):
    criterion = criterion or _criterion(scenario, f"capability --load {load.name}")
    title = (f"capability: {load.label}\n{scenario.preset}, {scenario.controller.kind}, "
             f"{scenario.duration:g} s, {scenario.plant.kind} plant")
    unlimited = scenario.actuators.unlimited
    draw_polar(results, load, out / "capability.png", title, UNLIMITED_NOTE if unlimited else
               f"actuators: {scenario.actuators.describe()}", noun=criterion.noun)
    noun = criterion.noun[:1].upper() + criterion.noun[1:]
    what = criterion.noun[4:] if criterion.noun.startswith("the ") else criterion.noun
    if criterion.kind == "funnel":  # the paper's words
        holds = "The funnel holds when a run finishes ok with every |z_i| < 1 throughout."
    else:
        holds = f"{noun} holds when a run finishes ok and {criterion.describe()}."
    unit = f" [{load.unit}]" if load.unit else ""
    lines = [f"# Capability: {load.label}", "",
             f"Base `{scenario.preset}`, controller `{scenario.controller.kind}`, plant `{scenario.plant.kind}`, "
             f"runs of {scenario.duration:g} s. {holds} "
             f"Search between {lo:g} and {hi:g}, to {tol:.0%} (see `usv_mj.jobs.sweep.capability`).", ""]
    if unlimited:
        lines += ["**The actuators are unlimited** (`[actuators] kind = \"unlimited\"`, as in the paper): the "
                  "controller may ask for any force, so this is the limit of the control law's arithmetic, "
                  "not of a vessel; a capability plot in the DNV sense needs thrust limits "
                  "(`--base paper-limited`).", ""]
    else:
        lines += [f"Actuators: {scenario.actuators.describe()}.", ""]
    if load.direction_path is None:
        lines += ["The paper's d(t) acts on fixed body-frame axes (docs/model.md §1): it has no direction, so the "
                  "search is on its scale alone and the polar plot draws one circle.", ""]
    else:
        lines += [f"Directions are going-to, relative to the path heading psi_d(0) = {heading:.1f} deg, "
                  f"counter-clockwise.", ""]
    lines += [f"| direction [deg] | {what} holds up to{unit} | {what} lost at{unit} | runs | notes |",
              "| --- | --- | --- | --- | --- |"]
    for r in results:
        d = "any direction" if r.direction_deg is None else f"{r.direction_deg:g}"
        lines.append(f"| {d} | {'-' if r.holds is None else f'{r.holds:.4g}'} | "
                     f"{'-' if r.fails is None else f'{r.fails:.4g}'} | {r.runs} | {'; '.join(r.notes)} |")
    lines += ["", "![capability polar](capability.png)", ""]
    (out / "capability.md").write_text("\n".join(lines))
    (out / "capability.json").write_text(json.dumps({
        "load": load.name, "path": load.path, "direction_path": load.direction_path, "unit": load.unit,
        "min": lo, "max": hi, "tol": tol, "path_heading_deg": heading,
        "actuators_unlimited": unlimited, "actuators": scenario.actuators.describe(),
        "criterion": {"kind": criterion.kind, "description": criterion.describe()},
        "results": [{"direction_deg": r.direction_deg, "holds": r.holds, "fails": r.fails, "runs": r.runs,
                     "notes": r.notes} for r in results],
        "runs": [{k: row.get(k) for k in ("direction_deg", "load", "status", "reason", "passed",
                                          "criterion.violations", "criterion.first_violation_s")} for row in rows],
    }, indent=1))
