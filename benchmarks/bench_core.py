"""Benchmark: the closed loop per control step, Python loop against compiled loop, beside the bare mj_step.

    python benchmarks/bench_core.py [--duration 60] [--repeat 5] [--no-sea] [--vessel KIND ...]

Prints, per 1 ms control step, in CPU time of this thread (``time.thread_time``: on a shared machine
the wall clock also counts the time waiting for a core), the best and the range over ``--repeat``
interleaved rounds:

- the bare RK4 ``mujoco.mj_step`` of models/usv.xml, no callback (the yardstick; ratios are to it);
- ``MuJoCoPlant.step`` + ``.state`` (the hydrodynamic callback included), ``AnalyticPlant.step`` + ``.state``;
- the PPC call, the reference, the quantizer (what the Python loop pays per part);
- ``simulate`` of the paper preset (``--duration`` s, no baseline) on both plants with the Python
  loop (``loop="python"``) and the compiled loop (usv_mj.loop.compiled), and the same in the
  ``moderate`` sea, with the realtime factor;
- with ``--vessel KIND`` (repeatable; docs/vessels.md) the same ``simulate`` on that vessel, and its
  compiled loop's step against the paper hull's;
- a plug-in's controller at the compiled speed (docs/controllers.md, "The compiled path"): the paper
  scenario driven by the built-in ``pi`` and by the example plug-in's ``example-pd``
  (examples/plugins/usv_mj_example_plugin: its law a numba function handed as its ``kernel()``), both
  in the compiled loop, and the plug-in's step over ``pi``'s (``--no-plugin`` skips them).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def per_call(fn, n=20000):
    fn()
    t0 = time.thread_time()
    for _ in range(n):
        fn()
    return (time.thread_time() - t0) / n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-sea", action="store_true", help="skip the moderate-sea runs")
    ap.add_argument("--vessel", action="append", default=[], help="also run the paper's scenario on this vessel kind")
    ap.add_argument("--no-plugin", action="store_true", help="skip the plug-in controller against pi")
    args = ap.parse_args(argv)

    import mujoco

    from usv_mj import load_scenario, simulate
    from usv_mj.plants.analytic import AnalyticPlant
    from usv_mj.plants.mujoco_plant import DEFAULT_MODEL, MuJoCoPlant
    from usv_mj.loop.simulate import make_controller, make_quantizers, make_reference

    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; mujoco {mujoco.__version__}")
    over = {"duration": args.duration, "baseline": {"enabled": False}}
    scenario = load_scenario(preset="paper", overrides=over)
    runs = {"paper": scenario}
    if not args.no_sea:
        runs["paper, moderate sea"] = load_scenario(preset="paper", overrides={**over, "sea": {"preset": "moderate"}})
    for kind in args.vessel:
        runs[f"vessel {kind}"] = load_scenario(preset="paper", overrides={**over, "vessel": {"kind": kind}})
    if not args.no_plugin:
        import sys
        from pathlib import Path

        plugin = Path(__file__).resolve().parent.parent / "examples" / "plugins" / "usv_mj_example_plugin"
        try:
            import usv_mj_example_plugin  # noqa: F401  (installed)
        except ImportError:
            sys.path.insert(0, str(plugin))
        runs["paper, pi"] = load_scenario(preset="paper", overrides={**over, "controller": {"kind": "pi"}})
        runs["paper, example-pd plug-in"] = load_scenario(preset="paper", overrides={
            **over, "controller": {"kind": "usv_mj_example_plugin.pd:ExamplePD"}})
    for sc in runs.values():  # compile / cache load of both loops on both plants
        for kind in ("analytic", "mujoco"):
            for loop in ("auto", "python"):
                simulate(sc.with_overrides({"duration": 1.0}), plant_kind=kind, loop=loop)

    model = mujoco.MjModel.from_xml_path(DEFAULT_MODEL)
    data = mujoco.MjData(model)
    data.ctrl[:] = (60.0, 1.0)
    ctrl = make_controller(scenario)
    ref = make_reference(scenario)
    qu, _ = make_quantizers(scenario)
    x = np.array([2.0, -3.0, 0.0, 0.1, 0.0, 0.0])
    r = ref.evaluate(1.0)
    analytic = AnalyticPlant(scenario.ship, scenario.disturbance, scenario.control_period)
    analytic.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))
    mj_plant = MuJoCoPlant(scenario.ship, scenario.disturbance, scenario.control_period)
    mj_plant.reset((2.0, -3.0, 0.0), (0.5, 0.0, 0.0))

    def plant_step(plant):
        def f():
            plant.step(60.0, 1.0)
            return plant.state
        return f

    def one_round():
        out = []
        saved = mujoco.get_mjcb_passive()
        mujoco.set_mjcb_passive(None)
        out.append(("bare mj_step, no callback (RK4, 1 ms)", per_call(lambda: mujoco.mj_step(model, data))))
        mujoco.set_mjcb_passive(saved)
        out.append(("MuJoCoPlant.step + .state", per_call(plant_step(mj_plant))))
        out.append(("AnalyticPlant.step + .state", per_call(plant_step(analytic))))
        out.append(("PPC controller call", per_call(lambda: ctrl(1.0, x, r))))
        out.append(("reference evaluate", per_call(lambda: ref.evaluate(12.3))))
        out.append(("quantizer step", per_call(lambda: qu.step(12.3))))
        for label, sc in runs.items():
            for kind in ("mujoco", "analytic"):
                for loop, name in (("python", "Python loop"), ("auto", "compiled loop")):
                    c0 = time.thread_time()
                    rec = simulate(sc, plant_kind=kind, loop=loop)
                    cpu = time.thread_time() - c0
                    assert rec.metadata["loop"] == ("python" if loop == "python" else "compiled"), rec.metadata
                    out.append((f"simulate({label}), {kind}, {name}", cpu / (rec.n_rows - 1)))
        return out

    rounds = [one_round() for _ in range(args.repeat)]
    mj_plant.close()
    names = [name for name, _ in rounds[0]]
    best = {name: min(r[i][1] for r in rounds) for i, name in enumerate(names)}
    worst = {name: max(r[i][1] for r in rounds) for i, name in enumerate(names)}
    yard = best[names[0]]
    print(f"\n{'per 1 ms control step (CPU time), best of ' + str(args.repeat):58s} {'us':>7s} {'range us':>15s} "
          f"{'x bare':>7s} {'x real time':>12s}")
    for name in names:
        b, w = best[name], worst[name]
        rt = f"{1e-3 / b:12.0f}" if name.startswith(("simulate", "bare", "MuJoCo", "Analytic")) else ""
        print(f"{name:58s} {b * 1e6:7.2f} {f'{b * 1e6:.2f}-{w * 1e6:.2f}':>15s} {b / yard:7.2f} {rt}")
    for label in runs:
        for kind in ("mujoco", "analytic"):
            py, co = best[f"simulate({label}), {kind}, Python loop"], best[f"simulate({label}), {kind}, compiled loop"]
            print(f"{label}, {kind}: compiled loop {py / co:.2f}x faster than the Python loop")
    if "paper, pi" in runs:
        for kind in ("mujoco", "analytic"):
            co = {c: best[f"simulate(paper, {c}), {kind}, compiled loop"] for c in ("pi", "example-pd plug-in")}
            print(f"example-pd plug-in, {kind}: compiled loop step {co['example-pd plug-in'] / co['pi']:.2f}x pi's "
                  f"({co['example-pd plug-in'] * 1e6:.2f} us against {co['pi'] * 1e6:.2f} us)")
    for label in (k for k in runs if k.startswith("vessel ")):
        for kind in ("mujoco", "analytic"):
            co, paper = best[f"simulate({label}), {kind}, compiled loop"], best[f"simulate(paper), {kind}, compiled loop"]
            print(f"{label}, {kind}: compiled loop step {co / paper:.2f}x the paper hull's")


if __name__ == "__main__":
    main()
