"""Benchmark: simulated seconds per wall second of the paper run, per plant, with the parts of a step.

    python benchmarks/bench_core.py [--duration 300] [--plant analytic] [--plant mujoco]

Prints the bare MuJoCo step (the yardstick, when mujoco is installed), the controller call, the
quantizer, the reference and the whole closed loop, so that ratios show where the time goes.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def per_call(fn, n=20000):
    fn()
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--plant", action="append", choices=("analytic", "mujoco"))
    args = ap.parse_args()
    plants = args.plant or ["analytic", "mujoco"]

    from usv_mj import load_scenario, simulate
    from usv_mj.simulation import make_controller, make_plant, make_quantizers, make_reference

    scenario = load_scenario(preset="paper", overrides={"duration": args.duration})
    simulate(scenario.with_overrides({"duration": 1.0}), plant_kind="analytic")  # numba compile / cache load

    rows = []
    try:
        import mujoco

        from pathlib import Path
        model = mujoco.MjModel.from_xml_path(str(Path(__file__).resolve().parents[1] / "models" / "usv.xml"))
        data = mujoco.MjData(model)
        data.ctrl[:] = (10.0, 0.5)[: model.nu]
        rows.append(("bare mujoco.mj_step (no callback), 1 ms RK4", per_call(lambda: mujoco.mj_step(model, data))))
    except Exception as exc:  # the yardstick is optional for the analytic benchmark
        print(f"(no bare MuJoCo yardstick: {exc})")

    ctrl = make_controller(scenario)
    ref = make_reference(scenario)
    x = np.array([2.0, -3.0, 0.0, 0.1, 0.0, 0.0])
    r = ref.evaluate(1.0)
    rows.append(("PPC controller call", per_call(lambda: ctrl(1.0, x, r))))
    rows.append(("reference evaluate", per_call(lambda: ref.evaluate(123.4))))
    qu, _ = make_quantizers(scenario)
    rows.append(("quantizer step", per_call(lambda: qu.step(12.3))))
    for kind in plants:
        try:
            plant = make_plant(scenario, kind)
        except Exception as exc:
            print(f"({kind} plant unavailable: {exc})")
            continue
        plant.reset((2, -3, 0), (0, 0, 0))
        rows.append((f"{kind} plant step (1 ms)", per_call(lambda: plant.step(10.0, 0.5), 5000)))
        plant.close()
    yard = rows[0][1]
    print(f"{'part':48s} {'us/call':>10s} {'x bare step':>12s}")
    for name, sec in rows:
        print(f"{name:48s} {sec * 1e6:10.2f} {sec / yard:12.2f}")
    print()
    for kind in plants:
        try:
            rec = simulate(scenario, plant_kind=kind)
        except Exception as exc:
            print(f"({kind}: {exc})")
            continue
        wall = rec.metadata["wall_time_s"]
        print(f"paper run, {args.duration:.0f} s on the {kind} plant: {wall:.2f} s wall, "
              f"{rec.metadata['realtime_factor']:.0f} simulated s per wall s, "
              f"{wall / len(rec) * 1e6:.2f} us per closed-loop step")


if __name__ == "__main__":
    main()
