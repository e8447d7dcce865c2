"""The benchmark's statistics a reviewer asks for (issue 37, item 2; docs/metrics.md, "Statistics"):

- a time to an event (settling) is censored, never averaged: constructed records that settle at
  known times, and some that never settle, give the fraction reached and the median with its
  distribution-free interval by hand;
- Holm's correction against a worked example computed here step by step;
- ``--compare`` of two identical controllers finds no difference on any metric (constructed rows over
  several cells, and two entries of the same built-in law run as a real suite);
- a pass rate is compared only between controllers judged by the same criterion;
- the exact sign and McNemar tests, and the order statistics of the median, against binomial sums.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.jobs.bench import compare, compare_table
from usv_mj.jobs.bench.metrics import episode_metrics, estimate_event
from usv_mj.jobs.bench.stats import censored_median, censored_pairs, holm, median_ranks, sign_test_p
from usv_mj.record.run_record import CORE_COLUMNS, RunRecord

DT, T, U = 0.01, 40.0, 0.5


def _record(settle_at):
    """The vessel along x_d = U t, y_d = 0 with a lateral offset 2 m that drops to 0.2 m at
    ``settle_at`` [s] (None: stays 2 m): a 1 m band is entered at that time and never left."""
    t = np.arange(int(round(T / DT)) + 1) * DT
    cols = {name: np.zeros(len(t)) for name in CORE_COLUMNS}
    cols["t"] = t
    cols["x"] = cols["x_d"] = U * t
    cols["x_d_dot"] = cols["u_d"] = np.full(len(t), U)
    cols["y"] = np.where(t < (settle_at if settle_at is not None else np.inf), 2.0, 0.2)
    meta = {"criterion": {"kind": "path_tolerance", "settle_time_s": 0.0, "cross_track_m": 5.0, "along_track_m": None}}
    return RunRecord.from_arrays(cols, metadata=meta, diagnostic_fields=())


def test_a_settling_time_that_never_came_is_censored_not_averaged():
    settle = [5.0, 7.0, 9.0, 12.0, 3.0, 20.0, 31.0, None, None, None]
    m = [episode_metrics(_record(s), band_cross_track_m=1.0) for s in settle]
    for s, row in zip(settle, m):
        assert row["settled_cross_track"] is (s is not None)
        # the first row inside the band after the last row outside it: settle_at on the 0.01 s grid
        assert row["settling_time_cross_track"] == pytest.approx(T if s is None else s, abs=1e-9)
    e = estimate_event([r["settling_time_cross_track"] for r in m], [r["settled_cross_track"] for r in m])
    # by hand: 7 of 10 reached; ordered 3, 5, 7, 9, 12, 20, 31, >T, >T, >T: the median is the mean of the
    # 5th and 6th, (12 + 20) / 2 = 16 (the mean of the recorded numbers, (87 + 3 x 40) / 10, would be 20.7);
    # the 95 % ranks for n = 10: P(B <= 1) = 11/1024 <= 0.025 < P(B <= 2) = 56/1024, so j = 2, k = 9:
    # [x_(2), x_(9)] = [5, > T]
    assert (e.n, e.reached, e.mean, e.lo) == (10, 7, 16.0, 5.0) and math.isinf(e.hi)
    # most never settled: the median itself is "> T"
    e = estimate_event([5.0, 7.0, T, T, T], [True, True, False, False, False])
    assert e.reached == 2 and math.isinf(e.mean)
    from usv_mj.jobs.bench.report import cell_text

    assert cell_text(e, False) == "2/5: > T [0, > T]"


def test_median_ranks_and_the_exact_tests_by_binomial_sums():
    def cdf(k, n):
        return sum(math.comb(n, i) for i in range(k + 1)) / 2**n

    for n in range(1, 40):
        j, k = median_ranks(n)
        assert k == n + 1 - j
        assert j == 0 or cdf(j - 1, n) <= 0.025 < cdf(j, n)
        if j == 0:
            assert cdf(0, n) > 0.025
    assert median_ranks(5) == (0, 6) and median_ranks(6) == (1, 6) and median_ranks(10) == (2, 9)
    assert sign_test_p(8, 0) == pytest.approx(2 / 2**8)
    assert sign_test_p(3, 1) == pytest.approx(2 * 5 / 16)
    assert sign_test_p(0, 0) == 1.0
    assert censored_pairs([1, 2, None, None, 4], [True, True, False, False, True],
                          [2, None, 3, None, 4], [True, False, True, False, True]) == (2, 1, 2)
    m = censored_median([1.0, 2.0, 3.0], [True, True, True])
    assert (m["median"], m["reached"]) == (2.0, 3)


def test_holm_against_a_worked_example():
    # four tests at alpha 0.05: sorted 0.005, 0.01, 0.03, 0.04 are multiplied by 4, 3, 2, 1:
    # 0.02, 0.03, 0.06, 0.04, made monotone: 0.02, 0.03, 0.06, 0.06. Rejected: the first two only
    # (Bonferroni, 0.05/4 = 0.0125, would reject the same two here; the third, 0.03 > 0.05/2, stops Holm).
    p = [0.01, 0.04, 0.03, 0.005]
    adj = holm(p)
    assert adj == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert [a < 0.05 for a in adj] == [True, False, False, True]
    # a p that multiplied exceeds 1 is 1; one test is its own p
    assert holm([0.6, 0.7]) == pytest.approx([1.0, 1.0]) and holm([0.2]) == [0.2]


def _row(ctrl, task, cond, ep, **m):
    row = {"vary.task": task, "vary.condition": cond, "vary.vessel": "default", "vary.controller": ctrl,
           "vary.episode": ep, "status": "ok", "criterion.kind": "funnel",
           "criterion.description": "the funnel"}
    row.update({f"m.{k}": v for k, v in m.items()})
    return row


def _metrics(rng):
    settled = bool(rng.random() < 0.6)
    return {"iae_cross_track": float(rng.uniform(1, 9)), "energy": float(rng.uniform(10, 90)),
            "settling_time_cross_track": float(rng.uniform(2, 30)) if settled else 60.0,
            "settled_cross_track": settled, "passed": bool(rng.random() < 0.7),
            "switches_per_s_u": float(rng.uniform(0, 200))}


def test_compare_of_two_identical_controllers_finds_no_difference_on_any_metric():
    rng = np.random.default_rng(7)
    rows = []
    for task in ("line", "circle"):
        for cond in ("calm", "sea"):
            for ep in range(12):
                m = _metrics(rng)
                rows += [_row("A", task, cond, ep, **m), _row("B", task, cond, ep, **m)]
    result = compare(rows, "A", "B")
    assert result["n_tests"] == 4 * 5 and result["cells"] == 4 and result["correction"] == "Holm-Bonferroni within each cell"
    assert {t["family"] for t in result["tests"]} == {5}
    assert {t["verdict"] for t in result["tests"]} == {"no difference"}
    assert all(t["p"] == 1.0 and t["p_holm"] == 1.0 for t in result["tests"])
    assert not result["apart"]
    assert "No metric differs in any cell" in compare_table(result, "A", "B")


def test_holm_runs_within_each_cell():
    """Two cells, one with a real difference: its Holm family is its own tests, not the other cell's."""
    rows = []
    for ep in range(12):
        rows += [_row("A", "t", "calm", ep, iae_cross_track=1.0 + ep), _row("B", "t", "calm", ep, iae_cross_track=2.0 + ep)]
        rows += [_row("A", "t", "sea", ep, iae_cross_track=1.0 + ep, energy=3.0),
                 _row("B", "t", "sea", ep, iae_cross_track=1.0 + ep, energy=3.0)]
    result = compare(rows, "A", "B")
    calm = [t for t in result["tests"] if t["condition"] == "calm"]
    assert [(t["metric"], t["family"], t["verdict"]) for t in calm] == [("iae_cross_track", 1, "A better")]
    assert calm[0]["p_holm"] == calm[0]["p"] == pytest.approx(2 / 2**12)


