"""usv-mj bench on the sweep's engine: 1 vs 2 workers, interrupt and resume, a plug-in from a
temporary folder, the paired comparison, the leaderboard, bad suites (usv_mj.jobs.bench)."""

import math
import os
import textwrap
from pathlib import Path

import pytest

from usv_mj.jobs.bench import compare, run_bench
from usv_mj.jobs.bench.suite import load_suite, plan_suite
from usv_mj.core.errors import SweepError
from usv_mj.jobs.sweep.runner import TIMING_COLUMNS, read_results

ROOT = Path(__file__).resolve().parents[1]

TINY = """
name = "tiny"
episodes = 2
seed = 3
duration = 6.0
plant = "analytic"
controllers = ["ppc", "pi"]
[conditions.calm]
[conditions.limited]
actuators = "paper-limited"
[[tasks]]
name = "line"
base = "paper"
set = { "trajectory.kind" = "line", "initial.eta" = [0.0, 0.0, 0.0] }
vary = { "initial.eta[1]" = { uniform = [-2.0, 2.0] } }
settle_time_s = 3.0
"""


def _suite(tmp_path, text=TINY, name="tiny.toml"):
    path = tmp_path / name
    path.write_text(text)
    return load_suite(path)


def _metrics(rows):
    """The rows without the columns that time the machine."""
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as c:
        yield c


def test_plan_pairs_the_episodes_across_controllers(tmp_path):
    suite = _suite(tmp_path)
    runs = suite.plan.runs
    assert len(runs) == 1 * 2 * 2 * 2
    by = {(r.values["condition"], r.values["controller"], r.values["episode"]): r for r in runs}
    for cond in ("calm", "limited"):
        for ep in (0, 1):
            a, b = by[(cond, "ppc", ep)], by[(cond, "pi", ep)]
            assert a.values["initial.eta[1]"] == b.values["initial.eta[1]"]   # the same start pose
            assert a.scenario.controller.kind == "ppc" and b.scenario.controller.kind == "pi"
    assert by[("calm", "pi", 0)].values["initial.eta[1]"] != by[("calm", "pi", 1)].values["initial.eta[1]"]
    assert by[("limited", "ppc", 0)].scenario.actuators.kind == "twin"
    assert by[("calm", "ppc", 0)].scenario.actuators.kind == "unlimited"
    assert all(not r.scenario.baseline.enabled and r.scenario.duration == 6.0 for r in runs)


def test_one_and_two_workers_give_bit_identical_metrics(tmp_path, client):
    suite = _suite(tmp_path)
    one = run_bench(suite, tmp_path / "one", workers=1, progress=False, echo=None, draw=False)
    two = run_bench(suite, tmp_path / "two", client=client, progress=False, echo=None, draw=False)
    assert one.complete and two.complete
    a, _ = read_results(tmp_path / "one" / "results.parquet")
    b, _ = read_results(tmp_path / "two" / "results.parquet")
    assert len(a) == 8 and all(r["status"] == "ok" for r in a)
    assert _metrics(a) == _metrics(b)
    assert all(isinstance(r["m.iae_cross_track"], float) and r["m.iae_cross_track"] > 0 for r in a)
    assert (tmp_path / "one" / "report.md").read_text() == (tmp_path / "two" / "report.md").read_text()


def test_an_interrupted_benchmark_resumed_equals_the_uninterrupted_one(tmp_path, client):
    suite = _suite(tmp_path)
    whole = run_bench(suite, tmp_path / "whole", client=client, progress=False, echo=None, draw=False)
    part = run_bench(suite, tmp_path / "part", client=client, progress=False, echo=None, max_runs=3, draw=False)
    assert whole.complete and not part.complete
    kept, _ = read_results(tmp_path / "part" / "results.parquet")
    assert 3 <= len(kept) < 8
    assert not (tmp_path / "part" / "report.md").exists()
    resumed = run_bench(suite, tmp_path / "part", client=client, progress=False, echo=None, resume=True, draw=False)
    assert resumed.complete and resumed.ran == 8 - len(kept)
    a, _ = read_results(tmp_path / "whole" / "results.parquet")
    b, _ = read_results(tmp_path / "part" / "results.parquet")
    assert _metrics(a) == _metrics(b)
    assert (tmp_path / "whole" / "report.md").read_text() == (tmp_path / "part" / "report.md").read_text()
    # another suite's results are refused
    other = _suite(tmp_path, TINY.replace("seed = 3", "seed = 4"), "other.toml")
    with pytest.raises(SweepError, match="another sweep"):
        run_bench(other, tmp_path / "part", client=client, progress=False, echo=None, resume=True)


