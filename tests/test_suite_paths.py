"""The rough edges of issue 37, item 5, for sweeps and suites:

- a sweep's (or a suite task's) ``"controller.kind"`` that switches the law takes the new kind's keys
  only, as ``run --set controller.kind=...`` does (the paper preset's PPC gains used to stay behind:
  "unknown key 'controller.l1'");
- a suite's data files (``vessels = ["boats/boat.toml"]``, a task's ``"vessel.kind"``) are found next
  to the suite file, from any working folder;
- ``usv-mj bench --out DIR --compare A B`` reads the suite from the results folder: no suite file again.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from usv_mj.core.errors import SweepError
from usv_mj.jobs.sweep.spec import plan_sweep

REPO = Path(__file__).resolve().parent.parent
WAMV = REPO / "examples" / "vessels" / "wamv.toml"


def test_a_sweep_that_switches_the_controller_kind_takes_the_new_kinds_keys_only():
    plan = plan_sweep({"base": "paper", "duration": 2.0, "set": {"controller.kind": "los", "controller.lookahead": 4.0}})
    assert plan.base.controller.kind == "los" and plan.base.controller.gains.lookahead == 4.0
    plan = plan_sweep({"base": "paper", "duration": 2.0, "set": {"controller.kind": "pi"},
                       "vary": {"controller.kp_u": [100.0, 250.0]}})
    assert [r.scenario.controller.gains.kp_u for r in plan.runs] == [100.0, 250.0]
    plan = plan_sweep({"base": "paper", "duration": 2.0, "vary": {"controller.kind": ["los", "ppc", "pi"]}})
    assert [r.scenario.controller.kind for r in plan.runs] == ["los", "ppc", "pi"]
    assert plan.runs[1].scenario.controller.gains.gamma_u == 1e3   # the preset's own PPC gains stay with PPC
    # the same for a module:Name plug-in, and the baseline
    plan = plan_sweep({"base": "paper", "duration": 2.0,
                       "set": {"controller.kind": "usv_mj.controllers.los:LOSController", "baseline.kind": "los"}})
    assert plan.base.baseline.kind == "los" and plan.base.baseline.enabled
    # a key of the old kind given with the switch is still refused, naming it
    with pytest.raises(SweepError, match="controller.l1"):
        plan_sweep({"base": "paper", "duration": 2.0, "set": {"controller.kind": "los", "controller.l1": 2.0}})


def test_a_trajectory_kind_switch_keeps_only_the_keys_the_new_kind_has():
    plan = plan_sweep({"base": "paper", "duration": 2.0, "set": {"trajectory.kind": "circle", "trajectory.radius": 9.0}})
    assert plan.base.trajectory.kind == "circle" and plan.base.trajectory.radius == 9.0
    assert plan.base.trajectory.speed == 0.6   # the paper's speed, a key the circle has too


def _suite_text(vessel: str) -> str:
    return f"""
episodes = 1
duration = 3.0
plant = "analytic"
controllers = ["pi"]
vessels = ["{vessel}"]
[[tasks]]
name = "line"
set = {{ "trajectory.kind" = "line", "initial.eta" = [0.0, 0.0, 0.0], "controller.kind" = "los" }}
[[tasks]]
name = "line-own"
set = {{ "trajectory.kind" = "line", "vessel.kind" = "{vessel}" }}
"""


def test_a_suites_data_files_are_found_next_to_the_suite(tmp_path, monkeypatch):
    from usv_mj.jobs.bench.suite import load_suite

    folder = tmp_path / "study"
    (folder / "boats").mkdir(parents=True)
    shutil.copy(WAMV, folder / "boats" / "boat.toml")
    (folder / "suite.toml").write_text(_suite_text("boats/boat.toml"))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)   # nothing is found by the working folder
    suite = load_suite(folder / "suite.toml")
    want = str((folder / "boats" / "boat.toml").resolve())
    assert {r.scenario.vessel.kind for r in suite.plan.runs} == {want}
    assert {r.values["vessel"] for r in suite.plan.runs} == {"boats/boat.toml"}   # named as the suite names it
    assert suite.plan.runs[0].scenario.vessel.model.dimensions.L == 4.9
    # the task's set switched the kind of the suite's controller (pi) to LOS: LOS's keys only
    assert {r.scenario.controller.kind for r in suite.plan.runs if r.values["task"] == "line"} == {"pi"}


def test_bench_compare_reads_the_suite_from_the_results_folder(tmp_path, capsys):
    from usv_mj.cli.main import main
    from usv_mj.jobs.bench import run_bench
    from usv_mj.jobs.bench.suite import load_suite

    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "suite.toml").write_text("""
episodes = 2
duration = 3.0
plant = "analytic"
controllers = ["pi", { name = "pi-2", kind = "pi", set = { "controller.kp_u" = 150.0 } }]
[[tasks]]
name = "line"
set = { "trajectory.kind" = "line", "initial.eta" = [0.0, 0.0, 0.0] }
""")
    out = tmp_path / "out"
    run_bench(load_suite(folder / "suite.toml"), out, workers=1, progress=False, echo=None, draw=False)
    os.chdir(tmp_path)
    assert main(["bench", "--out", str(out), "--compare", "pi", "pi-2"]) == 0
    text = capsys.readouterr().out
    assert "suite " + str(folder / "suite.toml") in text and "Holm-Bonferroni within each cell" in text
    # the suite given again must be the folder's
    other = folder / "other.toml"
    other.write_text((folder / "suite.toml").read_text().replace("episodes = 2", "episodes = 3"))
    assert main(["bench", str(other), "--out", str(out), "--compare", "pi", "pi-2"]) == 2
    assert "another suite" in capsys.readouterr().err


def test_overrides_that_switch_the_kind_drop_a_files_own_gains(tmp_path):
    """The same rule for a scenario file's own [controller] gains under --set / load_scenario(overrides=)
    / Scenario.with_overrides (compare's saturated case switches a LOS scenario to PPC this way)."""
    from usv_mj import load_scenario

    f = tmp_path / "ppc.toml"
    f.write_text('preset = "paper"\n[controller]\nkind = "ppc"\nk1 = 4.0\n')
    sc = load_scenario(f, overrides={"controller": {"kind": "los", "lookahead": 5.0}})
    assert sc.controller.kind == "los" and sc.controller.gains.lookahead == 5.0
    back = sc.with_overrides({"controller": {"kind": "ppc"}})
    assert back.controller.kind == "ppc" and back.controller.gains.k1 == 3.0   # the preset's, not the file's
    assert load_scenario(f, overrides={"controller": {"k3": 9.0}}).controller.gains.k1 == 4.0   # no switch: kept
