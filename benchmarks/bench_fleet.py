"""The cost of a run of several vessels: wall seconds per simulated second for 1, 2, 4 and 8 vessels
on both plants, the encounter measures of every pair included, beside the bare ``mj_step`` of the
same MuJoCo model (issue 35: the cost must grow no worse than linearly in the vessels).

    python benchmarks/bench_fleet.py [--duration 20] [--repeat 2]

Each vessel keeps course and speed (LOS on a line) on its own lane, far from the others (no
contact), at a 0.05 s control period; the figure is the best of ``--repeat`` runs after a warm-up
run (numba compiled once). "per vessel" divides by the vessels; "pairs" is the encounter measures'
share (usv_mj.record.encounters.encounter_summary: every pair's geometry at every row).
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco

from usv_mj import load_scenario, simulate
from usv_mj.builder import build_fleet
from usv_mj.record.encounters import encounter_summary


def fleet_scenario(n: int, plant: str, duration: float):
    vessels = [{"name": f"v{i}", "steer": "keep", "initial": {"eta": [60.0 * i, 0.0, math.pi / 2], "nu": [0.6, 0, 0]}}
               for i in range(n)]
    return load_scenario(preset="paper", overrides={"duration": duration, "control_period": 0.05,
                                                    "plant": {"kind": plant}, "vessels": vessels})


def bare_mj_step(n: int, duration: float, dt: float = 0.05) -> float:
    """Wall seconds per simulated second of mj_step alone on the fleet's MuJoCo model of n hulls."""
    with build_fleet(fleet_scenario(n, "mujoco", duration)) as parts:
        for i, v in enumerate(parts.vessels):   # each hull on its lane (not all at the origin, in contact)
            parts.plant.reset_vessel(i, v.scenario.initial.eta, v.scenario.initial.nu)
        m, d = parts.plant.model, parts.plant.data
        steps = int(duration / dt)
        t0 = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(m, d)
        return (time.perf_counter() - t0) / duration


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds per run")
    ap.add_argument("--repeat", type=int, default=2, help="runs per figure (the best is printed)")
    ap.add_argument("--vessels", default="1,2,4,8")
    args = ap.parse_args(argv)
    counts = [int(v) for v in args.vessels.split(",")]
    print(f"{'plant':8s} {'vessels':>7s} {'wall/sim s':>11s} {'per vessel':>11s} {'pairs':>8s} {'bare mj_step':>13s}")
    for plant in ("analytic", "mujoco"):
        encounter_summary(simulate(fleet_scenario(2, plant, 1.0)))   # warm-up: compile
        for n in counts:
            best, pairs = math.inf, math.inf
            for _ in range(args.repeat):
                sc = fleet_scenario(n, plant, args.duration)
                t0 = time.perf_counter()
                record = simulate(sc)
                t1 = time.perf_counter()
                encounter_summary(record)
                t2 = time.perf_counter()
                best = min(best, (t2 - t0) / args.duration)
                pairs = min(pairs, (t2 - t1) / args.duration)
            bare = bare_mj_step(n, args.duration) if plant == "mujoco" else math.nan
            print(f"{plant:8s} {n:7d} {best:11.4f} {best / n:11.4f} {pairs:8.4f} {bare:13.5f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