PLUGIN = '''
"""A plug-in controller in a folder of its own: the PI law with a slower surge loop."""
from usv_mj.controllers.pi_baseline import PIController, PIGains


class GentlePI(PIController):
    """The PI baseline under another name; its gains (the options class attribute) from [controller]."""

    options = PIGains
'''


def test_a_plugin_controller_from_a_temporary_folder_is_on_the_leaderboard(tmp_path, monkeypatch):
    folder = tmp_path / "plug"
    folder.mkdir()
    (folder / "gentle_plugin.py").write_text(textwrap.dedent(PLUGIN))
    monkeypatch.syspath_prepend(str(folder))
    # as a user would: PYTHONPATH=folder usv-mj bench suite.toml (the workers inherit the environment)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(folder), os.environ.get("PYTHONPATH", "")]))
    suite = _suite(tmp_path, TINY.replace('controllers = ["ppc", "pi"]',
                                          'controllers = ["pi", { name = "gentle", kind = "gentle_plugin:GentlePI", '
                                          'set = { "controller.kp_u" = 100.0 } }]'))
    result = run_bench(suite, tmp_path / "out", workers=2, progress=False, echo=None)
    rows = result.rows
    assert {r["vary.controller"] for r in rows} == {"pi", "gentle"}
    assert all(r["status"] == "ok" for r in rows), [r["reason"] for r in rows]
    report = (tmp_path / "out" / "report.md").read_text()
    assert "| `gentle` |" in report and "| `pi` |" in report
    for fig in ("heatmap.png", "bars-line.png", "worst-episodes.png"):
        assert (tmp_path / "out" / "figures" / fig).stat().st_size > 1000
    gentle = {(r["vary.condition"], r["vary.episode"]): r["m.effort_u"] for r in rows if r["vary.controller"] == "gentle"}
    pi = {(r["vary.condition"], r["vary.episode"]): r["m.effort_u"] for r in rows if r["vary.controller"] == "pi"}
    assert gentle.keys() == pi.keys() and all(gentle[k] != pi[k] for k in gentle)   # its own gain was used


def _row(ctrl, ep, iae, passed=True):
    return {"vary.task": "t", "vary.condition": "calm", "vary.vessel": "default", "vary.controller": ctrl,
            "vary.episode": ep, "status": "ok", "m.iae_cross_track": iae, "m.passed": passed}


def test_compare_is_the_exact_wilcoxon_test_per_cell():
    # A lower in all 8 pairs: the exact two-sided signed-rank p is 2 / 2^8; Holm over the cell's two
    # tests (IAE, passed) doubles it
    rows = [_row("A", i, 1.0 + i) for i in range(8)] + [_row("B", i, 1.5 + 1.1 * i) for i in range(8)]
    result = compare(rows, "A", "B")
    by = {r["metric"]: r for r in result["tests"]}
    iae = by["iae_cross_track"]
    assert iae["pairs"] == 8 and iae["p"] == pytest.approx(2 / 2 ** 8) and iae["p_holm"] == pytest.approx(4 / 2 ** 8)
    assert iae["verdict"] == "A better" and (iae["task"], iae["condition"]) == ("t", "calm")
    assert by["passed"]["verdict"] == "no difference" and by["passed"]["p"] == 1.0
    # B lower in 3 of 4 pairs only: not significant (the smallest two-sided p with 4 pairs is 0.125)
    rows = [_row("A", i, v) for i, v in enumerate([1.0, 2.0, 3.0, 4.0])] + \
           [_row("B", i, v) for i, v in enumerate([0.5, 1.8, 2.6, 4.5])]
    r = {x["metric"]: x for x in compare(rows, "A", "B")["tests"]}["iae_cross_track"]
    assert r["verdict"] == "no difference" and r["p"] >= 0.125
    with pytest.raises(SweepError, match="no controller 'C'"):
        compare(rows, "A", "C")


