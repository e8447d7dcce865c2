"""Sweep throughput: runs per minute on Dask with 1 and 2 workers, beside a plain loop in one process.

    python benchmarks/bench_sweep.py [--runs 24] [--duration 10] [--workers 1 2]

Each run is the paper scenario on the analytic plant (``--plant mujoco`` for MuJoCo's; ``--duration`` s of
simulated time) with a
sampled start pose, the same runs in every mode. The plain loop calls the sweep's own task function
(:func:`usv_mj.sweep.runner.run_one`) in this process, one run after the other. The Dask figures
are measured from the first submission to the last result written to ``results.parquet``, on a
LocalCluster whose workers have each done one warm-up run (numba's cache loaded); the cluster's
start-up is printed apart. The engine's overhead per run is (wall time x workers - the time spent inside
the tasks) / runs: the worker time spent on anything but the runs (scheduling, transfer, parquet).
Every mode is timed ``--repeat`` times and the best pass is kept (the machine is shared).

The machine has 2 cores and is shared: note the load average printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path


def _warm(duration: float, plant: str = "analytic") -> float:
    """One short run in this process (numba's cache is loaded or compiled)."""
    from usv_mj import load_scenario, simulate

    t0 = time.perf_counter()
    simulate(load_scenario(preset="paper", overrides={"duration": duration, "plant": {"kind": plant}}))
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=24)
    parser.add_argument("--duration", type=float, default=10.0, help="simulated seconds per run")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--plant", choices=("analytic", "mujoco"), default="analytic")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many passes in each mode")
    args = parser.parse_args()

    from distributed import Client, LocalCluster

    from usv_mj.sweep import plan_sweep
    from usv_mj.sweep.runner import run_one, run_sweep

    plan = plan_sweep({"base": "paper", "duration": args.duration, "plant": args.plant, "samples": args.runs,
                       "seed": 1, "vary": {"initial.eta[0]": {"uniform": [-5.0, 5.0]},
                                           "initial.eta[2]": {"uniform": [-1.0, 1.0]}}},
                      source="bench_sweep")
    print(f"{args.runs} runs of {args.duration:g} s (paper, {args.plant} plant); cores: {os.cpu_count()}; "
          f"load average before: {os.getloadavg()[0]:.2f}")
    first = _warm(args.duration, args.plant)
    print(f"warm-up run in this process: {first:.2f} s")

    loops = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        for run in plan.runs:
            row = run_one(run.run_id, run.scenario, run.values, {"transient": plan.transient})
            assert row["status"] == "ok", row
        loops.append(time.perf_counter() - t0)
    loop = min(loops)
    print(f"plain loop, 1 process : {loop:7.2f} s = {60 * args.runs / loop:7.1f} runs/min "
          f"({loop / args.runs * 1000:.0f} ms per run; best of {args.repeat}: {', '.join(f'{v:.2f}' for v in loops)} s)")

    out_root = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        for n in args.workers:
            t0 = time.perf_counter()
            with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                    Client(cluster) as client:
                client.wait_for_workers(n)
                start = time.perf_counter() - t0
                t1 = time.perf_counter()
                client.run(_warm, args.duration, args.plant)
                warm = time.perf_counter() - t1
                walls, overheads = [], []
                for k in range(args.repeat):
                    t2 = time.perf_counter()
                    result = run_sweep(plan, out_root / f"w{n}-{k}", client=client, progress=False, echo=None,
                                       report=False)
                    wall = time.perf_counter() - t2
                    bad = [r for r in result.rows if r["status"] != "ok"]
                    assert not bad, bad[0]
                    walls.append(wall)
                    # time not spent inside the tasks, per run: submission, scheduling, transfer, parquet
                    overheads.append((wall * n - sum(r["task_wall_time_s"] for r in result.rows)) / args.runs)
            wall = min(walls)
            print(f"Dask, {n} worker(s)    : {wall:7.2f} s = {60 * args.runs / wall:7.1f} runs/min "
                  f"(speed-up over the loop {loop / wall:.2f}x; best of {args.repeat}: "
                  f"{', '.join(f'{v:.2f}' for v in walls)} s; cluster start {start:.1f} s, worker warm-up {warm:.1f} s)")
            print(f"  engine overhead: {min(overheads) * 1000:.0f} ms per run (worker time outside the tasks, "
                  f"best pass)")
    finally:
        shutil.rmtree(out_root, ignore_errors=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
