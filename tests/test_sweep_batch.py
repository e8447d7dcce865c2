"""A sweep's runs in batches (issue 36 item 3): one Dask task runs several episodes in one compiled batch
(usv_mj.jobs.sweep.runner.run_many) and the rows are those of one task per run; resume still counts
episodes."""

from __future__ import annotations

import pytest

from usv_mj.jobs.sweep import load_sweep
from usv_mj.jobs.sweep.runner import TIMING_COLUMNS, read_results, run_many, run_one, run_sweep

SWEEP = """
base = "paper"
duration = 1.5
plant = "analytic"
samples = 3
seed = 11
transient = 0.5
[vary]
"initial.eta[0]" = { uniform = [-4.0, 4.0] }
"disturbance.scale" = [1e-4, 1e-3]
"limits.max_distance" = [4.5, 50.0]
"""


def _comparable(rows):
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


def _plan(tmp_path):
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    return load_sweep(path)


def test_run_many_gives_the_rows_of_run_one(tmp_path):
    plan = _plan(tmp_path)
    options = {"transient": plan.transient}
    runs = [(r.run_id, r.scenario, r.values, {**options, **r.options}) for r in plan.runs]
    alone = [run_one(*run) for run in runs]
    together = run_many(runs)
    assert _comparable(together) == _comparable(alone)
    assert {r["status"] for r in alone} == {"ok", "diverged"}   # both kinds of end in one batch
    assert all(r["task_wall_time_s"] > 0 for r in together)


def test_a_batched_sweep_and_its_resume_give_the_table_of_one_task_per_run(tmp_path):
    from distributed import Client, LocalCluster

    plan = _plan(tmp_path)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        one = run_sweep(plan, tmp_path / "one", client=client, progress=False, echo=None, report=False)
        part = run_sweep(plan, tmp_path / "part", client=client, progress=False, echo=None, report=False,
                         batch=5, max_runs=5)
        assert not part.complete and part.ran == 5
        rest = run_sweep(plan, tmp_path / "part", client=client, progress=False, echo=None, report=False,
                         batch=5, resume=True)
    assert rest.ran == len(plan.runs) - 5   # episodes are still the unit of resume
    a, _ = read_results(tmp_path / "one" / "results.parquet")
    b, _ = read_results(tmp_path / "part" / "results.parquet")
    assert len(a) == len(plan.runs) == 12
    assert _comparable(a) == _comparable(b)


@pytest.mark.parametrize("options", [{"log_path": "x.mcap"}, {"episode_fn": "m:f"}, {"hooks": {"raise": [0]}}])
def test_what_is_not_batched(options):
    from usv_mj.jobs.sweep.runner import batchable

    assert batchable({"transient": 2.0}) and not batchable(options)
