"""Benchmark of the MuJoCo plant and of the closed loop on it.

    python benchmarks/bench_mujoco.py [--duration 30] [--repeat 3]

Prints, in one run, per 1 ms control step (best of ``--repeat`` timings, microseconds of CPU time
of this thread, so that the figures mean something on a shared machine; the closed-loop runs are
reported in CPU time and in wall time, the realtime factor from both):

- the bare ``mujoco.mj_step`` of models/usv.xml with no callback (the yardstick);
- ``mj_step`` with the native hydrodynamic callback installed (4 callback calls per RK4 step);
- ``MuJoCoPlant.step`` + ``.state`` (what the loop pays), native and Python callback;
- the analytic plant step + state, for comparison;
- the PPC controller call (PPCController.__call__) and the reference evaluation;
- the whole closed loop: ``simulate`` on the ``paper`` preset for ``--duration`` seconds, on both
  plants, with the realtime factor and the projection to the 300 s paper run;
- the sea (docs/sea.md §6; :func:`sea_section`, alone with ``--sea-only``): the force kernel
  (``hydrodynamic_force`` against ``sea_force`` with 128 wave components, current and wind), the
  plant step (4 RK4 stages, so 4 kernel calls) calm / ``moderate`` waves / waves + current + wind on
  both plants, and ``simulate`` of the paper preset in the ``moderate`` sea on both plants with its
  realtime factor (aim: 50x on the MuJoCo plant).

The machine may be shared: the figures are as good as its load at the time (printed first).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def best_per_call(fn, n: int, repeat: int) -> float:
    """Best of ``repeat`` timings of ``n`` calls, in CPU seconds of this thread per call.

    CPU time (``time.thread_time``) rather than wall time: on a shared machine the wall clock also
    counts the time the process waits for a core.
    """
    fn()
    best = float("inf")
    for _ in range(repeat):
        t0 = time.thread_time()
        for _ in range(n):
            fn()
        best = min(best, (time.thread_time() - t0) / n)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=30.0, help="closed-loop run length [s] (default 30)")
    ap.add_argument("--repeat", type=int, default=3, help="timings per figure; the best is printed")
    ap.add_argument("-n", type=int, default=20000, help="calls per timing")
    ap.add_argument("--sea-only", action="store_true", help="only the sea section")
    args = ap.parse_args(argv)
    if args.sea_only:
        return sea_section(args)

    import mujoco

    from usv_mj.plants.analytic import AnalyticPlant
    from usv_mj.plants.mujoco_plant import DEFAULT_MODEL, MuJoCoPlant
    from usv_mj.scenario.spec import load_scenario
    from usv_mj.loop.simulate import make_controller, make_reference, simulate

    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; mujoco {mujoco.__version__}")
    scenario = load_scenario(preset="paper")
    n, rep = args.n, args.repeat

    model = mujoco.MjModel.from_xml_path(DEFAULT_MODEL)
    data = mujoco.MjData(model)
    data.ctrl[:] = (60.0, 1.0)
    controller = make_controller(scenario)
    reference = make_reference(scenario)
    x = np.array([2.0, -3.0, 0.0, 0.1, 0.0, 0.0])
    ref = reference.evaluate(1.0)
    analytic = AnalyticPlant(scenario.ship, scenario.disturbance, scenario.control_period)

    def one_round() -> list[tuple[str, float]]:
        """Every per-call figure once; rounds are repeated and the best of each figure is kept, so
        that a burst of load on the shared machine does not land on one figure only."""
        out = []
        mujoco.set_mjcb_passive(None)
        out.append(("bare mj_step, no callback (RK4, 1 ms)", best_per_call(lambda: mujoco.mj_step(model, data), n, 1)))
        with MuJoCoPlant(scenario.ship, scenario.disturbance, scenario.control_period) as plant:
            plant.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))
            plant.data.ctrl[:] = (60.0, 1.0)
            m, d = plant.model, plant.data
            out.append(("mj_step with the native callback", best_per_call(lambda: mujoco.mj_step(m, d), n, 1)))

            def plant_step():
                plant.step(60.0, 1.0)
                return plant.state

            out.append(("MuJoCoPlant.step + .state (native)", best_per_call(plant_step, n, 1)))
        with MuJoCoPlant(scenario.ship, scenario.disturbance, scenario.control_period, callback="python") as plant:
            plant.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))

            def plant_step_py():
                plant.step(60.0, 1.0)
                return plant.state

            out.append(("MuJoCoPlant.step + .state (Python callback)", best_per_call(plant_step_py, n // 4, 1)))
        analytic.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))

        def analytic_step():
            analytic.step(60.0, 1.0)
            return analytic.state

        out.append(("AnalyticPlant.step + .state", best_per_call(analytic_step, n, 1)))
        out.append(("PPC controller call", best_per_call(lambda: controller(1.0, x, ref), n, 1)))
        out.append(("reference evaluate", best_per_call(lambda: reference.evaluate(12.3), n, 1)))
        return out

    rounds = [one_round() for _ in range(rep)]
    rows: list[tuple[str, float]] = [(name, min(r[i][1] for r in rounds)) for i, (name, _) in enumerate(rounds[0])]

    loops = {}
    short = scenario.with_overrides({"duration": min(args.duration, scenario.duration)})
    simulate(short.with_overrides({"duration": 1.0}), plant_kind="mujoco")  # compile / cache load
    simulate(short.with_overrides({"duration": 1.0}), plant_kind="analytic")
    for kind in ("mujoco", "analytic"):
        for loop in ("python", "auto"):
            best = None
            for _ in range(max(1, rep - 1)):
                c0 = time.thread_time()
                rec = simulate(short, plant_kind=kind, loop=loop)
                cpu = time.thread_time() - c0
                if best is None or cpu < best[0]:
                    best = (cpu, rec.metadata["wall_time_s"], rec.n_rows - 1)
            name = "Python loop" if loop == "python" else "compiled loop"
            loops[f"simulate, {kind} plant, {name}"] = best
            rows.append((f"closed-loop step, simulate(paper), {kind}, {name}", best[0] / best[2]))

    yard = rows[0][1]
    print(f"\n{'per 1 ms control step (CPU time)':56s} {'us':>9s} {'x bare':>8s}")
    for name, sec in rows:
        print(f"{name:56s} {sec * 1e6:9.2f} {sec / yard:8.2f}")
    ctrl_us = dict(rows)["PPC controller call"]
    loop_us = dict(rows)["closed-loop step, simulate(paper), mujoco, Python loop"]
    plant_us = dict(rows)["MuJoCoPlant.step + .state (native)"]
    print(f"\nshares of the Python loop's step on the MuJoCo plant: plant {plant_us / loop_us:.0%}, controller "
          f"{ctrl_us / loop_us:.0%}, rest of the loop (reference, quantizers, recording, checks) "
          f"{1 - (plant_us + ctrl_us) / loop_us:.0%}")
    for label, (cpu, wall, steps) in loops.items():
        sim = steps * scenario.control_period
        print(f"paper preset, {sim:.0f} s, {label}: {cpu:.2f} s CPU ({sim / cpu:.0f}x realtime), "
              f"{wall:.2f} s wall ({sim / wall:.0f}x); projected 300 s run: {cpu * 300.0 / sim:.1f} s CPU")
    return sea_section(args)


def sea_section(args) -> int:
    """The cost of the sea per step beside the calm step, on both plants, and the paper run in the
    ``moderate`` sea. Per-call figures: best of ``--repeat`` interleaved rounds, CPU time."""
    import mujoco

    from usv_mj.plants.analytic import AnalyticPlant
    from usv_mj.plants.mujoco_plant import DEFAULT_MODEL, MuJoCoPlant
    from usv_mj.scenario.spec import load_scenario
    from usv_mj.physics.sea import Environment, SeaSettings, load_sea_preset, sea_force
    from usv_mj.physics.sea import CurrentSettings, WindSettings
    from usv_mj.physics.ship import hydrodynamic_force
    from usv_mj.loop.simulate import simulate

    print(f"\n--- sea --- load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    scenario = load_scenario(preset="paper")
    n, rep = args.n, args.repeat
    dt = scenario.control_period
    moderate = load_sea_preset("moderate")
    envs = {
        "calm": None,
        "moderate waves (128 components)": Environment(moderate, t_max=400.0),
        "waves + current 0.3 m/s + wind 5 m/s (gusts)": Environment(SeaSettings(
            waves=moderate.waves, current=CurrentSettings(speed=0.3, direction_deg=30.0, sigma=0.05),
            wind=WindSettings(speed=5.0, direction_deg=90.0, gust_sigma=1.0)), t_max=400.0),
    }
    p, dp = scenario.ship.as_array(), scenario.disturbance.as_array()
    eta, nu = np.array([2.0, -3.0, 0.4]), np.array([0.8, 0.1, 0.05])
    model = mujoco.MjModel.from_xml_path(DEFAULT_MODEL)
    data = mujoco.MjData(model)

    def one_round():
        out = []
        mujoco.set_mjcb_passive(None)
        out.append(("bare mj_step, no callback (RK4, 1 ms)", best_per_call(lambda: mujoco.mj_step(model, data), n, 1)))
        out.append(("kernel: hydrodynamic_force (calm)", best_per_call(lambda: hydrodynamic_force(p, dp, 12.3, eta, nu), n, 1)))
        for label, env in envs.items():
            if env is None:
                continue
            packed = env.packed
            out.append((f"kernel: sea_force, {label}",
                        best_per_call(lambda: sea_force(p, dp, *packed, 12.3, eta, nu), n, 1)))
        for label, env in envs.items():
            with MuJoCoPlant(scenario.ship, scenario.disturbance, dt, environment=env) as plant:
                plant.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))

                def mj_step():
                    plant.step(60.0, 1.0)
                    return plant.state

                out.append((f"MuJoCoPlant.step + .state, {label}", best_per_call(mj_step, n, 1)))
            analytic = AnalyticPlant(scenario.ship, scenario.disturbance, dt, environment=env)
            analytic.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))

            def an_step():
                analytic.step(60.0, 1.0)
                return analytic.state

            out.append((f"AnalyticPlant.step + .state, {label}", best_per_call(an_step, n, 1)))
        return out

    rounds = [one_round() for _ in range(rep)]
    rows = [(name, min(r[i][1] for r in rounds)) for i, (name, _) in enumerate(rounds[0])]
    yard = rows[0][1]
    print(f"{'per 1 ms control step or call (CPU time)':64s} {'us':>9s} {'x bare':>8s}")
    for name, sec in rows:
        print(f"{name:64s} {sec * 1e6:9.2f} {sec / yard:8.2f}")
    d = dict(rows)
    for plant in ("MuJoCoPlant", "AnalyticPlant"):
        calm = d[f"{plant}.step + .state, calm"]
        for label in list(envs)[1:]:
            print(f"sea cost per step, {plant}, {label}: +{(d[f'{plant}.step + .state, {label}'] - calm) * 1e6:.1f} us")

    sea_scn = load_scenario(preset="paper", overrides={"sea": {"waves": dict(moderate.to_dict()["waves"])}})
    short = sea_scn.with_overrides({"duration": min(args.duration, sea_scn.duration)})
    for kind in ("mujoco", "analytic"):
        simulate(short.with_overrides({"duration": 1.0}), plant_kind=kind)  # compile / cache load
        best = None
        for _ in range(max(1, rep - 1)):
            c0 = time.thread_time()
            rec = simulate(short, plant_kind=kind)
            cpu = time.thread_time() - c0
            if best is None or cpu < best[0]:
                best = (cpu, rec.metadata["wall_time_s"], rec.n_rows - 1, rec.status)
        cpu, wall, steps, status = best
        sim = steps * dt
        print(f"paper preset in the moderate sea, {sim:.0f} s, simulate, {kind} plant ({status}): {cpu:.2f} s CPU "
              f"({sim / cpu:.0f}x realtime), {wall:.2f} s wall ({sim / wall:.0f}x); projected 300 s run: "
              f"{cpu * 300.0 / sim:.1f} s CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
