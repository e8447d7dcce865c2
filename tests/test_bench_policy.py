"""A learned policy in the benchmark runs as it was trained (its own control period, zero-order
hold) and is judged by the criterion of its training reward; the default suite covers every vessel
that has landed (usv_mj.jobs.bench.policy, usv_mj.jobs.bench.suite)."""

import math
import tomllib

import numpy as np
import pytest

from usv_mj.jobs.bench.suite import default_suite_path, plan_suite

PROBE = '''
import numpy as np

COMMANDS = []          # the normalized actions handed out, in order


class Probe:
    """A policy whose k-th command is known: surge +0.4 / -0.2 alternating, yaw 0.05 (k mod 3)."""

    def __init__(self, env):
        COMMANDS.clear()

    def __call__(self, obs):
        k = len(COMMANDS)
        a = np.array([0.4 if k % 2 == 0 else -0.2, 0.05 * (k % 3)], np.float32)
        COMMANDS.append(a)
        return a
'''


def _probe_suite(tmp_path, monkeypatch, **entry):
    (tmp_path / "probe_policy.py").write_text(PROBE)
    monkeypatch.syspath_prepend(str(tmp_path))
    return plan_suite({"duration": 0.5, "episodes": 1, "plant": "analytic",
                       "controllers": [{"name": "probe", "policy": "probe_policy:Probe", **entry}],
                       "tasks": [{"name": "line", "settle_time_s": 0.2,
                                  "set": {"trajectory.kind": "line", "initial.eta": [0.0, 1.0, 0.0]}}]})


def test_a_policy_runs_at_its_training_period_with_its_action_held(tmp_path, monkeypatch):
    from usv_mj.jobs.bench.policy import policy_episode
    from usv_mj.jobs.bench.suite import _with_table
    from usv_mj.loop.simulate import simulate

    run = _probe_suite(tmp_path, monkeypatch).plan.runs[0]
    # Track-v0's period, 0.01 s: 10 of the task's 1 ms integration steps (the paper preset's step)
    assert run.scenario.control_period == 0.01 and run.scenario.plant.substeps == 10
    record = policy_episode(run.scenario, run.options)
    import probe_policy

    commands = np.array(probe_policy.COMMANDS, float)
    t = np.asarray(record["t"])
    assert len(commands) == 50                                  # 0.5 s / 0.01 s: one call per period, not 500
    assert np.allclose(t, 0.01 * np.arange(51), atol=1e-12)     # a row per control step
    # row k holds the k-th command from t_k to t_k+1: the action is +-1000 N (N m) per unit (the
    # paper ship's unlimited channels), so 400 N / -200 N alternating and 0, 50, 100 N m in turn
    assert np.array_equal(record["tau_u"][:-1], commands[:, 0] * 1000.0)
    assert np.array_equal(record["tau_r"][:-1], commands[:, 1] * 1000.0)
    # the other plant, driven open loop by the same commands held 10 ms each (a step table at the
    # same period): the same thrust after the quantizer and the same motion
    table = {"kind": "open_loop", "times": list(0.01 * np.arange(50)), "tau_u": list(commands[:, 0] * 1000.0),
             "tau_r": list(commands[:, 1] * 1000.0), "interpolation": "step"}
    held = simulate(_with_table(run.scenario, "controller", table, "test"))
    assert held.metadata["plant"] != record.metadata["plant"]   # analytic vs the environment's MuJoCo
    assert np.array_equal(record["f_u"][:-1], held["f_u"][:-1]) and np.array_equal(record["f_r"][:-1], held["f_r"][:-1])
    for c in ("x", "y", "psi", "u", "v", "r"):
        assert record[c][-1] == pytest.approx(held[c][-1], abs=1e-9), c
    assert abs(record["u"][-1]) > 0.1    # it moved: the comparison is not of two hulls at rest


def test_a_policy_is_judged_by_its_training_reward_band_or_its_own_criterion(tmp_path, monkeypatch):
    from usv_mj.jobs.bench.policy import policy_episode
    from usv_mj.record.criteria import criterion_of_record

    run = _probe_suite(tmp_path, monkeypatch).plan.runs[0]
    # the track reward is full within 0.25 m and 0.1 rad (usv_mj.envs.tasks), after the task's settling time
    assert run.options["criterion"] == {"kind": "pose_tolerance", "settle_time_s": 0.2, "position_m": 0.25,
                                        "heading_deg": pytest.approx(180.0 / math.pi * 0.1)}
    record = policy_episode(run.scenario, run.options)
    judged = criterion_of_record(record).evaluate(record)
    assert judged["kind"] == "pose_tolerance" and judged["passed"] is False   # it starts 1 m off the line
    own = _probe_suite(tmp_path, monkeypatch, control_period=0.005,
                       criterion={"kind": "path_tolerance", "settle_time_s": 0.1, "cross_track_m": 5.0}).plan.runs[0]
    assert own.scenario.control_period == 0.005 and own.scenario.plant.substeps == 5
    record = policy_episode(own.scenario, own.options)
    assert len(record["t"]) == 101 and criterion_of_record(record).evaluate(record)["passed"] is True
    from usv_mj.core.errors import SweepError

    with pytest.raises(SweepError, match="control_period 0.0015 s is not a whole number"):
        _probe_suite(tmp_path, monkeypatch, control_period=0.0015)
    with pytest.raises(SweepError, match="go with a policy"):
        plan_suite({"controllers": [{"kind": "ppc", "control_period": 0.01}], "tasks": [{"name": "a"}]})


