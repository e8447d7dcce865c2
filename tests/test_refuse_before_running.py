"""Issue 38: inputs a command can judge before it runs are refused before it runs (exit 2, one
line, nothing written), not after the work (or the memory) is spent.

- cause 12: a suite's size (episodes x conditions x vessels x controllers) over the stated limit
  (usv_mj.jobs.bench.suite.MAX_EPISODES) is refused before any episode is drawn;
"""

from __future__ import annotations

import pytest

from usv_mj.core.errors import SweepError
from usv_mj.jobs.bench import suite as suite_module
from usv_mj.jobs.bench.suite import MAX_EPISODES, plan_suite


def _no_draws(monkeypatch):
    def refuse(*a, **k):
        raise AssertionError("the suite was drawn before its size was checked")
    monkeypatch.setattr(suite_module, "draw_values", refuse)
    monkeypatch.setattr(suite_module, "apply_values", refuse)


def test_a_huge_suite_is_refused_before_it_is_drawn(monkeypatch):
    _no_draws(monkeypatch)
    with pytest.raises(SweepError, match=r"<suite>: 300000000 episodes \(100000000 over the tasks x 1 conditions x "
                                         r"1 vessels x 3 controllers\) is over the limit of 100000"):
        plan_suite({"episodes": 100_000_000, "tasks": [{"name": "a"}]})
    # the limit counts every factor: 2 tasks (one with its own episodes) x 2 conditions x 2 vessels x 1 controller
    per = MAX_EPISODES // 8 + 1                   # (per + per) * 2 * 2 * 1 = 8 per > MAX_EPISODES
    with pytest.raises(SweepError, match=rf"{8 * per} episodes \({2 * per} over the tasks x 2 conditions x 2 vessels"):
        plan_suite({"episodes": per, "controllers": ["los"], "vessels": ["paper", "otter"],
                    "conditions": {"calm": {}, "sea": {"sea": "moderate"}},
                    "tasks": [{"name": "a"}, {"name": "b", "episodes": per}]})


def test_a_suite_at_the_limit_is_planned(monkeypatch):
    suite = plan_suite({"episodes": 2, "controllers": ["los"], "tasks": [{"name": "a", "duration": 2.0}]})
    assert len(suite.plan.runs) == 2
    assert suite_module.check_size("s", MAX_EPISODES, [{"name": "a"}], 1, 1, 1) == MAX_EPISODES


def test_the_cli_says_it_in_one_line_and_exit_2(tmp_path, capsys):
    from usv_mj.cli.main import main

    big = tmp_path / "big.toml"
    big.write_text('episodes = 100000000\n[[tasks]]\nname = "a"\n')
    assert main(["bench", str(big), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is over the limit of 100000" in err[0]
    assert not (tmp_path / "o").exists()
