"""Issue 38, cause 4: the leaderboard's handling of episodes that are not ok (diverged or failed).

Their metrics integrate only up to the divergence, so counted as they are they rank a controller
that blows up first. An episode that is not ok counts with the worst value of every metric its
table measured (usv_mj.jobs.bench.metrics.worst_value): +inf for a lower-is-better metric, a rate's
bad outcome. The numbers below are worked out by hand from the constructed results table."""

import math
import re
from types import SimpleNamespace

import pytest

from usv_mj.jobs.bench.metrics import wilson_ci, worst_value
from usv_mj.jobs.bench.report import RANKED, aggregate, normalised_scores, ranking, task_table, write_report

KEY = ("t", "calm", "default")


def _row(ctrl, ep, status, iae, energy, passed):
    return {"run_id": len(ctrl) * 10 + ep, "vary.task": "t", "vary.condition": "calm", "vary.vessel": "default",
            "vary.controller": ctrl, "vary.episode": ep, "status": status, "reason": "" if status == "ok" else "boom",
            "m.iae_cross_track": iae, "m.energy": energy, "m.passed": passed}


ROWS = ([_row("pid", i, "ok", iae, e, p) for i, (iae, e, p) in enumerate([(10.0, 100.0, True), (20.0, 200.0, True),
                                                                           (30.0, 300.0, False)])]
        # an open-loop 1e6 N "controller": every episode diverged after a fraction of a second, so its
        # integrals are tiny and its (partial) record passed the criterion
        + [_row("blast", i, "diverged", 0.5, 1.0, True) for i in range(3)]
        + [_row("half", 0, "ok", 5.0, 50.0, True), _row("half", 1, "ok", 7.0, 70.0, True),
           _row("half", 2, "diverged", 0.1, 1.0, True)])


def test_worst_values():
    assert worst_value("iae_cross_track") == math.inf
    assert worst_value("min_clearance_m") == -math.inf
    assert worst_value("passed") is False and worst_value("goal_reached") is False
    assert worst_value("contact") is True


def test_a_diverged_controller_is_not_ranked_first():
    agg = aggregate(ROWS)
    cells = agg[KEY]
    # pid: means 20 m s and 200 J, 2 of 3 passed; blast and half: an infinite IAE and energy
    assert cells["pid"]["iae_cross_track"].mean == pytest.approx(20.0)
    assert cells["pid"]["energy"].mean == pytest.approx(200.0)
    assert cells["blast"]["iae_cross_track"].mean == math.inf and cells["half"]["energy"].mean == math.inf
    # the rates count the episodes not ok as failures: blast 0/3, half 2/3 (Wilson's interval of 2 of 3)
    assert (cells["blast"]["passed"].mean, cells["blast"]["passed"].n) == (0.0, 3)
    assert cells["half"]["passed"].mean == pytest.approx(2 / 3)
    assert (cells["half"]["passed"].lo, cells["half"]["passed"].hi) == pytest.approx(wilson_ci(2, 3))
    # ranks per ranked metric (ties share the lower rank; `passed` is not ranked: each controller is
    # judged by its own criterion, so the rates are shown apart):
    #   iae:    pid 1, blast 2, half 2      (20 < inf = inf)
    #   energy: pid 1, blast 2, half 2
    assert "passed" not in RANKED
    rank = ranking(agg)
    assert rank["pid"] == {"mean_rank": 1.0, "wins": 2, "ranked": 2}
    for ctrl in ("half", "blast"):   # one diverged episode is enough to count with the worst value
        assert rank[ctrl]["mean_rank"] == pytest.approx(2.0) and rank[ctrl]["wins"] == 0
    # the heat map's score: pid 1 on both; half and blast 0 (a worst value ranks last, by rank)
    scores = normalised_scores(agg)[KEY]
    assert scores == pytest.approx({"pid": 1.0, "half": 0.0, "blast": 0.0})


def test_the_report_says_worst_and_ranks_the_diverged_last(tmp_path):
    lines = task_table(aggregate(ROWS)[KEY], ["pid", "blast", "half"])
    blast = next(line for line in lines if line.startswith("| `blast` |"))
    assert "| 0/3 |" in blast and "worst (not ok)" in blast and "**" not in blast
    suite = SimpleNamespace(controllers=[SimpleNamespace(name=c) for c in ("pid", "blast", "half")], vessels=[""],
                            episodes={"t": 3}, name="s", source="s.toml", tasks=["t"], conditions=["calm"], skipped=[])
    text = write_report(tmp_path, ROWS, suite, draw=False).read_text()
    order = re.findall(r"^\| \d \| `(\w+)` \|", text, re.M)
    assert order[0] == "pid" and sorted(order[1:]) == ["blast", "half"]
    assert "counts with the worst value" in text
