"""The leaderboard of a benchmark: ``report.md``, ``leaderboard.json`` and ``figures/``.

- One table per task and condition (and vessel, when the suite names vessels): controllers as rows,
  the metrics of :data:`usv_mj.jobs.bench.metrics.METRICS` that the task measured as columns, each cell
  the mean over episodes with its 95 % interval (:func:`usv_mj.jobs.bench.metrics.estimate`), a time
  to an event (settling, time to the goal) as the share that reached it and its median with the
  others censored (:func:`usv_mj.jobs.bench.metrics.estimate_event`, never a mean); the best of each
  column in bold (the metric's direction: lower or higher is better). An episode that is not ok
  (diverged or failed) counts with the metric's worst value (:func:`scored`; for a time to an event:
  not reached), never with its metrics up to the divergence, which would rank a diverging controller first. The criterion column is each
  controller's own promise: bold only when every controller of the table is judged by the same one.
- The summary ranking: in every table and every ranked metric (:data:`RANKED`: metrics that mean the
  same for every controller, so not the criterion, which differs between them) the controllers are
  ranked 1..n by their means (medians for a time to an event, "not reached" last; ties share the
  lower rank); a controller's score is its mean rank over all of them, and its wins the number of
  (table, metric) it is best in. The criteria are shown apart (:func:`criteria_table`).
- Figures: ``heatmap.png`` (controller x task/condition, the mean normalised score over the ranked
  metrics, 1 = the best of the table, 0 = the worst), ``bars-<task>.png`` (each condition, four key
  metrics, bars with the intervals), ``worst-episodes.png`` (each controller's worst episode, the one
  with the largest mean |e_ct| = IAE / duration over the suite, run again here and drawn against
  its reference).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from usv_mj.jobs.bench.episode import PREFIX
from usv_mj.jobs.bench.metrics import BY_COLUMN, METRICS, estimate, estimate_event, wilson_ci, worst_value

RANKED = ("iae_cross_track", "iae_heading", "max_cross_track_after_settle", "settling_time_cross_track",
          "energy", "switches_per_s_u", "min_clearance_m", "contact", "goal_reached", "time_to_goal_s")
"""The metrics of the summary ranking and the heat map (one of each kind of quality): each means the
same for every controller (the same formula, band and goal), so ``passed``, which judges each by
its own criterion, is not among them."""
TABLE = ("iae_cross_track", "ise_cross_track", "iae_heading", "max_cross_track_after_settle",
         "max_heading_after_settle", "settling_time_cross_track", "effort_u", "effort_r", "energy",
         "switches_per_s_u", "switches_per_s_r", "total_variation_u", "saturation_fraction", "passed",
         "min_clearance_m", "contact", "goal_reached", "time_to_goal_s")
"""The columns of a task's table (those the task measured); every metric is in leaderboard.json."""
BARS = ("iae_cross_track", "iae_heading", "energy", "passed")


def group_key(row: dict) -> tuple:
    return (row["vary.task"], row["vary.condition"], row.get("vary.vessel") or "default")


def table_name(key: tuple, vessels: bool) -> str:
    return f"{key[0]} / {key[1]}" + (f" / {key[2]}" if vessels else "")


def scored(row: dict, column: str, measured: bool):
    """The value ``row`` counts with in ``column`` of the leaderboard: its own metric when its
    status is ok; otherwise (diverged or failed) the metric's worst value (+-inf, or a rate's bad
    outcome: :func:`usv_mj.jobs.bench.metrics.worst_value`) when its table ``measured`` the metric
    (some episode of the table has a value), else None (not measured)."""
    if row["status"] == "ok":
        return row.get(PREFIX + column)
    return worst_value(column) if measured else None


def aggregate(rows: list[dict]) -> dict:
    """``{(task, condition, vessel): {controller: {metric: Estimate, "_ok": (ok, n)}}}`` in row order;
    an episode that is not ok counts with the worst value of every metric its table measured
    (:func:`scored`), so a controller that diverged ranks last on the continuous metrics."""
    out: dict = {}
    for row in rows:
        out.setdefault(group_key(row), {}).setdefault(row["vary.controller"], []).append(row)
    agg = {}
    for key, by_ctrl in out.items():
        agg[key] = {}
        measured = {m.column for m in METRICS
                    if any(r.get(PREFIX + m.column) is not None for rs in by_ctrl.values() for r in rs)}
        for ctrl, rs in by_ctrl.items():
            cell = {m.column: _estimate(m, rs, m.column in measured) for m in METRICS}
            cell["_ok"] = (sum(r["status"] == "ok" for r in rs), len(rs))
            cell["_criterion"] = _criterion_words(rs)
            agg[key][ctrl] = cell
    return agg


