"""Cost of the obstacle and environment topics of the run log and of the sea in the video (issues 7, 8).

Prints
1. encoding cost per control step (one thread, in-process): the six row topics (the yardstick), the
   ``/usv/obstacles`` message with 1, 10 and 50 obstacles, and ``/usv/environment`` (the loads
   recomputed with Environment.loads_record + elevation, 128 components, current and wind, then
   encoded);
2. a closed-loop run in a sea (analytic plant, moderate sea + current + wind): wall time without a
   log, with the background writer (which computes the environment topic), and the writer's CPU time;
3. rendering: frames per second at WxH in one process for the same poses in calm water and in the sea,
   and the sea update alone (elevation grid + hfield upload) per frame.

    python benchmarks/bench_extra_topics.py [--duration 60] [--size 1280x720] [--frames 30]

2 cores; other processes running at the same time inflate every figure: say so when quoting them.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from usv_mj.outputs.render.gl_backend import select_backend  # noqa: E402

SEA = {"preset": "moderate", "current": {"speed": 0.3, "direction_deg": 30.0},
       "wind": {"speed": 5.0, "direction_deg": 90.0, "gust_sigma": 1.0}}


def per_step(fn, n_rows, repeat=3):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best / n_rows * 1e6


def encoding(duration_rows: int = 10000):
    import numpy as np

    from usv_mj.record.run_record import COLUMNS
    from usv_mj.outputs.log.extra_topics import environment_block, environment_layout, obstacle_block, obstacle_layout
    from usv_mj.outputs.log.protobuf_rows import BinaryRows, FixedLayout, message_class
    from usv_mj.outputs.log.topics import ROW_TOPICS, row_topic_schema
    from usv_mj.scenario.spec import load_scenario
    from usv_mj.loop.simulate import make_environment, simulate

    sc = load_scenario(preset="paper", overrides={"duration": duration_rows * 1e-3, "sea": SEA,
                                                  "plant": {"kind": "analytic"}})
    t0 = time.perf_counter()
    rec = simulate(sc)
    sim_us = (time.perf_counter() - t0) / rec.n_rows * 1e6
    rec = simulate(sc)   # second run: compiled
    t0 = time.perf_counter()
    rec = simulate(sc)
    sim_us = (time.perf_counter() - t0) / rec.n_rows * 1e6
    block = rec.data[:rec.n_rows]
    n = block.shape[0]
    lt = np.rint(block[:, 0] * 1e9).astype(np.int64)
    col = {c: i for i, c in enumerate(COLUMNS)}     # the writer's layout of the row topics (RunLogFile)
    rows = BinaryRows([(i + 1, FixedLayout(message_class(row_topic_schema(title, f), title)), [col[c] for c in f])
                       for i, (_, title, f) in enumerate(ROW_TOPICS)])
    print(f"1. encoding per control step ({n} rows; simulation step in this sea: {sim_us:.1f} us)")
    print(f"   five row topics (yardstick)          {per_step(lambda: rows.encode(block, lt, 0), n):7.2f} us")
    for m in (1, 10, 50):
        one = obstacle_layout([f"obstacle_{i}" for i in range(m)])
        lay = BinaryRows([(20, one, range(len(one.paths)))])
        rng = np.random.default_rng(m)
        ob = obstacle_block(block[:, 0], rng.normal(size=(n, m)), np.zeros((n, m)), rng.normal(size=(n, m, 2)))
        print(f"   /usv/obstacles, {m:2d} obstacles         {per_step(lambda: lay.encode(ob, lt, 0), n):7.2f} us"
              f"  (+ {per_step(lambda: obstacle_block(block[:, 0], ob[:, 1::4], ob[:, 2::4], np.zeros((n, m, 2))), n):.2f} us"
              " to copy the arrays on the loop side)")
    env = make_environment(sc)
    one = environment_layout()
    lay = BinaryRows([(21, one, range(len(one.paths)))])
    environment_block(env, block[:10])
    comp = per_step(lambda: environment_block(env, block), n)
    eb = environment_block(env, block)
    enc = per_step(lambda: lay.encode(eb, lt, 0), n)
    print(f"   /usv/environment: loads {comp:.2f} us + encode {enc:.2f} us = {comp + enc:.2f} us "
          "(in the writer process, off the loop)")


def closed_loop(duration: float):
    from usv_mj.scenario.spec import load_scenario

    for name, over in (("calm water (no environment topic)", {}), ("the sea", {"sea": SEA})):
        sc = load_scenario(preset="paper", overrides={"duration": duration, "plant": {"kind": "analytic"}, **over})
        _closed_loop(sc, name)


def _closed_loop(sc, name):
    from usv_mj.outputs.log import RunLogWriter
    from usv_mj.loop.simulate import simulate

    duration = sc.duration
    simulate(sc, duration=1.0)
    t0 = time.perf_counter()
    simulate(sc)
    bare = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        with RunLogWriter(Path(tmp) / "sea.mcap", sc) as writer:
            rec = simulate(sc, sinks=[writer.sink("main")])
            loop = time.perf_counter() - t0
        total = time.perf_counter() - t0
        size = (Path(tmp) / "sea.mcap").stat().st_size
    print(f"2. {duration:.0f} s in {name}, analytic plant, {rec.n_rows} steps: bare {bare:.2f} s; with the log "
          f"loop {loop:.2f} s, with closing {total:.2f} s (+{100 * (total / bare - 1):.0f} %); writer CPU "
          f"{writer.stats.get('cpu_s', float('nan')):.2f} s; file {size / 1e6:.1f} MB")


def rendering(width: int, height: int, frames: int):
    import numpy as np

    from usv_mj.record.run_record import RunRecord
    from usv_mj.outputs.render.planner import plan_frames
    from usv_mj.outputs.render.replay import FrameRenderer
    from usv_mj.outputs.render.world import SEA_NODES
    from usv_mj.scenario.spec import load_scenario

    out = {}
    t = np.linspace(0.0, 30.0, frames)
    for name, over in (("calm", {}), ("sea", {"sea": SEA})):
        sc = load_scenario(preset="paper", overrides={"duration": 30.0, **over})
        rec = RunRecord.from_arrays({"t": t, "x": 0.5 * t, "y": np.sin(t / 5), "psi": 0.2 * np.ones_like(t),
                                     "x_d": 0.5 * t + 1, "y_d": 0 * t, "psi_d": 0 * t, "rho1": 4 + 0 * t,
                                     "rho2": 4 + 0 * t, "e1": 0 * t, "e2": 0 * t},
                                    metadata={"scenario": sc.to_dict()})
        plan = plan_frames(rec, rows=list(range(frames)), width=width, height=height)
        r = FrameRenderer(width, height)
        try:
            r.render(plan.frames[0])
            t0 = time.perf_counter()
            for spec in plan.frames:
                r.render(spec)
            out[name] = frames / (time.perf_counter() - t0)
            if name == "sea":
                import mujoco

                t0 = time.perf_counter()
                for spec in plan.frames:
                    r.update_sea(spec)
                    r.renderer._gl_context.make_current()
                    mujoco.mjr_uploadHField(r.model, r.renderer._mjr_context, r.sea_hfield)
                sea_ms = (time.perf_counter() - t0) / frames * 1e3
        finally:
            r.close()
    print(f"3. rendering {width}x{height}, one process: calm {out['calm']:.1f} frames/s, sea {out['sea']:.1f} "
          f"frames/s; sea update (elevation grid {SEA_NODES}x{SEA_NODES} + upload) {sea_ms:.1f} ms a frame")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=30)
    args = ap.parse_args()
    select_backend(None)
    w, h = (int(v) for v in args.size.split("x"))
    encoding()
    closed_loop(args.duration)
    rendering(w, h, args.frames)


if __name__ == "__main__":
    main()
