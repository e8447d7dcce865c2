"""Sweep throughput: runs per minute of a sweep file on a local Dask cluster, the start-up apart,
beside a plain loop in one process and the bare mj_step.

    python benchmarks/bench_sweep.py [--sweep examples/sweeps/quick.toml] [--workers 1 2] [--repeat 3]
                                     [--samples N]

The sweep file's runs (``--samples`` replaces its draws per grid point, for steadier figures), the
same runs in every mode:

- the bare RK4 ``mujoco.mj_step`` of models/usv.xml (the project's yardstick), measured here at the
  start and at the end (the load on the machine varies);
- a plain loop in this process calling the sweep's own task function
  (:func:`usv_mj.jobs.sweep.runner.run_one`) run after run;
- :func:`usv_mj.jobs.sweep.runner.run_sweep` on a ``LocalCluster`` made by the sweep's own
  :func:`~usv_mj.jobs.sweep.runner.open_client`, for each ``--workers``. The start-up is printed apart:
  the cluster's start (worker processes, their imports), and the warm-up that ``run_sweep`` does
  before the first task (the first run's scenario for a few steps here, then on every worker: the
  imports and the compiled loop loaded, or compiled once into the disk cache). The runs per minute
  are from the first submission to the last result (``SweepResult.timing["runs_s"]``), best of
  ``--repeat`` passes on the same cluster. The engine's overhead per run is (wall time x workers -
  the time spent inside the tasks) / runs: worker time spent on anything but the runs (scheduling,
  transfer, parquet). "us per step" is the wall time x workers / control steps run: comparable to
  the bare mj_step.

The machine has 2 cores and is shared: note the load average printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def bare_mj_step(n: int = 20000, repeat: int = 3) -> float:
    """Best seconds per ``mujoco.mj_step`` of models/usv.xml (RK4, 1 ms, no callback), CPU time."""
    import mujoco

    from usv_mj.plants.mujoco_plant import DEFAULT_MODEL

    model = mujoco.MjModel.from_xml_path(str(DEFAULT_MODEL))
    data = mujoco.MjData(model)
    data.ctrl[:] = (60.0, 1.0)
    saved = mujoco.get_mjcb_passive()
    mujoco.set_mjcb_passive(None)
    try:
        best = float("inf")
        for _ in range(repeat):
            mujoco.mj_step(model, data)
            t0 = time.thread_time()
            for _ in range(n):
                mujoco.mj_step(model, data)
            best = min(best, (time.thread_time() - t0) / n)
    finally:
        mujoco.set_mjcb_passive(saved)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", default=str(ROOT / "examples" / "sweeps" / "quick.toml"), help="the sweep file")
    parser.add_argument("--samples", type=int, default=None, help="draws per grid point (default: the file's)")
    parser.add_argument("--workers", type=int, nargs="+", default=[2])
    parser.add_argument("--repeat", type=int, default=3, help="best of this many passes in each mode")
    args = parser.parse_args()

    import tomllib

    from usv_mj.jobs.sweep import plan_sweep
    from usv_mj.jobs.sweep.runner import describe_startup, open_client, run_one, run_sweep, warm_up

    path = Path(args.sweep)
    data = tomllib.loads(path.read_text())
    if args.samples is not None:
        data["samples"] = args.samples
    plan = plan_sweep(data, source=str(path), directory=path.parent)
    runs = len(plan.runs)
    steps = sum(int(round(r.scenario.duration / r.scenario.control_period)) for r in plan.runs)
    print(f"{path.name}: {runs} runs ({plan.base.duration:g} s, {plan.base.plant.kind} plant, {steps} control "
          f"steps in all); cores: {os.cpu_count()}; load average before: {os.getloadavg()[0]:.2f}")
    bare = bare_mj_step()
    print(f"bare mujoco.mj_step (models/usv.xml, RK4 1 ms): {bare * 1e6:.2f} us / step (yardstick)")
    w = warm_up(plan.runs[0].scenario)
    print(f"warm-up in this process: {w['seconds']:.2f} s ({w.get('loop') or w.get('error')} loop"
          f"{': ' + w['loop_reason'] if w.get('loop_reason') else ''})")

    def figures(wall: float, workers: int) -> str:
        per_step = wall * workers / steps
        return (f"{60 * runs / wall:7.1f} runs/min, {per_step * 1e6:5.2f} us per step per worker = "
                f"{per_step / bare:4.2f}x bare mj_step")

    loops = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        for run in plan.runs:
            row = run_one(run.run_id, run.scenario, run.values, {"transient": plan.transient})
            assert row["status"] != "failed", row
        loops.append(time.perf_counter() - t0)
    loop = min(loops)
    print(f"plain loop, 1 process : {loop:6.2f} s = {figures(loop, 1)} "
          f"(best of {args.repeat}: {', '.join(f'{v:.2f}' for v in loops)} s)")

    out_root = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        for n in args.workers:
            t0 = time.perf_counter()
            with open_client(workers=n, echo=None) as client:
                client.wait_for_workers(n)
                start = time.perf_counter() - t0
                walls, overheads, startups = [], [], []
                for k in range(args.repeat):
                    result = run_sweep(plan, out_root / f"w{n}-{k}", client=client, progress=False, echo=None,
                                       report=False)
                    bad = [r for r in result.rows if r["status"] == "failed"]
                    assert not bad, bad[0]
                    wall = result.timing["runs_s"]
                    walls.append(wall)
                    startups.append(result.timing["startup"])
                    # time not spent inside the tasks, per run: submission, scheduling, transfer, parquet
                    overheads.append((wall * n - sum(r["task_wall_time_s"] for r in result.rows)) / runs)
            wall = min(walls)
            print(f"Dask, {n} worker(s)    : {wall:6.2f} s = {figures(wall, n)} (speed-up over the loop "
                  f"{loop / wall:.2f}x; best of {args.repeat}: {', '.join(f'{v:.2f}' for v in walls)} s)")
            first = dict(startups[0], cluster_s=start, total_s=start + startups[0]["total_s"])
            print(f"  {describe_startup(first)}")
            print(f"  engine overhead: {min(overheads) * 1000:.0f} ms per run (worker time outside the tasks, "
                  f"best pass)")
    finally:
        shutil.rmtree(out_root, ignore_errors=True)
    again = bare_mj_step()
    print(f"bare mujoco.mj_step again at the end: {again * 1e6:.2f} us / step; load average after: "
          f"{os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
