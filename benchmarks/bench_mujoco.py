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
    from usv_mj.scenario import load_scenario
    from usv_mj.simulation import make_controller, make_reference, simulate

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
        best = None
        for _ in range(max(1, rep - 1)):
            c0 = time.thread_time()
            rec = simulate(short, plant_kind=kind)
            cpu = time.thread_time() - c0
            if best is None or cpu < best[0]:
                best = (cpu, rec.metadata["wall_time_s"], rec.n_rows - 1)
        loops[f"simulate, {kind} plant"] = best
        rows.append((f"closed-loop step, simulate(paper), {kind} plant", best[0] / best[2]))
    fused = fused_paper_loop(short)
    loops["compiled loop (prototype), mujoco plant"] = fused[:3]
    rows.append(("closed-loop step, compiled loop (prototype), mujoco", fused[0] / fused[2]))

    yard = rows[0][1]
    print(f"\n{'per 1 ms control step (CPU time)':56s} {'us':>9s} {'x bare':>8s}")
    for name, sec in rows:
        print(f"{name:56s} {sec * 1e6:9.2f} {sec / yard:8.2f}")
    ctrl_us = dict(rows)["PPC controller call"]
    loop_us = dict(rows)["closed-loop step, simulate(paper), mujoco plant"]
    plant_us = dict(rows)["MuJoCoPlant.step + .state (native)"]
    print(f"\nshares of the simulate() step on the MuJoCo plant: plant {plant_us / loop_us:.0%}, controller "
          f"{ctrl_us / loop_us:.0%}, rest of the loop (reference, quantizers, recording, checks) "
          f"{1 - (plant_us + ctrl_us) / loop_us:.0%}")
    print(f"compiled-loop prototype vs simulate on the MuJoCo plant: max |state difference| over the run "
          f"{fused[3]:.1e} (the same computation)")
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
    from usv_mj.scenario import load_scenario
    from usv_mj.sea import Environment, SeaSettings, load_sea_preset, sea_force
    from usv_mj.sea import CurrentSettings, WindSettings
    from usv_mj.ship import hydrodynamic_force
    from usv_mj.simulation import simulate

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
    from usv_mj.simulation import make_environment

    env = make_environment(short)
    cpu, wall, steps, diff = fused_paper_loop(short, env)
    sim = steps * dt
    print(f"paper preset in the moderate sea, {sim:.0f} s, compiled loop (prototype), mujoco plant: {cpu:.2f} s CPU "
          f"({sim / cpu:.0f}x realtime), {wall:.2f} s wall ({sim / wall:.0f}x); max |state - simulate's| {diff:.1e}")
    return 0


def fused_paper_loop(scenario, environment=None):
    """A prototype of the closed loop compiled as one numba function (paper reference, PPC, quantizer,
    MuJoCo plant through ``native_stepper``), to measure what the Python loop of ``simulate`` costs.

    Records only the state. Returns (CPU time [s], wall time [s], steps, max |state - simulate's state|).
    ``environment``: the sea of ``scenario`` (its grids must already cover the run: the compiled loop
    does not extend them).
    """
    from numba import njit

    from usv_mj.controllers.hysteresis_quantizer import quantize_step
    from usv_mj.controllers.ppc import ppc_law
    from usv_mj.plants import mujoco_callback as mcb
    from usv_mj.plants.mujoco_plant import MuJoCoPlant
    from usv_mj.simulation import make_controller, make_quantizers, make_reference, simulate
    from usv_mj.trajectories import _paper_evaluate

    stepper = mcb.native_stepper()

    @njit
    def loop(n, dt, m_addr, d_addr, x0, rx, ry, rpsi, rgrid, rspeed, rturn, rphase, ramp, rper, rout,
             p, g, funnel, centres, w, s2, diag, s_buf, z_buf, du, umu, dr, umr, states):
        x = x0.copy()
        ku, kr = 0, 0
        states[0] = x
        for k in range(n):
            t = k * dt
            ref = _paper_evaluate(rx, ry, rpsi, rgrid, rspeed, rturn, rphase, ramp, rper, t, rout)
            tau_u, tau_r = ppc_law(t, x, ref, p, g, funnel, centres, w, s2, dt, diag, s_buf, z_buf)
            qu, ku = quantize_step(du, umu, ku, tau_u)
            qr, kr = quantize_step(dr, umr, kr, tau_r)
            x, failed = stepper(m_addr, d_addr, t, qu, qr, 1)
            if failed:
                return k
            states[k + 1] = x
        return n

    ctrl = make_controller(scenario)
    ref = make_reference(scenario)
    qu, qr = make_quantizers(scenario)
    n = int(round(scenario.duration / scenario.control_period))
    states = np.empty((n + 1, 6))

    def run():
        ctrl.reset()
        with MuJoCoPlant(scenario.ship, scenario.disturbance, scenario.control_period,
                         environment=environment) as plant:
            plant.reset(scenario.initial.eta, scenario.initial.nu)
            x0 = plant.state.copy()
            c0, t0 = time.thread_time(), time.perf_counter()
            done = loop(n, scenario.control_period, plant.model._address, plant.data._address, x0,
                        ref._x, ref._y, ref._psi, ref.GRID, ref.speed, ref.t_turn, ref.t_phase, ref.amplitude,
                        ref.period, ref._out, ctrl._p, ctrl._g, ctrl._funnel, ctrl._centres, ctrl.weights,
                        ctrl._s2, ctrl._diag, ctrl._s_buf, ctrl._z_buf, qu.params.delta,
                        qu.params.u_min, qr.params.delta, qr.params.u_min, states)
            return time.thread_time() - c0, time.perf_counter() - t0, done

    run()  # compile
    cpu, wall, done = run()
    rec = simulate(scenario, plant_kind="mujoco")
    sim_states = np.stack([rec[c] for c in ("x", "y", "psi", "u", "v", "r")], axis=1)
    m = min(len(sim_states), done + 1)
    return cpu, wall, done, float(np.max(np.abs(sim_states[:m] - states[:m])))


if __name__ == "__main__":
    raise SystemExit(main())
