"""Benchmark throughput: episodes per minute of ``usv-mj bench`` beside the sweep's runs per minute,
the same runs on the same engine (one 2-worker LocalCluster of the sweep's ``open_client``).

    python benchmarks/bench_bench.py [--episodes 16] [--duration 30] [--workers 2] [--repeat 2]

The same N runs (the paper preset on a line, the analytic plant, the start's lateral offset drawn
uniformly) are run as

- a sweep (:func:`usv_mj.jobs.sweep.runner.run_sweep` of a sweep table), and
- a benchmark suite of one task, one condition, one controller and N episodes
  (:func:`usv_mj.jobs.bench.run_bench`: the same ``run_sweep`` with the metrics computed on the workers),
  its leaderboard (report.md, figures) timed apart.

Each is timed from the first submission to the last result (``SweepResult.timing["runs_s"]``, the
start-up apart), best of ``--repeat`` passes, alternating, on one cluster. The benchmark's own
overhead is (its time - the sweep's) / the sweep's: the metrics of every episode (the row hook); the
same ratio of the time spent inside the tasks is printed too (the sum of ``task_wall_time_s``).
The machine is shared: the load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--duration", type=float, default=30.0, help="s of each run")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()

    from usv_mj.jobs.bench import run_bench
    from usv_mj.jobs.bench.report import write_report
    from usv_mj.jobs.bench.suite import plan_suite
    from usv_mj.jobs.sweep import plan_sweep, run_sweep
    from usv_mj.jobs.sweep.runner import open_client

    sets = {"trajectory.kind": "line", "initial.eta": [0.0, 0.0, 0.0], "baseline.enabled": False}
    sweep = plan_sweep({"base": "paper", "duration": args.duration, "plant": "analytic", "samples": args.episodes,
                        "seed": 1, "set": sets, "vary": {"initial.eta[1]": {"uniform": [-3.0, 3.0]}}})
    suite = plan_suite({"episodes": args.episodes, "seed": 1, "duration": args.duration, "plant": "analytic",
                        "controllers": ["ppc"], "tasks": [{"name": "line", "base": "paper", "set": sets,
                                                           "vary": {"initial.eta[1]": {"uniform": [-3.0, 3.0]}}}]})
    tmp = Path(tempfile.mkdtemp(prefix="bench_bench-"))
    best = {"sweep": float("inf"), "bench": float("inf"), "report": float("inf"),
            "sweep_task": float("inf"), "bench_task": float("inf")}
    try:
        with open_client(workers=args.workers, echo=None) as client:
            for i in range(args.repeat):
                r = run_sweep(sweep, tmp / f"sweep{i}", client=client, progress=False, echo=None, report=False)
                best["sweep"] = min(best["sweep"], r.timing["runs_s"])
                best["sweep_task"] = min(best["sweep_task"], sum(row["task_wall_time_s"] for row in r.rows))
                r = run_bench(suite, tmp / f"bench{i}", client=client, progress=False, echo=None, report=False)
                best["bench"] = min(best["bench"], r.timing["runs_s"])
                best["bench_task"] = min(best["bench_task"], sum(row["task_wall_time_s"] for row in r.rows))
                t0 = time.perf_counter()
                write_report(tmp / f"bench{i}", r.rows, suite)
                best["report"] = min(best["report"], time.perf_counter() - t0)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    n = args.episodes
    load = os.getloadavg()
    print(f"{n} runs of {args.duration:g} s (paper preset on a line, analytic plant, 1 ms control period) on "
          f"{args.workers} workers, best of {args.repeat}; load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")
    print(f"  sweep:     {best['sweep']:6.1f} s  {60 * n / best['sweep']:6.1f} runs/min")
    print(f"  benchmark: {best['bench']:6.1f} s  {60 * n / best['bench']:6.1f} episodes/min  "
          f"(own overhead {100 * (best['bench'] - best['sweep']) / best['sweep']:+.1f} %: the metrics on the workers)")
    print(f"  inside the tasks (the sum of task_wall_time_s, less exposed to the scheduling on a shared machine): "
          f"sweep {best['sweep_task']:.1f} s, benchmark {best['bench_task']:.1f} s "
          f"({100 * (best['bench_task'] - best['sweep_task']) / best['sweep_task']:+.1f} %)")
    print(f"  leaderboard (report.md, leaderboard.json, figures incl. the worst episode run again): {best['report']:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