#: published rigid-body masses [kg]: the paper's ship (ShipParams.m), CyberShip II (Skjetne et al.
#: 2004: 23.8 kg), the Otter (hull 55 + payload 25 kg, Fossen's otter.py), and Clarke's 2 m ship
#: m = rho C_b L B T = 1025 x 0.65 x 2.0 x 0.4 x 0.12
MASSES = {"cybership2": 23.8, "otter": 80.0, "clarke83": 1025.0 * 0.65 * 2.0 * 0.4 * 0.12}


def test_the_default_suite_scores_every_vessel_that_has_landed():
    data = tomllib.loads(default_suite_path().read_text())
    # as load_suite() plans it (the file, its folder) at 1 episode per cell instead of 10: the same
    # plan, a tenth of the scenarios to build (tests/test_bench_run.py: the file says 10)
    suite = plan_suite({**data, "episodes": 1}, str(default_suite_path()), default_suite_path().parent)
    assert suite.vessels == ["paper", "cybership2", "otter", "clarke83"]
    n_ep, n_tasks, n_cond = 1, len(data["tasks"]), len(data["conditions"])
    policies = [c for c in suite.controllers if c.policy]
    kinds = [c for c in suite.controllers if not c.policy]
    assert [c.name for c in kinds] == ["ppc", "pi", "los"] and [c.name for c in policies] == ["ppo"]
    # a policy skips the harbour (obstacles): its rows are those of the other tasks
    assert len(suite.plan.runs) == n_ep * n_cond * len(suite.vessels) * (n_tasks * len(kinds) + (n_tasks - 1) * len(policies))
    assert suite.skipped == [("harbour", "ppo", "a policy's Track observation has no view of the obstacles")]
    for run in suite.plan.runs:
        vessel = run.values["vessel"]
        assert run.scenario.vessel.kind == vessel
        if vessel in MASSES:
            assert run.scenario.vessel.model.split.rigid[0] == pytest.approx(MASSES[vessel], rel=1e-12)
        if run.values["controller"] == "ppo":
            assert run.scenario.control_period == 0.01 and run.scenario.plant.substeps == 10
        else:
            assert run.scenario.control_period == 0.001 and run.scenario.plant.substeps == 1


def test_usv_mj_bench_prints_the_leaderboard_it_writes(tmp_path, monkeypatch, capsys):
    """The command end to end (a new folder, then --resume of the finished one): exit 0, and the
    leaderboard it prints is the one report.md opens with. The two commands that run episodes are
    processes of their own (their own cluster, as a user's); the ones that run none (--resume of a
    finished folder, the refusals) call the program in this process, which saves a start-up each."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from usv_mj.cli.main import main

    root = Path(__file__).resolve().parents[1]
    (tmp_path / "probe_policy_cli.py").write_text(PROBE)   # its own name: imported here too
    suite = tmp_path / "s.toml"
    suite.write_text('duration = 2.0\nepisodes = 1\nplant = "analytic"\nvessels = ["paper", "otter"]\n'
                     'controllers = ["ppc", { name = "probe", policy = "probe_policy_cli:Probe" }]\n'
                     '[[tasks]]\nname = "line"\nsettle_time_s = 1.0\n'
                     'set = { "trajectory.kind" = "line", "initial.eta" = [0.0, 0.5, 0.0] }\n')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(tmp_path)])}
    out = tmp_path / "out"
    args = ["bench", str(suite), "--out", str(out), "--workers", "1", "--no-progress", "--no-figures"]
    cmd = [sys.executable, "-m", "usv_mj.cli.main", *args]
    done = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "INFO:distributed" not in done.stderr   # the scheduler's start-up stays quiet
    printed = [line for line in done.stdout.splitlines() if line.startswith("|")]
    report = (out / "report.md").read_text()
    assert printed and "\n".join(printed[:4]) in report
    assert "| vessel | `ppc` | `probe` |" in printed and any(line.startswith("| otter |") for line in printed)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))   # the policy's module, as PYTHONPATH gives it above
    capsys.readouterr()
    assert main(args + ["--resume"]) == 0
    again = capsys.readouterr()
    assert "4 episodes (0 run now)" in again.out and "INFO:distributed" not in again.err, again.err
    assert main(args) == 2
    assert "pass --overwrite" in capsys.readouterr().err
    replaced = subprocess.run(cmd + ["--overwrite"], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=300)
    assert replaced.returncode == 0 and "4 episodes (4 run now)" in replaced.stdout, replaced.stderr
    assert (out / "report.md").read_text() == report   # the same suite again: the same leaderboard
    assert main(args + ["--overwrite", "--resume"]) == 2
    assert "give one of them" in capsys.readouterr().err