def test_the_leaderboard_marks_the_best_and_ranks(tmp_path):
    from usv_mj.jobs.bench.report import aggregate, ranking, task_table

    rows = [_row("A", i, 1.0 + 0.1 * i) for i in range(4)] + [_row("B", i, 2.0 + 0.1 * i, passed=i < 2)
                                                              for i in range(4)]
    agg = aggregate(rows)
    lines = task_table(agg[("t", "calm", "default")], ["A", "B"])
    a, b = lines[2], lines[3]
    assert a.startswith("| `A` | 4/4 | **1.15 [") and "**100 % [" in a     # IAE mean 1.15, best; all passed
    assert "| 2.15 [" in b and "| 50 % [" in b
    rank = ranking(agg)
    # the criterion is not ranked (it means each controller's own promise): IAE alone ranks them
    assert rank["A"]["mean_rank"] == 1.0 and rank["B"]["mean_rank"] == 2.0 and rank["A"]["wins"] == 1


def test_bad_suites_say_where(tmp_path):
    with pytest.raises(SweepError, match="unknown key 'episdes'.*did you mean 'episodes'"):
        plan_suite({"episdes": 3, "tasks": [{"name": "a"}]})
    with pytest.raises(SweepError, match="a suite needs at least one"):
        plan_suite({"controllers": ["ppc"]})
    with pytest.raises(SweepError, match="controller 'nope'"):
        plan_suite({"controllers": ["nope"], "tasks": [{"name": "a", "duration": 2.0}]})
    with pytest.raises(SweepError, match=r"task 'a': goal must be \[x, y\]"):
        plan_suite({"tasks": [{"name": "a", "goal": "there"}]})
    with pytest.raises(SweepError, match="task 'a': bench metrics: settle_time_s = 'long' must be a finite number"):
        plan_suite({"tasks": [{"name": "a", "settle_time_s": "long"}]})
    with pytest.raises(SweepError, match="vessel"):   # a vessel kind that no registry knows
        plan_suite({"vessels": ["nope"], "tasks": [{"name": "a", "duration": 2.0}]})
    otter = plan_suite({"vessels": ["otter"], "controllers": ["los"], "tasks": [{"name": "a", "duration": 2.0}]})
    assert {run.scenario.vessel.kind for run in otter.plan.runs} == {"otter"}   # the suite's vessels reach the runs