def _estimate(m, rs: list[dict], measured: bool):
    """A metric of a controller's episodes in a table: :func:`estimate_event` for a time to an event
    (an episode that is not ok did not reach it), else :func:`estimate` of each episode's value as
    :func:`scored` counts it (``measured``: some episode of the table has a value)."""
    if not m.reached:
        return estimate(m.column, [scored(r, m.column, measured) for r in rs])
    flags = [None if r.get(PREFIX + m.reached) is None else bool(r[PREFIX + m.reached]) and r["status"] == "ok"
             for r in rs]
    return estimate_event([r.get(PREFIX + m.column) for r in rs], flags)


def _criterion_words(rs: list[dict]) -> str:
    """The criterion a controller's episodes were judged by (its words from the rows)."""
    seen = sorted({str(r.get("criterion.description") or r.get("criterion.kind") or "") for r in rs} - {""})
    return " / ".join(seen)


def _best(cells: dict, column: str):
    """The controllers with the best mean of ``column`` (none when fewer than two measured it, and for
    the criterion none unless every controller of the table is judged by the same one); a time to an
    event not reached by the median episode is an infinite median, last."""
    means = {c: v[column].mean for c, v in cells.items() if v[column].n and not math.isnan(v[column].mean)}
    if column == "passed" and len({cells[c].get("_criterion", "") for c in means}) > 1:
        return set(), means
    if len(means) < 2 or len(set(means.values())) < 2:
        return set(), means
    pick = min if BY_COLUMN[column].better == "lower" else max
    best = pick(means.values())
    return {c for c, m in means.items() if m == best}, means


def ranking(agg: dict) -> dict:
    """``{controller: {"mean_rank", "wins", "ranked"}}`` over every table and ranked metric."""
    ranks: dict = {}
    wins: dict = {}
    for cells in agg.values():
        for column in RANKED:
            best, means = _best(cells, column)
            if not best:
                continue
            sign = 1.0 if BY_COLUMN[column].better == "lower" else -1.0
            ordered = sorted(means.values(), key=lambda v: sign * v)
            for c, m in means.items():
                ranks.setdefault(c, []).append(1 + ordered.index(m))
                wins[c] = wins.get(c, 0) + (c in best)
    return {c: {"mean_rank": float(np.mean(r)), "wins": wins.get(c, 0), "ranked": len(r)} for c, r in ranks.items()}


def ranking_by(agg: dict, index: int) -> dict:
    """``{value: ranking(...)}``: the summary ranking over the tables whose key[index] (0 task, 1
    condition, 2 vessel) is each value, in first-seen order."""
    values = list(dict.fromkeys(k[index] for k in agg))
    return {v: ranking({k: c for k, c in agg.items() if k[index] == v}) for v in values}


def by_table(by: dict, controllers: list, what: str) -> list[str]:
    """The mean rank of each controller (columns) per task or vessel (rows), the best in bold."""
    ctrls = [c for c in controllers if any(c in r for r in by.values())]
    lines = [f"| {what} | " + " | ".join(f"`{c}`" for c in ctrls) + " |", "| --- |" + " --- |" * len(ctrls)]
    for value, rank in by.items():
        best = min((r["mean_rank"] for r in rank.values()), default=None)
        cells = []
        for c in ctrls:
            if c not in rank:
                cells.append("-")
                continue
            text = f"{rank[c]['mean_rank']:.2f}"
            cells.append(f"**{text}**" if rank[c]["mean_rank"] == best else text)
        lines.append(f"| {value} | " + " | ".join(cells) + " |")
    return lines


