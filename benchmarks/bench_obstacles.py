"""Benchmark: the cost of obstacles per control step against the open-water step.

    python benchmarks/bench_obstacles.py [--counts 1 10 50] [--steps 5000]

For 1, 10 and 50 obstacles (a random field of buoys and boxes, none touching the hull at the
origin, plus one run with the hull pressed against a pier so that the contact solver works), it
prints microseconds per control step of

- the bare ``mujoco.mj_step`` of the open-water model ``models/usv.xml`` (the yardstick, with the
  hydrodynamic callback) and ``MuJoCoPlant.step`` on it;
- ``HarbourPlant.step``: the same on the composed model (collision detection on, obstacles present);
- ``MuJoCoClearance.update``: mj_kinematics + mj_geomDistance per hull geom and obstacle + contacts,
  all exact, with the default bounding-circle cut (exact within 10 m; the field's obstacles are
  8-85 m away, so few are queried) and with the broad phase (the run's monitor: the grid);
- ``GeometricClearance.update``: the analytic plant's numba clearance, the same two ways, and the
  shapely reference;
- the analytic plant's step, for scale;
- the whole closed loop (PPC on the MuJoCo plant, a straight line, 10 s) in open water against
  :func:`usv_mj.obstacles.run_obstacle_scenario` with the obstacle field (guidance off).

Then, for harbours of 10 / 100 / 300 / 1000 standing circles (:func:`harbour_toml`: one buoy per
170 m^2 about a 45 m line, guidance on; ``--harbours``), it prints the planning time (cold, and
again from :func:`usv_mj.obstacles.make_plan`'s cache) and the closed loop's us per step on the
MuJoCo and the analytic plant beside open water (the lower of two runs each) and the load average. ``--write-harbour N PATH`` writes the N-circle harbour as a scenario file
(``python -m usv_mj.cli.main run --scenario PATH --no-video`` then runs it whole).

The machine is shared: run it twice and take the lower figures.
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco
import numpy as np


def per_call(fn, n):
    fn()
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n * 1e6


def obstacle_field(count, seed=0, tables_only=False):
    from usv_mj.scenario.obstacles import from_tables

    rng = np.random.default_rng(seed)
    tables = []
    while len(tables) < count:
        x, y = rng.uniform(-60, 60, 2)
        if np.hypot(x, y) < 8.0:
            continue
        if rng.random() < 0.6:
            tables.append({"center": [float(x), float(y)], "radius": float(rng.uniform(0.3, 1.5))})
        else:
            tables.append({"kind": "box", "center": [float(x), float(y)], "size": [float(rng.uniform(2, 10)),
                           float(rng.uniform(1, 4))], "yaw": float(rng.uniform(-3, 3))})
    return tables if tables_only else from_tables(tables)


def harbour_toml(count: int, seed: int = 0) -> str:
    """A harbour scenario of ``count`` standing buoys (radius 0.3-1 m, one per 170 m^2 in a square
    about the 45 m line from (0, 0) to (45, 0), none within 8 m of its ends) on
    examples/scenarios/harbour_gap.toml's settings (75 s, tight funnel, MuJoCo, guidance on)."""
    from pathlib import Path

    rng = np.random.default_rng(seed)
    half = 0.5 * math.sqrt(count * 170.0)
    buoys = []
    while len(buoys) < count:
        x, y = rng.uniform(22.5 - half, 22.5 + half), rng.uniform(-half, half)
        if min(math.hypot(x, y), math.hypot(x - 45.0, y)) >= 8.0:
            buoys.append((x, y, rng.uniform(0.3, 1.0)))
    head = (Path(__file__).resolve().parents[1] / "examples/scenarios/harbour_gap.toml").read_text()
    head = head.split("[[obstacles]]")[0]
    body = "".join(f'[[obstacles]]\nname = "buoy_{i}"\nkind = "circle"\ncenter = [{x:.3f}, {y:.3f}]\n'
                   f"radius = {r:.3f}\n\n" for i, (x, y, r) in enumerate(buoys))
    return head + body + "[guidance]\navoid = true\nmargin_m = 0.3\n"