def test_cli_bad_suite_is_one_line_and_exit_2(tmp_path, capsys):
    from usv_mj.cli.main import main

    bad = tmp_path / "bad.toml"
    bad.write_text('episodes = 0\n[[tasks]]\nname = "a"\n')
    assert main(["bench", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("usv-mj bench: error: ") and "episodes" in err[0]


def default_suite_at_one_episode():
    """The shipped suite as load_suite() plans it (its file, its folder), at 1 episode per cell instead
    of its 10: planning all 3240 scenarios takes tens of seconds, and the plan is the same for every
    episode count but for the draws (checked: the file says 10, no task its own)."""
    import tomllib

    from usv_mj.jobs.bench.suite import DEFAULT_EPISODES, default_suite_path

    path = default_suite_path()
    data = tomllib.loads(path.read_text())
    assert data["episodes"] == DEFAULT_EPISODES == 10 and not any("episodes" in t for t in data["tasks"])
    return plan_suite({**data, "episodes": 1}, str(path), path.parent)


def test_the_default_suite_plans(tmp_path):
    suite = default_suite_at_one_episode()
    assert suite.tasks == ["paper-track", "line-0.6", "line-1.0", "circle-0.6", "circle-1.0", "lawnmower", "harbour"]
    assert suite.conditions == ["calm", "sea", "limited"]
    assert [c.name for c in suite.controllers] == ["ppc", "pi", "los", "ppo"]
    # 3 conditions x 4 vessels x (7 tasks x 3 controllers + 6 tasks for the policy, no harbour) per
    # episode; x 10 episodes: the default suite's 3240
    assert len(suite.plan.runs) == 3 * 4 * (7 * 3 + 6) and 10 * len(suite.plan.runs) == 3240
    ppo = [r for r in suite.plan.runs if r.values["controller"] == "ppo"]
    assert Path(ppo[0].options["policy"]).is_file()   # the shipped policy, beside the suite
    harbour = [r for r in suite.plan.runs if r.values["task"] == "harbour"]
    assert harbour[0].scenario.obstacles and harbour[0].options["metrics"]["goal"] == (45.0, 0.0)
    sea = [r for r in suite.plan.runs if r.values["condition"] == "sea"][0].scenario.sea
    assert sea.waves.hs == 0.2 and sea.current.speed == 0.3
    assert math.isclose(suite.plan.runs[0].scenario.duration, 120.0)


def test_a_policy_on_the_gymnasium_observation_is_scored_like_a_controller(tmp_path, monkeypatch):
    from usv_mj.jobs.sweep.runner import run_one

    (tmp_path / "zero_policy.py").write_text("import numpy as np\n\ndef zero(obs):\n    return np.zeros(2, np.float32)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    suite = plan_suite({"duration": 5.0, "episodes": 1, "controllers": [
        "ppc", {"name": "ppc-policy", "policy": "usv_mj.envs:PPCPolicy", "control_period": 0.001},
        {"name": "zero", "policy": "zero_policy:zero"}],
        "tasks": [{"name": "line", "set": {"trajectory.kind": "line", "initial.eta": [0.0, 1.0, 0.0],
                                           "plant.kind": "mujoco"}}]})
    rows = {r.values["controller"]: run_one(r.run_id, r.scenario, r.values, r.options) for r in suite.plan.runs}
    assert all(r["status"] == "ok" for r in rows.values()), {k: r["reason"] for k, r in rows.items()}
    # the paper's law as a policy on the observation (usv_mj.envs.PPCPolicy), at the law's own 1 ms
    # period, is the ppc controller run through the environment: the same track, within the float32
    # observation's rounding
    assert rows["ppc-policy"]["m.iae_cross_track"] == pytest.approx(rows["ppc"]["m.iae_cross_track"], rel=1e-3)
    assert rows["ppc-policy"]["m.effort_u"] == pytest.approx(rows["ppc"]["m.effort_u"], rel=1e-3)
    # a zero action is no thrust: no effort, and the offset of 1 m from the line stays (IAE = 1 m x 5 s)
    assert rows["zero"]["m.effort_u"] == 0.0 and rows["zero"]["m.energy"] == 0.0
    assert rows["zero"]["m.iae_cross_track"] == pytest.approx(5.0, rel=0.02)
    # the Track observation has no view of obstacles: a policy is not planned on the harbour, and says so
    harbour = plan_suite({"duration": 5.0, "episodes": 1, "controllers": ["ppc", {"name": "zero", "policy": "zero_policy:zero"}],
                          "tasks": [{"name": "h", "base": str(ROOT / "examples/scenarios/harbour_gap.toml")}]})
    assert [r.values["controller"] for r in harbour.plan.runs] == ["ppc"]
    assert harbour.skipped == [("h", "zero", "a policy's Track observation has no view of the obstacles")]
    with pytest.raises(SweepError, match="nothing to run: zero not on h"):
        plan_suite({"duration": 5.0, "controllers": [{"name": "zero", "policy": "zero_policy:zero"}],
                    "tasks": [{"name": "h", "base": str(ROOT / "examples/scenarios/harbour_gap.toml")}]})


def test_a_stable_baselines3_zip_is_a_controller(tmp_path):
    sb3 = pytest.importorskip("stable_baselines3")
    import gymnasium

    import usv_mj.envs  # noqa: F401  (registers usv_mj/Track-v0)
    from usv_mj.jobs.bench.policy import load_policy
    from usv_mj.jobs.sweep.runner import run_one

    env = gymnasium.make("usv_mj/Track-v0")
    model = sb3.PPO("MlpPolicy", env, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=64)
    model.save(tmp_path / "ppo.zip")
    policy = load_policy(str(tmp_path / "ppo.zip"), env)
    obs, _ = env.reset(seed=1)
    assert policy(obs) == pytest.approx(model.predict(obs, deterministic=True)[0])   # the model's own action
    suite = _suite(tmp_path, TINY.replace('controllers = ["ppc", "pi"]',
                                          'controllers = [{ name = "ppo", policy = "ppo.zip" }]'))
    run = suite.plan.runs[0]
    assert run.options["policy"] == str((tmp_path / "ppo.zip").resolve())   # relative to the suite's folder
    row = run_one(run.run_id, run.scenario, run.values, run.options)
    assert row["status"] in ("ok", "diverged") and row["m.iae_cross_track"] is not None, row["reason"]
    with pytest.raises(Exception, match="no such file"):
        load_policy(str(tmp_path / "missing.zip"), env)