def test_compare_finds_a_real_difference_per_cell_after_holm():
    rows = []
    for ep in range(12):   # A lower in all 12 pairs: exact p = 2 / 2^12, Holm over the cell's 3 tests: x 3
        rows += [_row("A", "t", "calm", ep, iae_cross_track=1.0 + ep, passed=True),
                 _row("B", "t", "calm", ep, iae_cross_track=1.5 + 1.1 * ep, passed=True)]
        rows[-1]["criterion.description"] = rows[-2]["criterion.description"]
    for r in rows:
        r["m.settled_cross_track"], r["m.settling_time_cross_track"] = True, 10.0
    result = compare(rows, "A", "B")
    by = {t["metric"]: t for t in result["tests"]}
    assert by["iae_cross_track"]["p"] == pytest.approx(2 / 2**12)
    assert by["iae_cross_track"]["p_holm"] == pytest.approx(3 * 2 / 2**12)
    assert by["iae_cross_track"]["verdict"] == "A better" and by["passed"]["verdict"] == "no difference"
    assert by["settling_time_cross_track"]["verdict"] == "no difference"   # 12 ties
    # four pairs only: the smallest two-sided p is 0.125, never significant
    few = [r for r in rows if r["vary.episode"] < 4]
    assert {t["verdict"] for t in compare(few, "A", "B")["tests"]} == {"no difference"}