def harbours(counts, loop_seconds: float) -> None:
    """Planning time and the closed loop's us per step of :func:`harbour_toml` harbours, on the
    MuJoCo and the analytic plant, beside open water (the same loop without obstacles)."""
    import os
    import tempfile
    from collections import OrderedDict
    from pathlib import Path

    from usv_mj import build
    from usv_mj.obstacles import hooks
    from usv_mj.scenario.spec import load_scenario
    from usv_mj.loop.simulate import simulate

    def loop_us(scenario, plant):
        best = math.inf
        for _ in range(2):   # the lower of two: the machine is shared
            parts = build(scenario, plant_kind=plant)
            t0 = time.perf_counter()
            rec = simulate(parts)
            best = min(best, (time.perf_counter() - t0) / scenario.steps * 1e6)
        return best, rec.metadata["loop"]

    base = load_scenario(preset="paper").with_overrides({
        "duration": loop_seconds, "plant": {"kind": "mujoco"}, "initial": {"eta": [0.0, 0.0, 0.0]},
        "trajectory": {"kind": "line", "start": [0.0, 0.0], "heading_deg": 0.0}})
    simulate(base.with_overrides({"duration": 0.5}))
    open_us = {plant: loop_us(base, plant)[0] for plant in ("mujoco", "analytic")}
    print(f"harbours of standing circles (one per 170 m^2), guidance on, {loop_seconds:g} s loop; open water "
          f"{open_us['mujoco']:.1f} us/step (MuJoCo), {open_us['analytic']:.1f} (analytic); load average "
          f"{os.getloadavg()[0]:.1f}")
    print(f"{'circles':>8} {'plan (s)':>9} {'cached (ms)':>12} {'MuJoCo us/step':>15} {'x open':>7} "
          f"{'analytic us/step':>17} {'x open':>7} {'path nodes':>11} {'loop':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        for count in counts:
            path = Path(tmp) / f"harbour_{count}.toml"
            path.write_text(harbour_toml(count))
            sc = load_scenario(path).with_overrides({"duration": loop_seconds})
            hooks._plans = OrderedDict()  # cold
            t0 = time.perf_counter()
            plan = hooks.make_plan(sc)
            cold = time.perf_counter() - t0
            t0 = time.perf_counter()
            hooks.make_plan(sc)
            warm = (time.perf_counter() - t0) * 1e3
            mj, loop = loop_us(sc, "mujoco")
            an, _ = loop_us(sc, "analytic")
            print(f"{count:>8d} {cold:9.2f} {warm:12.2f} {mj:15.1f} {mj / open_us['mujoco']:7.2f} {an:17.1f} "
                  f"{an / open_us['analytic']:7.2f} {len(plan.polyline):>11d} {loop:>9}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--counts", type=int, nargs="*", default=[1, 10, 50, 1000])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--loop-seconds", type=float, default=10.0, help="simulated seconds of the closed-loop comparison")
    ap.add_argument("--harbours", type=int, nargs="*", default=[10, 100, 300, 1000],
                    help="circle counts of the planning table (none: skip it)")
    ap.add_argument("--harbours-only", action="store_true", help="print only the planning table")
    ap.add_argument("--write-harbour", nargs=2, metavar=("N", "PATH"), help="write the N-circle harbour and stop")
    args = ap.parse_args()
    if args.write_harbour:
        from pathlib import Path

        Path(args.write_harbour[1]).write_text(harbour_toml(int(args.write_harbour[0])))
        return
    if args.harbours_only:
        harbours(args.harbours, args.loop_seconds)
        return
    n = args.steps

    from usv_mj.scenario.obstacles import from_tables
    from usv_mj.obstacles.clearance import GeometricClearance, MuJoCoClearance
    from usv_mj.plants.harbour import HarbourPlant
    from usv_mj.plants.analytic import AnalyticPlant
    from usv_mj.plants.mujoco_plant import MuJoCoPlant
    from usv_mj.scenario.spec import load_scenario

    sc = load_scenario(preset="paper")
    ship, dist = sc.ship, sc.disturbance

    open_water = MuJoCoPlant(ship, dist, 1e-3, 1)
    open_water.reset((0, 0, 0), (0.5, 0, 0))
    bare = per_call(lambda: mujoco.mj_step(open_water.model, open_water.data), n)
    open_water.reset((0, 0, 0), (0.5, 0, 0))
    plant_step = per_call(lambda: open_water.step(10.0, 0.0), n)
    open_water.close()
    analytic = AnalyticPlant(ship, dist, 1e-3, 1)
    analytic.reset((0, 0, 0), (0.5, 0, 0))
    analytic_step = per_call(lambda: analytic.step(10.0, 0.0), n)
    print("microseconds per control step (1 ms, 1 substep); machine shared with other jobs")
    print(f"  open water: bare mj_step {bare:8.1f}   MuJoCoPlant.step {plant_step:8.1f}   "
          f"AnalyticPlant.step {analytic_step:8.1f}")
    print(f"{'obstacles':>10} {'Harbour step':>13} {'x open':>7} | {'MuJoCo clearance':>17} {'x bare':>7} "
          f"{'exact<10m':>10} {'broad':>7} | {'geometric numba':>16} {'exact<10m':>10} {'broad':>7} {'shapely':>9}")
    state = np.array([0.0, 0.0, 0.2, 0.5, 0.0, 0.0])
    for count in args.counts:
        obstacles = obstacle_field(count)
        with HarbourPlant(ship, dist, obstacles) as plant:
            plant.reset((0, 0, 0), (0.5, 0, 0))
            step = per_call(lambda: plant.step(10.0, 0.0), n)
            monitor = MuJoCoClearance(plant, exact_within=math.inf)
            clear = per_call(lambda: monitor.update(0.0), n)
            monitor = MuJoCoClearance(plant)
            clear_near = per_call(lambda: monitor.update(0.0), n)
            monitor = MuJoCoClearance(plant, broad_phase=True)
            clear_broad = per_call(lambda: monitor.update(0.0), n)
        geo = GeometricClearance(obstacles, exact_within=math.inf)
        geo_t = per_call(lambda: geo.update(1.0, state), n)
        geo = GeometricClearance(obstacles)
        geo_near = per_call(lambda: geo.update(1.0, state), n)
        geo = GeometricClearance(obstacles, broad_phase=True)
        geo_broad = per_call(lambda: geo.update(1.0, state), n)
        shp = GeometricClearance(obstacles, method="shapely")
        shp_t = per_call(lambda: shp.update(1.0, state), max(n // 20, 50))
        print(f"{count:>10d} {step:13.1f} {step / plant_step:7.2f} | {clear:17.1f} {clear / bare:7.2f} {clear_near:10.1f} "
              f"{clear_broad:7.1f} | {geo_t:16.1f} {geo_near:10.1f} {geo_broad:7.1f} {shp_t:9.1f}")
    # in contact: the hull pushed against a pier (the constraint solver runs every step)
    pier = from_tables([{"kind": "box", "center": [8, 0], "size": [2, 6]}])
    with HarbourPlant(ship, dist, pier) as plant:
        plant.reset((5.9, 0, 0), (0, 0, 0))
        for _ in range(500):
            plant.step(200.0, 0.0)
        ncon = plant.data.ncon
        step = per_call(lambda: plant.step(200.0, 0.0), n)
        monitor = MuJoCoClearance(plant)
        clear = per_call(lambda: monitor.update(0.0), n)
        print(f"{'1, contact':>10} {step:13.1f} {step / plant_step:7.2f} | {clear:17.1f} {clear / bare:7.2f} "
              f"  ({plant.data.ncon} contact(s) active, {ncon} at the start)")
    # the whole closed loop (PPC, quantizers, recording): open water against the same scenario
    # with the obstacle field (the one build composes the harbour; guidance off)
    from usv_mj import build
    from usv_mj.loop.simulate import simulate

    loop = sc.with_overrides({"duration": args.loop_seconds, "plant": {"kind": "mujoco"},
                              "initial": {"eta": [0.0, 0.0, 0.0]},
                              "trajectory": {"kind": "line", "start": [0.0, 0.0], "heading_deg": 0.0}})
    simulate(loop.with_overrides({"duration": 0.5}))
    t0 = time.perf_counter()
    simulate(loop)
    open_loop = (time.perf_counter() - t0) / loop.steps * 1e6
    simulate(loop.with_overrides({"duration": 0.5, "obstacles": obstacle_field(10, tables_only=True),
                                  "guidance": {"avoid": False}}))   # the hook's kernel compiled (not timed)
    print(f"closed loop ({args.loop_seconds:g} s, PPC, MuJoCo) per step: open water {open_loop:.1f}", end="")
    for count in args.counts:
        osc = loop.with_overrides({"obstacles": obstacle_field(count, tables_only=True), "guidance": {"avoid": False}})
        t0 = time.perf_counter()
        parts = build(osc)           # composes the harbour model (dm_control.mjcf): shown apart
        t1 = time.perf_counter()
        rec = simulate(parts)
        per = (time.perf_counter() - t1) / loop.steps * 1e6
        print(f"; {count} obstacles {per:.1f} (x{per / open_loop:.2f}, {rec.metadata['loop'].split(' ')[0]} loop, "
              f"build {t1 - t0:.2f} s)", end="")
    print()
    with MuJoCoPlant(ship, dist, 1e-3, 1) as open_water:
        open_water.reset((0, 0, 0), (0.5, 0, 0))
        again = per_call(lambda: mujoco.mj_step(open_water.model, open_water.data), n)
    print(f"  bare mj_step measured again at the end: {again:.1f} (the load on the machine varies)")
    if args.harbours:
        harbours(args.harbours, args.loop_seconds)


if __name__ == "__main__":
    main()