def criteria_table(agg: dict, controllers: list) -> list[str]:
    """Each controller's own criterion and the share of its episodes that kept it over the suite,
    with Wilson's interval: shown apart from the ranking, a rate comparable only between controllers
    judged by the same criterion (markdown)."""
    lines = ["| controller | criterion (its own) | kept | 95 % interval |", "| --- | --- | --- | --- |"]
    for ctrl in controllers:
        cells = [t[ctrl] for t in agg.values() if ctrl in t]
        if not cells:
            continue
        k = sum(round(c["passed"].mean * c["passed"].n) for c in cells if c["passed"].n)
        n = sum(c["passed"].n for c in cells)
        words = " / ".join(sorted({c.get("_criterion", "") for c in cells} - {""})) or "-"
        if n:
            lo, hi = wilson_ci(k, n)
            lines.append(f"| `{ctrl}` | {words} | {k}/{n} | [{100 * lo:.0f}, {100 * hi:.0f}] % |")
        else:
            lines.append(f"| `{ctrl}` | {words} | not judged | - |")
    return lines


def printed_leaderboard(agg: dict, controllers: list, vessels: bool) -> list[str]:
    """What ``usv-mj bench`` prints at the end (and report.md opens with): the summary ranking,
    then the mean rank per task and, with vessels, per vessel, then each controller's own criterion
    apart (markdown). With fewer than two controllers there is nothing to rank: one sentence says so
    instead of empty tables."""
    present = [c for c in controllers if any(c in cells for cells in agg.values())]
    if len(present) < 2:
        who = f"one controller (`{present[0]}`)" if present else "no controller"
        return [f"The suite scores {who}: a ranking compares two or more, so there is none; its metrics are in "
                f"the tables of each task (report.md, leaderboard.json)."]
    lines = summary_table(ranking(agg))
    lines += ["", "Mean rank per task (over its conditions" + (" and vessels" if vessels else "")
              + "; lower is better, the best in bold):", ""] + by_table(ranking_by(agg, 0), controllers, "task")
    if vessels:
        lines += ["", "Mean rank per vessel (over the tasks and conditions):", ""] \
            + by_table(ranking_by(agg, 2), controllers, "vessel")
    lines += ["", "Each controller's own criterion over all its episodes (not ranked: a rate compares only "
              "controllers judged by the same criterion):", ""] + criteria_table(agg, controllers)
    return lines


def normalised_scores(agg: dict) -> dict:
    """``{key: {controller: score}}``: per table, the mean over the ranked metrics of
    (worst - value) / (worst - best) over the finite means (1 = the table's best, 0 = its worst); an
    infinite mean (an episode not ok: the worst value) scores 0, and the finite means then span
    1 (best) to 0 (worst finite), or are all 1 when they are equal."""
    out = {}
    for key, cells in agg.items():
        scores: dict = {c: [] for c in cells}
        for column in RANKED:
            best, means = _best(cells, column)
            if not best:
                continue
            values = list(means.values())
            if not all(math.isfinite(v) for v in values):   # a time not reached (inf): by rank instead
                sign = 1.0 if BY_COLUMN[column].better == "lower" else -1.0
                distinct = sorted(set(values), key=lambda v: sign * v)
                for c, m in means.items():
                    scores[c].append(1.0 - distinct.index(m) / (len(distinct) - 1))
                continue
            lo, hi = min(values), max(values)
            for c, m in means.items():
                if not math.isfinite(m):
                    s = 0.0
                elif hi == lo:
                    s = 1.0
                else:
                    s = (hi - m) / (hi - lo) if BY_COLUMN[column].better == "lower" else (m - lo) / (hi - lo)
                scores[c].append(s)
        out[key] = {c: (float(np.mean(s)) if s else math.nan) for c, s in scores.items()}
    return out


def _fmt(v: float) -> str:
    if math.isinf(v):
        return "worst"   # an episode not ok counts with the worst value (aggregate)
    if not math.isfinite(v):
        return "-"
    a = abs(v)
    if a == 0:
        return "0"
    if a >= 1000 or a < 0.01:
        return f"{v:.3g}"
    return f"{v:.3g}" if a < 100 else f"{v:.0f}"


