"""Benchmark of the MuJoCo plant and of the closed loop on it (issue 3).

    python benchmarks/bench_mujoco.py [--duration 30] [--repeat 3]

Prints, in one run, per 1 ms control step (best of ``--repeat`` timings, microseconds):

- the bare ``mujoco.mj_step`` of models/usv.xml with no callback (the yardstick);
- ``mj_step`` with the native hydrodynamic callback installed (4 callback calls per RK4 step);
- ``MuJoCoPlant.step`` + ``.state`` (what the loop pays), native and Python callback;
- the analytic plant step + state, for comparison;
- the PPC controller call (PPCController.__call__) and the reference evaluation;
- the whole closed loop: ``simulate`` on the ``paper`` preset for ``--duration`` seconds, on both
  plants, with the realtime factor and the projection to the 300 s paper run.

The machine may be shared: the figures are as good as its load at the time (printed first).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def best_per_call(fn, n: int, repeat: int) -> float:
    fn()
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=30.0, help="closed-loop run length [s] (default 30)")
    ap.add_argument("--repeat", type=int, default=3, help="timings per figure; the best is printed")
    ap.add_argument("-n", type=int, default=20000, help="calls per timing")
    args = ap.parse_args(argv)

    import mujoco

    from usv_mj.plants.analytic import AnalyticPlant
    from usv_mj.plants.mujoco_plant import DEFAULT_MODEL, MuJoCoPlant
    from usv_mj.scenario import load_scenario
    from usv_mj.simulation import make_controller, make_reference, simulate

    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; mujoco {mujoco.__version__}")
    scenario = load_scenario(preset="paper")
    n, rep = args.n, args.repeat

    rows: list[tuple[str, float]] = []
    model = mujoco.MjModel.from_xml_path(DEFAULT_MODEL)
    data = mujoco.MjData(model)
    data.ctrl[:] = (60.0, 1.0)
    mujoco.set_mjcb_passive(None)
    rows.append(("bare mj_step, no callback (RK4, 1 ms)", best_per_call(lambda: mujoco.mj_step(model, data), n, rep)))

    with MuJoCoPlant(scenario.ship, scenario.disturbance, scenario.control_period) as plant:
        plant.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))
        plant.data.ctrl[:] = (60.0, 1.0)
        m, d = plant.model, plant.data
        rows.append(("mj_step with the native callback", best_per_call(lambda: mujoco.mj_step(m, d), n, rep)))

        def plant_step():
            plant.step(60.0, 1.0)
            return plant.state

        rows.append(("MuJoCoPlant.step + .state (native)", best_per_call(plant_step, n, rep)))
    with MuJoCoPlant(scenario.ship, scenario.disturbance, scenario.control_period, callback="python") as plant:
        plant.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))

        def plant_step_py():
            plant.step(60.0, 1.0)
            return plant.state

        rows.append(("MuJoCoPlant.step + .state (Python callback)", best_per_call(plant_step_py, n // 4, rep)))
    analytic = AnalyticPlant(scenario.ship, scenario.disturbance, scenario.control_period)
    analytic.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))

    def analytic_step():
        analytic.step(60.0, 1.0)
        return analytic.state

    rows.append(("AnalyticPlant.step + .state", best_per_call(analytic_step, n, rep)))

    controller = make_controller(scenario)
    reference = make_reference(scenario)
    x = np.array([2.0, -3.0, 0.0, 0.1, 0.0, 0.0])
    ref = reference.evaluate(1.0)
    rows.append(("PPC controller call", best_per_call(lambda: controller(1.0, x, ref), n, rep)))
    rows.append(("reference evaluate", best_per_call(lambda: reference.evaluate(12.3), n, rep)))

    loops = {}
    short = scenario.with_overrides({"duration": min(args.duration, scenario.duration)})
    simulate(short.with_overrides({"duration": 1.0}), plant_kind="mujoco")  # compile / cache load
    simulate(short.with_overrides({"duration": 1.0}), plant_kind="analytic")
    for kind in ("mujoco", "analytic"):
        best = None
        for _ in range(max(1, rep - 1)):
            rec = simulate(short, plant_kind=kind)
            if best is None or rec.metadata["wall_time_s"] < best.metadata["wall_time_s"]:
                best = rec
        steps = best.n_rows - 1
        loops[kind] = (best.metadata["wall_time_s"], steps)
        rows.append((f"closed-loop step, simulate(paper), {kind} plant", best.metadata["wall_time_s"] / steps))

    yard = rows[0][1]
    print(f"\n{'per 1 ms control step':52s} {'us':>9s} {'x bare':>8s}")
    for name, sec in rows:
        print(f"{name:52s} {sec * 1e6:9.2f} {sec / yard:8.2f}")
    ctrl_us = dict(rows)["PPC controller call"]
    loop_us = dict(rows)["closed-loop step, simulate(paper), mujoco plant"]
    plant_us = dict(rows)["MuJoCoPlant.step + .state (native)"]
    print(f"\nshares of the MuJoCo closed-loop step: plant {plant_us / loop_us:.0%}, controller "
          f"{ctrl_us / loop_us:.0%}, rest of the loop (reference, quantizer, recording, checks) "
          f"{1 - (plant_us + ctrl_us) / loop_us:.0%}")
    for kind, (wall, steps) in loops.items():
        sim = steps * scenario.control_period
        print(f"paper preset, {sim:.0f} s on the {kind} plant: {wall:.2f} s wall, realtime factor {sim / wall:.0f}x; "
              f"projected 300 s run: {wall * 300.0 / sim:.1f} s wall")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