def test_a_pass_rate_is_compared_only_under_the_same_criterion():
    rows = []
    for ep in range(10):
        rows += [_row("A", "t", "calm", ep, passed=True),
                 {**_row("B", "t", "calm", ep, passed=ep < 3), "criterion.kind": "path_tolerance",
                  "criterion.description": "within 0.25 m of the path"}]
    result = compare(rows, "A", "B")
    assert "passed" not in {t["metric"] for t in result["tests"]}
    (apart,) = result["apart"]
    assert apart["a"] == "10/10 (the funnel)" and apart["b"] == "3/10 (within 0.25 m of the path)"
    # the leaderboard: no bold pass rate between different criteria, none ranked, both shown apart
    from usv_mj.jobs.bench.report import RANKED, aggregate, criteria_table, task_table

    assert "passed" not in RANKED
    agg = aggregate(rows)
    lines = task_table(agg[("t", "calm", "default")], ["A", "B"])
    assert "**100 %" not in "\n".join(lines)
    table = "\n".join(criteria_table(agg, ["A", "B"]))
    assert "| `A` | the funnel | 10/10 |" in table and "| `B` | within 0.25 m of the path | 3/10 |" in table


def test_a_suite_of_the_same_law_twice_compares_equal(tmp_path):
    """Two entries of the built-in pi (one under another name) on a small real suite, run in this
    process: every paired test says no difference."""
    from usv_mj.jobs.bench.suite import plan_suite
    from usv_mj.jobs.sweep.runner import run_one

    suite = plan_suite({"episodes": 6, "seed": 4, "duration": 8.0, "plant": "analytic",
                        "controllers": ["pi", {"name": "pi-again", "kind": "pi"}],
                        "tasks": [{"name": "line", "set": {"trajectory.kind": "line", "initial.eta": [0.0, 0.0, 0.0]},
                                   "vary": {"initial.eta[1]": {"uniform": [-2.0, 2.0]}}, "settle_time_s": 4.0}]},
                       str(tmp_path / "same.toml"), tmp_path)
    rows = [run_one(r.run_id, r.scenario, r.values, r.options) for r in suite.plan.runs]
    result = compare(rows, "pi", "pi-again")
    assert result["n_tests"] >= 10
    assert {t["verdict"] for t in result["tests"]} == {"no difference"}


def test_the_command_refuses_a_controller_compared_with_itself(tmp_path, capsys):
    """Every test of A against A says "no difference": the command refuses it before reading results."""
    from usv_mj.cli.main import main

    assert main(["bench", "--compare", "sbmpc", "sbmpc", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "usv-mj bench: error: --compare sbmpc sbmpc: give two different controllers of the suite"