def cell_text(e, rate: bool) -> str:
    if not e.n:
        return "-"
    if e.reached is not None:   # a time to an event: reached of n, median [interval], > T where censored
        def t(v):
            return "> T" if math.isinf(v) else _fmt(v)

        return f"{e.reached}/{e.n}: {t(e.mean)} [{t(e.lo)}, {t(e.hi)}]"
    if math.isinf(e.mean):
        return "worst (not ok)"
    if rate:
        return f"{100 * e.mean:.0f} % [{100 * e.lo:.0f}, {100 * e.hi:.0f}]"
    return f"{_fmt(e.mean)} [{_fmt(e.lo)}, {_fmt(e.hi)}]"


def task_table(cells: dict, controllers: list) -> list[str]:
    """The markdown lines of one task's table (the columns it measured)."""
    columns = [c for c in TABLE if any(cells[k][c].n for k in cells)]
    head = ["controller", "ok"] + [f"{BY_COLUMN[c].label}" + (f" [{BY_COLUMN[c].unit}]" if BY_COLUMN[c].unit else "")
                                   + (" ↓" if BY_COLUMN[c].better == "lower" else " ↑") for c in columns]
    lines = ["| " + " | ".join(head) + " |", "| " + " | ".join(["---"] * len(head)) + " |"]
    best = {c: _best(cells, c)[0] for c in columns}
    for ctrl in controllers:
        if ctrl not in cells:
            continue
        v = cells[ctrl]
        ok, n = v["_ok"]
        row = [f"`{ctrl}`", f"{ok}/{n}"]
        for c in columns:
            text = cell_text(v[c], BY_COLUMN[c].rate)
            row.append(f"**{text}**" if ctrl in best[c] else text)
        lines.append("| " + " | ".join(row) + " |")
    return lines


def summary_table(rank: dict) -> list[str]:
    lines = ["| rank | controller | mean rank | wins | ranked (table, metric) pairs |", "| --- | --- | --- | --- | --- |"]
    for i, (c, r) in enumerate(sorted(rank.items(), key=lambda kv: (kv[1]["mean_rank"], -kv[1]["wins"]))):
        lines.append(f"| {i + 1} | `{c}` | {r['mean_rank']:.2f} | {r['wins']} | {r['ranked']} |")
    return lines


def glance_table(agg: dict, scores: dict, controllers: list, vessels: bool) -> list[str]:
    """Tables as rows, controllers as columns: the normalised score (the heat map's, best in bold),
    the mean IAE of the cross-track error and the share of episodes that passed the criterion."""
    ctrls = [c for c in controllers if any(c in cells for cells in agg.values())]
    lines = ["| task / condition | " + " | ".join(f"`{c}`" for c in ctrls) + " |",
             "| --- |" + " --- |" * len(ctrls)]
    for key, cells in agg.items():
        sc = {c: v for c, v in scores[key].items() if math.isfinite(v)}
        top = max(sc.values()) if sc else None
        row = [table_name(key, vessels)]
        for c in ctrls:
            if c not in cells:
                row.append("-")
                continue
            v = cells[c]
            score = f"{scores[key][c]:.2f}" if math.isfinite(scores[key].get(c, math.nan)) else "-"
            if top is not None and c in sc and sc[c] == top:
                score = f"**{score}**"
            passed = "-" if not v["passed"].n else f"{100 * v['passed'].mean:.0f} %"
            row.append(f"{score} (IAE {_fmt(v['iae_cross_track'].mean)}, {passed})")
        lines.append("| " + " | ".join(row) + " |")
    return lines


