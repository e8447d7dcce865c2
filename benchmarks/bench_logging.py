"""Cost of MCAP logging: the paper run with and without the run-log sink.

Prints, per plant (analytic; mujoco when usv_mj/plants/mujoco_plant.py exists): the loop's wall time
without logging, with logging (loop, then closing the file), the overhead in % of the bare run
(target < 20 %), the file size, and the time to read the file back (and that it reads back exactly).

    python benchmarks/bench_logging.py [--duration 300] [--plants analytic,mujoco] [--repeat 1]

The machine has 2 cores; the background writer uses the second one. Other processes running at the
same time inflate the overhead: say so when quoting the figures.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from usv_mj.record.run_record import COLUMNS  # noqa: E402
from usv_mj.outputs.log import RunLogWriter, read_run  # noqa: E402
from usv_mj.scenario.spec import load_scenario  # noqa: E402
from usv_mj.loop.simulate import simulate  # noqa: E402


def bench(plant: str, duration: float, repeat: int, background: bool, out_dir: Path) -> dict:
    scenario = load_scenario(preset="paper", overrides={"duration": duration, "plant": {"kind": plant}})
    simulate(scenario, duration=1.0)                     # JIT caches warm
    bare, logged, closing, bare_cpu, main_cpu, worker_cpu = [], [], [], [], [], []
    path = out_dir / f"bench_{plant}.mcap"
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        rec_bare = simulate(scenario)
        bare.append(time.perf_counter() - t0)
        bare_cpu.append(time.process_time() - c0)
        t0, c0 = time.perf_counter(), time.process_time()
        with RunLogWriter(path, scenario, background=background) as writer:
            rec = simulate(scenario, sinks=[writer.sink("main")])
            t1 = time.perf_counter()
        t2 = time.perf_counter()
        main_cpu.append(time.process_time() - c0)
        worker_cpu.append(writer.stats.get("cpu_s", float("nan")))
        logged.append(t1 - t0)
        closing.append(t2 - t1)
    size = path.stat().st_size
    t0 = time.perf_counter()
    log = read_run(path)
    read_s = time.perf_counter() - t0
    exact = len(log.record) == len(rec) and all(np.array_equal(log.record[c], rec[c], equal_nan=True) for c in COLUMNS)
    same_as_bare = all(np.array_equal(rec_bare[c], rec[c], equal_nan=True) for c in COLUMNS)
    b, lg, cl = min(bare), min(logged), min(closing)
    return {"plant": plant, "rows": len(rec), "bare_s": b, "loop_s": lg, "close_s": cl,
            "overhead_pct": 100.0 * (lg + cl - b) / b, "size_mb": size / 1e6, "read_s": read_s, "exact": exact,
            "same_as_bare": same_as_bare, "bare_cpu": min(bare_cpu), "main_cpu": min(main_cpu),
            "worker_cpu": min(worker_cpu)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds (paper run: 300)")
    ap.add_argument("--plants", default=None, help="comma list; default analytic, plus mujoco if present")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--foreground", action="store_true", help="write in the loop's process (no worker)")
    args = ap.parse_args()
    plants = args.plants.split(",") if args.plants else ["analytic"] + (
        ["mujoco"] if (ROOT / "usv_mj" / "plants" / "mujoco_plant.py").exists() else [])
    print(f"logging benchmark: paper preset, {args.duration:g} s at 1 ms, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f} at start, writer in {'foreground' if args.foreground else 'background'}")
    with tempfile.TemporaryDirectory() as tmp:
        for plant in plants:
            try:
                r = bench(plant, args.duration, args.repeat, not args.foreground, Path(tmp))
            except Exception as exc:  # noqa: BLE001 - report and go on with the next plant
                print(f"{plant}: failed: {type(exc).__name__}: {exc}")
                continue
            print(f"{r['plant']:>8}: {r['rows']} rows | bare {r['bare_s']:.2f} s | logged loop {r['loop_s']:.2f} s "
                  f"+ close {r['close_s']:.2f} s | overhead {r['overhead_pct']:+.1f} % (target < 20 %) | "
                  f"file {r['size_mb']:.1f} MB | read back {r['read_s']:.2f} s, bit-exact {r['exact']}, "
                  f"same rows as the bare run {r['same_as_bare']}")
            print(f"{'':>8}  CPU time: bare loop {r['bare_cpu']:.2f} s, logged loop (this process) {r['main_cpu']:.2f} s "
                  f"(+{100 * (r['main_cpu'] - r['bare_cpu']) / r['bare_cpu']:.1f} %), background writer "
                  f"{r['worker_cpu']:.2f} s ({100 * r['worker_cpu'] / r['bare_cpu']:.0f} % of the loop's; under 100 % "
                  f"it keeps up when a core is free)")
    print(f"load average at end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
