"""Issue 38: inputs a command can judge before it runs are refused before it runs (exit 2, one
line, nothing written), not after the work (or the memory) is spent.

- cause 12: a suite's size (episodes x conditions x vessels x controllers) over the stated limit
  (usv_mj.jobs.bench.suite.MAX_EPISODES) is refused before any episode is drawn;
- cause 14: a manoeuvre whose duration does not pass its approach (the execute at approach_s), or
  is shorter than a control period, or whose approach speed the run's limits call divergence, is
  refused when its options are read; a run that ends before the execute at run time (a divergence)
  reports that there is nothing to measure instead of crashing in the measures;
- cause 15: a bench task whose name cannot name its figure's file ('a/b': figures/bars-a/b.png)
  is refused when the suite is planned, not after every episode ran.
"""

from __future__ import annotations

import pytest

from usv_mj.core.errors import SweepError
from usv_mj.jobs.bench import suite as suite_module
from usv_mj.jobs.bench.suite import MAX_EPISODES, plan_suite
from usv_mj.core.errors import ScenarioError


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


# --- cause 14: manoeuvres ---------------------------------------------------------------------------


def test_a_manoeuvre_that_does_not_pass_its_approach_is_refused():
    from usv_mj.scenario.manoeuvre import SpiralOptions, StoppingOptions, TurningOptions, ZigzagOptions

    with pytest.raises(ScenarioError, match=r"manoeuvre.duration = 1 s does not pass the approach: the execute is "
                                            r"at manoeuvre.approach_s = 5.0 s"):
        TurningOptions(duration=1)
    with pytest.raises(ScenarioError, match=r"manoeuvre.duration = 60.0 s does not pass the approach.*= 100"):
        StoppingOptions(approach_s=100.0)
    with pytest.raises(ScenarioError, match=r"duration = 0.001 s is shorter than one control period"):
        ZigzagOptions(duration=0.001, control_period=0.01)
    with pytest.raises(ScenarioError, match=r"hold_s = 0.001 s is shorter than one control period"):
        SpiralOptions(hold_s=0.001)
    assert TurningOptions(duration=5.01).duration == 5.01          # one step past the execute is a run


def test_an_approach_the_limits_call_divergence_is_refused():
    from usv_mj.jobs.manoeuvres import run_manoeuvre
    from usv_mj.scenario.manoeuvre import manoeuvre_from_table
    from usv_mj.scenario.spec import load_scenario

    sc = load_scenario(preset="paper")
    with pytest.raises(ScenarioError, match=r"approach_speed = 1000000.0 m/s is not below limits.max_speed = 50.0"):
        run_manoeuvre(sc, manoeuvre_from_table({"kind": "turning", "approach_speed": 1e6}), plant_kind="analytic")
    # the paper hull's drag at 0.6 m/s is over 1 N: the run would stop at its first step
    weak = load_scenario(preset="paper", overrides={"limits": {"max_force": 1.0}})
    with pytest.raises(ScenarioError, match=r"takes a surge force of .* N, not below limits.max_force = 1.0 N"):
        run_manoeuvre(weak, manoeuvre_from_table({"kind": "stopping"}), plant_kind="analytic")


def test_a_run_that_ends_before_the_execute_has_nothing_to_measure():
    from usv_mj.jobs.manoeuvres import run_manoeuvre
    from usv_mj.scenario.manoeuvre import manoeuvre_from_table
    from usv_mj.scenario.spec import load_scenario

    # with the scenario's d(t) the hull yaws at once: a yaw-rate limit of 1e-6 rad/s ends the run
    # at its first step, 0.01 s (the last row kept: t = 0), long before the execute at 5 s
    sc = load_scenario(preset="paper", overrides={"limits": {"max_yaw_rate": 1e-6}})
    result = run_manoeuvre(sc, manoeuvre_from_table({"kind": "turning", "conditions": "scenario"}),
                           plant_kind="analytic")
    assert result["status"] == "diverged" and result["ended_before_execute"]
    assert result["measures"]["note"].startswith("the run ended at t = 0 s (diverged: state left its limits at t = 0.010 s")
    assert result["measures"]["note"].endswith("before the execute at 5 s: nothing to measure")


def test_the_manoeuvre_command_refuses_before_writing(tmp_path, capsys):
    from usv_mj.cli.main import main

    out = tmp_path / "o"
    assert main(["manoeuvre", "turning", "--duration", "1", "--plant", "analytic", "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not pass the approach" in err[0]
    assert not out.exists()


# --- cause 15: a bench task's name is a file name ---------------------------------------------------


@pytest.mark.parametrize("name", ["a/b", "..", "a\\b", "tab\there"])
def test_a_task_name_that_cannot_name_a_file_is_refused(monkeypatch, name):
    _no_draws(monkeypatch)
    with pytest.raises(SweepError, match=r"\[\[tasks\]\] 0: name .* cannot name a file \(figures/bars-NAME.png\)"):
        plan_suite({"tasks": [{"name": name}]})


def test_a_task_name_with_a_space_plans():
    suite = plan_suite({"episodes": 1, "controllers": ["los"], "tasks": [{"name": "line 0.6", "duration": 2.0}]})
    assert suite.tasks == ["line 0.6"]