def write_report(out: str | Path, rows: list[dict], suite, draw: bool = True) -> Path:
    """``out/report.md``, ``out/leaderboard.json`` and the figures of ``out/figures/``; returns report.md."""
    out = Path(out)
    figures = out / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    controllers = [c.name for c in suite.controllers]
    vessels = suite.vessels != [""]
    agg = aggregate(rows)
    rank = ranking(agg)
    scores = normalised_scores(agg)
    n_ep = sorted(set(suite.episodes.values()))
    failed = [r for r in rows if r["status"] != "ok"]
    lines = [f"# Benchmark `{suite.name}`", "",
             f"Suite `{suite.source}`: {len(suite.tasks)} tasks x {len(suite.conditions)} conditions"
             + (f" x {len(suite.vessels)} vessels" if vessels else "") + f" x {len(controllers)} controllers, "
             f"{'/'.join(map(str, n_ep))} episodes each: {len(rows)} episodes, {len(failed)} not ok "
             f"(diverged or failed). An episode not ok counts with the worst value of every metric (a rate: "
             f"not passed, contact, goal not reached; a time to an event: not reached; any other metric: the cell "
             f"says 'worst' and the controller ranks last on it), not with its metrics up to the divergence. "
             f"Each cell: the mean over the episodes, [its 95 % interval] (percentile "
             f"bootstrap; Wilson for the rates); a time to an event (settling, time to goal) as reached/episodes: "
             f"the median [its distribution-free 95 % interval], the episodes that did not reach it censored at "
             f"their end (> T), never averaged; the best of each column in bold (the criterion only among "
             f"controllers judged by the same one); ↓ lower is better, ↑ higher. Metrics and statistics: "
             f"docs/metrics.md.", "", "## Summary ranking", "",
             f"Mean rank of each controller over every table and the ranked metrics ({', '.join(RANKED)}: each "
             f"means the same for every controller; the criteria, which differ, are shown apart below); "
             f"wins: the (table, metric) pairs it is best in.", ""]
    lines += printed_leaderboard(agg, controllers, vessels)
    if getattr(suite, "skipped", None):
        lines += ["", "Not scored: " + "; ".join(f"`{c}` on `{t}` ({why})" for t, c, why in suite.skipped) + "."]
    lines += ["", "### At a glance", "", "Each cell: the normalised score of the heat map (1 = the best of the "
              "table on every ranked metric, 0 = the worst; the best in bold), (the mean IAE of the cross-track "
              "error [m s], the share of episodes that passed the controller's own criterion).", ""]
    lines += glance_table(agg, scores, controllers, vessels)
    lines += ["", "![normalised scores](figures/heatmap.png)", ""]
    tasks_seen = []
    for key, cells in agg.items():
        if key[0] not in tasks_seen:
            tasks_seen.append(key[0])
            lines += [f"## Task `{key[0]}`", "", f"![bars](<figures/bars-{key[0]}.png>)", ""]
        lines += [f"### {table_name(key, vessels)}", ""] + task_table(cells, controllers) + [""]
    if draw:
        lines += ["## Worst episodes", "", "Each controller's episode with the largest mean cross-track error "
                  "(IAE / duration), run again and drawn against its reference.", "",
                  "![worst episodes](figures/worst-episodes.png)", ""]
    if failed:
        lines += ["## Episodes not ok", "", "| run | task | condition | controller | episode | status | reason |",
                  "| --- | --- | --- | --- | --- | --- | --- |"]
        for r in failed[:50]:
            lines.append(f"| {r['run_id']} | {r['vary.task']} | {r['vary.condition']} | {r['vary.controller']} | "
                         f"{r['vary.episode']} | {r['status']} | {(r.get('reason') or '').replace('|', '/')[:160]} |")
        lines.append("")
    (out / "report.md").write_text("\n".join(lines))
    (out / "leaderboard.json").write_text(json.dumps({
        "suite": suite.source, "name": suite.name, "ranking": rank,
        "tables": [{"task": k[0], "condition": k[1], "vessel": k[2],
                    "controllers": {c: {**{m: {"mean": _j(e.mean), "lo": _j(e.lo), "hi": _j(e.hi), "n": e.n,
                                               **({"reached": e.reached} if e.reached is not None else {})}
                                           for m, e in v.items() if not m.startswith("_")},
                                        "ok": v["_ok"][0], "episodes": v["_ok"][1], "criterion": v["_criterion"]}
                                    for c, v in cells.items()},
                    "normalised_score": {c: _j(s) for c, s in scores[k].items()}} for k, cells in agg.items()],
    }, indent=1))
    if draw:
        from usv_mj.jobs.bench.figures import draw_bars, draw_heatmap, draw_worst

        draw_heatmap(scores, controllers, vessels, figures / "heatmap.png")
        for task in tasks_seen:
            draw_bars({k: v for k, v in agg.items() if k[0] == task}, controllers, BARS, vessels,
                      figures / f"bars-{task}.png", task)
        draw_worst(rows, suite, figures / "worst-episodes.png")
    return out / "report.md"


def _j(v):
    return v if isinstance(v, (int, float)) and math.isfinite(v) else None
