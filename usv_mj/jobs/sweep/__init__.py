"""Monte-Carlo sweeps and capability plots on Dask.

    usv-mj sweep SWEEP.toml --out DIR [--workers N | --scheduler ADDRESS | --jobqueue slurm --jobs N]
                 [--resume] [--keep-logs] [--max-runs N]
    usv-mj capability --load disturbance|current|wind|waves --out DIR [--base paper] [--duration S]

A sweep file names a base and what varies, by dotted path into the scenario (docs/model.md §7)::

    base = "paper"                 # preset or scenario file
    duration = 60.0
    samples = 50                   # draws per grid point
    seed = 7
    [vary]
    "initial.eta[0]" = { uniform = [-8.0, 8.0] }      # uniform, loguniform, normal, integers, choice
    "disturbance.scale" = [1e-4, 5e-4, 1e-3]          # a list is a grid axis

Every sampled scenario is validated before anything runs (a bad path or range: exit 2). Each run
is one Dask task; its row (varied values, status ok/diverged/failed and why, every summary.json
field) streams into DIR/results.parquet; --resume runs only the missing ones; DIR/report.md has the
rate of runs that passed their controller's criterion (Wilson 95 %), error histograms, scatter plots
and the failures. By default a local cluster with one worker process per core; --scheduler tcp://HOST:8786 uses any running Dask cluster
(``dask scheduler`` on one machine, ``dask worker tcp://HOST:8786 --nthreads 1 --nworkers N`` on
each other, every one with usv_mj installed); --jobqueue uses a batch system via dask-jobqueue.

Python API::

    from usv_mj.jobs.sweep import load_sweep, run_sweep, read_results
    plan = load_sweep("examples/sweeps/start_pose.toml")   # sampled and validated, nothing run yet
    result = run_sweep(plan, "out/start_pose", workers=2)   # DIR/results.parquet + DIR/report.md
    rows, _ = read_results("out/start_pose/results.parquet")

The sweep file format is in :mod:`usv_mj.jobs.sweep.spec`; the row columns in :mod:`usv_mj.jobs.sweep.runner`;
the capability search in :mod:`usv_mj.jobs.sweep.capability` (its loads in :mod:`usv_mj.jobs.sweep.loads`);
the commands in :mod:`usv_mj.cli.sweep` and :mod:`usv_mj.cli.capability`. The names below load on first
use (Dask only when a sweep runs).
"""

from __future__ import annotations

from usv_mj.core.lazy_names import lazy_names

__getattr__, __dir__, _ = lazy_names(__name__, {name: ".spec" for name in
                                                ("SweepError", "SweepPlan", "load_sweep", "parse_path", "plan_sweep")})
__all__ = ["SweepError", "SweepPlan", "load_sweep", "plan_sweep", "parse_path", "run_sweep", "read_results"]


def run_sweep(*args, **kwargs):
    """See :func:`usv_mj.jobs.sweep.runner.run_sweep` (imported lazily: Dask loads only when a sweep runs)."""
    from usv_mj.jobs.sweep.runner import run_sweep as _run

    return _run(*args, **kwargs)


def read_results(path):
    """See :func:`usv_mj.jobs.sweep.runner.read_results`: (rows sorted by run id, plan fingerprint)."""
    from usv_mj.jobs.sweep.runner import read_results as _read

    return _read(path)
