"""Env steps per second of the batched vector environment (issue 36), beside a bare batched RK4 and SyncVectorEnv.

One run prints:

- the analytic plant: ``gymnasium.make_vec("usv_mj/Track-v0", num_envs=N, plant="analytic")`` at
  N = 1, 64, 1024, 4096, beside a bare batched RK4 of the same hull (10 RK4 substeps of 1 ms per env
  step, thrust held, one prange call per env step: the physics alone, no reference, controller
  chain, observation or reward), in two forms: ``bare`` keeps the state in registers on the hull's
  tuple kernels (usv_mj.physics.ship.hull_terms, the fastest plain form), ``plant`` calls the analytic
  plant's own RK4 (usv_mj.physics.sea.dynamics.calm_rk4_advance) per episode, as the env does;
- the MuJoCo plant: the vector env at N = 1, 2, 16, 64 on 1 and on 2 threads (numba's), the pairs
  run interleaved (1, 2, 1, 2, ...) and the best of each kept, with the CPU seconds the process got,
  so that a machine shared with other jobs shows as what it is;
- today's ``gymnasium.vector.SyncVectorEnv`` of ``usv_mj/Track-v0`` (one USVGymEnv per episode, the
  MuJoCo plant) at N = 8.

Each figure is env steps (episodes x steps) per second of wall time, best of ``--repeats`` timed
runs of about ``--seconds`` each, compile excluded (a first call made before timing). The load
average before and after is printed: on a loaded machine every figure is a lower bound.

    python benchmarks/bench_batch.py                   # about 2-4 minutes, compile included
    python benchmarks/bench_batch.py --quick           # fewer sizes and repeats
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import njit, prange

from usv_mj.physics.ship import (PaperDisturbance, ShipParams, hull_terms, kinematics_terms, mass_solve_terms,
                                 packed_disturbance)
from usv_mj.physics.sea.dynamics import calm_rk4_advance

DT, NSUB = 0.01, 10
H = DT / NSUB


@njit(inline="always")
def _deriv(p, dp, t, x0, x1, x2, x3, x4, x5, fu, fr):
    nu = (x3, x4, x5)
    f0, f1, f2 = hull_terms(p, dp, t, (x0, x1, x2), nu, nu)
    a0, a1, a2 = mass_solve_terms(p, f0 + fu, f1, f2 + fr)
    e0, e1, e2 = kinematics_terms(x2, x3, x4, x5)
    return e0, e1, e2, a0, a1, a2


@njit(parallel=True)
def bare_step(k, X, FU, FR, p, dp, dt, h, n):
    """One env step of every episode: RK4 in registers (structure of arrays X (6, N))."""
    for i in prange(X.shape[1]):
        t = k * dt
        x0, x1, x2, x3, x4, x5 = X[0, i], X[1, i], X[2, i], X[3, i], X[4, i], X[5, i]
        fu, fr = FU[i], FR[i]
        half, sixth = 0.5 * h, h / 6.0
        for _ in range(n):
            a0, a1, a2, a3, a4, a5 = _deriv(p, dp, t, x0, x1, x2, x3, x4, x5, fu, fr)
            b0, b1, b2, b3, b4, b5 = _deriv(p, dp, t + half, x0 + half * a0, x1 + half * a1, x2 + half * a2,
                                            x3 + half * a3, x4 + half * a4, x5 + half * a5, fu, fr)
            c0, c1, c2, c3, c4, c5 = _deriv(p, dp, t + half, x0 + half * b0, x1 + half * b1, x2 + half * b2,
                                            x3 + half * b3, x4 + half * b4, x5 + half * b5, fu, fr)
            d0, d1, d2, d3, d4, d5 = _deriv(p, dp, t + h, x0 + h * c0, x1 + h * c1, x2 + h * c2,
                                            x3 + h * c3, x4 + h * c4, x5 + h * c5, fu, fr)
            x0 += sixth * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
            x1 += sixth * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
            x2 += sixth * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
            x3 += sixth * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
            x4 += sixth * (a4 + 2.0 * b4 + 2.0 * c4 + d4)
            x5 += sixth * (a5 + 2.0 * b5 + 2.0 * c5 + d5)
            t += h
        X[0, i], X[1, i], X[2, i], X[3, i], X[4, i], X[5, i] = x0, x1, x2, x3, x4, x5


@njit(parallel=True)
def plant_step(k, X, FU, FR, p, dp, dt, h, n):
    """One env step of every episode through the analytic plant's own RK4 (X (N, 6))."""
    for i in prange(X.shape[0]):
        x = calm_rk4_advance(p, dp, k * dt, X[i], FU[i], FR[i], h, n)
        for j in range(6):
            X[i, j] = x[j]


