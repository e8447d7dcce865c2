"""Cost of the sea (docs/sea.md): one load evaluation (128 components), one analytic RK4 step with
the sea against the calm step, one hfield frame, with the bare mujoco.mj_step as the yardstick.

Run: python benchmarks/bench_sea.py   (plain script; prints figures; best of several repeats)
"""

from __future__ import annotations

import pathlib
import time

import numpy as np
from numba import njit

from usv_mj.plants.analytic import rk4_advance
from usv_mj.physics.sea import Environment, SeaSettings, environment_loads, load_sea_preset, sea_rk4_advance
from usv_mj.physics.sea.waves import wave_loads
from usv_mj.physics.ship import PaperDisturbance, ShipParams

REPEATS = 7


def best_of(fn, n, repeats=REPEATS):
    fn(max(n // 100, 1))  # warm up / compile
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(n)
        times.append(time.perf_counter() - t0)
    return min(times) / n


@njit
def _loads_loop(ep, waves, cg, wg, n):
    eta = np.array([1.0, 2.0, 0.3])
    nu = np.array([0.5, 0.1, 0.02])
    acc = 0.0
    for i in range(n):
        out = environment_loads(ep, waves, cg, wg, i * 1e-3, eta, nu)
        acc += out[9]
    return acc


@njit
def _waves_loop(ep, waves, n):
    acc = 0.0
    for i in range(n):
        acc += wave_loads(ep, waves, i * 1e-3, 1.0, 2.0, 0.3)[0]
    return acc


@njit
def _rk4_sea_loop(p, dp, ep, waves, cg, wg, n):
    x = np.array([2.0, -3.0, 0.0, 0.5, 0.0, 0.0])
    for k in range(n):
        x = sea_rk4_advance(p, dp, ep, waves, cg, wg, k * 1e-3, x, 50.0, 0.5, 1e-3, 1)
    return x


@njit
def _rk4_calm_loop(p, dp, n):
    x = np.array([2.0, -3.0, 0.0, 0.5, 0.0, 0.0])
    for k in range(n):
        x = rk4_advance(p, dp, k * 1e-3, x, 50.0, 0.5, 1e-3, 1)
    return x


def main() -> None:
    full = SeaSettings(waves=load_sea_preset("moderate").waves,
                       current=load_sea_preset("steady-current").current,
                       wind=load_sea_preset("breeze").wind)
    sea = Environment(full, t_max=400.0)
    waves_only = Environment(SeaSettings(waves=load_sea_preset("moderate").waves))
    calm = Environment()
    p, dp = ShipParams().as_array(), PaperDisturbance().as_array()
    print(f"components: {sea.components.n}; machine under load from other sessions: figures are upper bounds")

    per = best_of(lambda n: _waves_loop(sea.packed.ep, sea.packed.waves, n), 20_000)
    print(f"wave_loads (first order + Newman drift), njit loop : {per * 1e6:8.3f} us / evaluation")
    per = best_of(lambda n: _loads_loop(*sea.packed, n), 20_000)
    print(f"environment_loads (waves+current+wind), njit loop : {per * 1e6:8.3f} us / evaluation")
    per = best_of(lambda n: _loads_loop(*calm.packed, n), 200_000)
    print(f"environment_loads, calm                           : {per * 1e6:8.3f} us / evaluation")
    eta, nu = np.array([1.0, 2.0, 0.3]), np.array([0.5, 0.1, 0.02])

    def py_loads(n):
        for i in range(n):
            sea.loads(i * 1e-3, eta, nu)
    per = best_of(py_loads, 5_000)
    print(f"Environment.loads() from Python                   : {per * 1e6:8.3f} us / call")

    calm_step = best_of(lambda n: _rk4_calm_loop(p, dp, n), 200_000)
    calm_sea_step = best_of(lambda n: _rk4_sea_loop(p, dp, *calm.packed, n), 200_000)
    waves_step = best_of(lambda n: _rk4_sea_loop(p, dp, *waves_only.packed, n), 20_000)
    sea_step = best_of(lambda n: _rk4_sea_loop(p, dp, *sea.packed, n), 20_000)
    print(f"analytic RK4 step (1 ms, 4 stages), usv_mj.physics.ship  : {calm_step * 1e6:8.3f} us   "
          f"({1e-3 / calm_step:8.0f} x real time)")
    print(f"analytic RK4 step, sea kernel, calm environment   : {calm_sea_step * 1e6:8.3f} us   "
          f"({1e-3 / calm_sea_step:8.0f} x real time)")
    print(f"analytic RK4 step, moderate waves                 : {waves_step * 1e6:8.3f} us   "
          f"({1e-3 / waves_step:8.0f} x real time)")
    print(f"analytic RK4 step, waves + current + wind         : {sea_step * 1e6:8.3f} us   "
          f"({1e-3 / sea_step:8.0f} x real time)")

    xs = np.linspace(-10, 10, 201)
    sea.elevation_grid(xs, xs, 0.0)

    def frames(n):
        for i in range(n):
            sea.elevation_grid(xs, xs, i * 0.04, origin=(0.1 * i, 0.0))
    per = best_of(frames, 20, repeats=3)
    print(f"elevation_grid 201 x 201 (one complex matmul)     : {per * 1e3:8.3f} ms / frame")

    try:
        import mujoco
    except ImportError:  # pragma: no cover
        print("mujoco not importable: no yardstick")
        return
    xml = pathlib.Path(__file__).resolve().parents[1] / "models" / "usv.xml"
    if not xml.exists():
        print("models/usv.xml missing: no yardstick")
        return
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)

    def steps(n):
        for _ in range(n):
            mujoco.mj_step(model, data)
    per = best_of(steps, 20_000, repeats=3)
    print(f"bare mujoco.mj_step (models/usv.xml, RK4 1 ms)    : {per * 1e6:8.3f} us / step (yardstick)")


if __name__ == "__main__":
    main()