def _timed(fn, seconds, repeats):
    """(best steps/s of wall time, CPU seconds per wall second of that run) of ``fn(steps)`` -> env steps."""
    best, cpu_share = 0.0, 0.0
    steps = 1
    while True:   # size a run to about `seconds`
        t = time.perf_counter()
        fn(steps)
        wall = time.perf_counter() - t
        if wall > seconds / 4 or steps > 1 << 20:
            break
        steps *= 4
    steps = max(1, int(steps * seconds / max(wall, 1e-6)))
    for _ in range(repeats):
        c, t = time.process_time(), time.perf_counter()
        n = fn(steps)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        if n / wall > best:
            best, cpu_share = n / wall, cpu / wall
    return best, cpu_share


def bare(n_env, seconds, repeats, kind):
    # the packed d(t) the plants carry (17 words, the dispatch word 0: the paper's kernel), as the env's
    p, dp = ShipParams().as_array(), packed_disturbance(PaperDisturbance())
    rng = np.random.default_rng(0)
    X = np.zeros((6, n_env)) if kind == "bare" else np.zeros((n_env, 6))
    FU, FR = rng.uniform(0, 100, n_env), rng.uniform(-10, 10, n_env)
    fn = bare_step if kind == "bare" else plant_step
    fn(0, X, FU, FR, p, dp, DT, H, NSUB)

    def run(steps):
        for k in range(steps):
            fn(k, X, FU, FR, p, dp, DT, H, NSUB)
        return steps * n_env

    return _timed(run, seconds, repeats)


def vector(n_env, seconds, repeats, plant, n_threads=None, vec=None):
    import gymnasium

    import usv_mj.envs  # noqa: F401 (registers the ids)

    env = vec or gymnasium.make_vec("usv_mj/Track-v0", num_envs=n_env, plant=plant, n_threads=n_threads)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (64, n_env, 2)).astype(np.float32)
    env.step(actions[0])

    def run(steps):
        for k in range(steps):
            env.step(actions[k & 63])
        return steps * n_env

    try:
        return _timed(run, seconds, repeats)
    finally:
        if vec is None:
            env.close()


def sync_vector(n_env, seconds, repeats):
    import gymnasium

    import usv_mj.envs  # noqa: F401

    env = gymnasium.make_vec("usv_mj/Track-v0", num_envs=n_env, vectorization_mode="sync")
    try:
        return vector(n_env, seconds, repeats, None, vec=env)
    finally:
        env.close()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=1.0, help="length of one timed run [s]")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="N = 64 and 1024 (analytic), 2 and 16 (MuJoCo), 2 repeats")
    args = ap.parse_args(argv)
    import numba

    analytic_n = (64, 1024) if args.quick else (1, 64, 1024, 4096)
    mujoco_n = (2, 16) if args.quick else (1, 2, 16, 64)
    repeats = 2 if args.quick else args.repeats
    print(f"numba {numba.__version__}, {numba.config.NUMBA_NUM_THREADS} threads, {os.cpu_count()} CPUs, load average before: {' '.join(f'{v:.1f}' for v in os.getloadavg())}", flush=True)
    print("env steps/s (best of repeats, wall time); cpu = CPU seconds the process got per wall second")
    print("\nanalytic plant (usv_mj/Track-v0, plant='analytic': 10 RK4 substeps of 1 ms per env step)")
    print(f"{'N':>6} {'vector env':>14} {'bare RK4':>14} {'plant RK4':>14} {'bare/vector':>12}")
    for n in analytic_n:
        v, vc = vector(n, args.seconds, repeats, "analytic")
        b, bc = bare(n, args.seconds, repeats, "bare")
        pk, pc = bare(n, args.seconds, repeats, "plant")
        print(f"{n:6d} {v:14,.0f} {b:14,.0f} {pk:14,.0f} {b / v:11.2f}x   (cpu {vc:.2f}, {bc:.2f}, {pc:.2f})", flush=True)
    print("\nMuJoCo plant (usv_mj/Track-v0): 1 thread vs 2 threads, interleaved")
    print(f"{'N':>6} {'1 thread':>14} {'2 threads':>14} {'2/1':>6}   cpu per wall second (1t, 2t)")
    for n in mujoco_n:
        one = two = (0.0, 0.0)
        for _ in range(repeats):   # interleaved: the machine's load falls on both alike
            r1 = vector(n, args.seconds, 1, "mujoco", n_threads=1)
            r2 = vector(n, args.seconds, 1, "mujoco", n_threads=2)
            one, two = max(one, r1), max(two, r2)
        print(f"{n:6d} {one[0]:14,.0f} {two[0]:14,.0f} {two[0] / one[0]:6.2f}   ({one[1]:.2f}, {two[1]:.2f})", flush=True)
    s, sc = sync_vector(8, args.seconds, repeats)
    print(f"\ntoday's SyncVectorEnv of usv_mj/Track-v0 (MuJoCo), N = 8: {s:,.0f} env steps/s (cpu {sc:.2f})")
    print(f"load average after: {' '.join(f'{v:.1f}' for v in os.getloadavg())}; numba threading layer "
          f"{numba.threading_layer()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
