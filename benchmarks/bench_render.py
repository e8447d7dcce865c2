"""Render speed of the paper run's video: frames per second at 1280x720, 1 and 2 workers.

    python benchmarks/bench_render.py                 # 300 frames per configuration
    python benchmarks/bench_render.py --frames 900    # the whole 30 s video
    python benchmarks/bench_render.py --record run.pkl --keep out/   # reuse a pickled RunRecord
    python benchmarks/bench_render.py --pipeline      # simulate the paper run while the workers warm up,
                                                      # then render its 900 frames: the main job's video part

Prints, for each configuration: wall frames/s (planning, worker start-up, rendering, encoding and
joining included), CPU ms per frame over this process and its children (workers and ffmpeg), and the
frames/s that CPU cost would give on two idle cores. The yardstick measured in the same run is a bare
``mujoco.Renderer.render()`` of the same scene at the same size in this process, MuJoCo's default
settings (shadows, 4x multisampling) and with ours (no shadows, no multisampling), no overlay, no
encoding. The machine's load average is printed: other jobs share the cores.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def cpu_seconds() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def paper_record(path: str | None):
    if path:
        with open(path, "rb") as f:
            return pickle.load(f)
    from usv_mj import load_scenario, simulate

    t0 = time.perf_counter()
    rec = simulate(load_scenario(preset="paper", overrides={"plant": {"kind": "analytic"}}))
    print(f"simulated the paper run (analytic plant, {len(rec)} rows) in {time.perf_counter() - t0:.1f} s")
    return rec


def bare_renderer_fps(width: int, height: int, frames: int, ours: bool) -> float:
    """Frames/s of mujoco.Renderer on models/scene.xml, the hull moving along x, nothing else drawn."""
    import mujoco

    from usv_mj.outputs.render.replay import DEFAULT_SCENE

    spec = mujoco.MjSpec.from_file(str(DEFAULT_SCENE))
    spec.visual.global_.offwidth, spec.visual.global_.offheight = width, height
    if ours:
        spec.visual.quality.offsamples = 0
    m = spec.compile()
    d = mujoco.MjData(m)
    r = mujoco.Renderer(m, height, width)
    cam = mujoco.MjvCamera()
    cam.type, cam.elevation, cam.azimuth, cam.distance = mujoco.mjtCamera.mjCAMERA_FREE, -90.0, 90.0, 30.0
    r.update_scene(d, cam)
    r.render()
    t0 = time.perf_counter()
    for i in range(frames):
        d.qpos[0] = 0.05 * i
        mujoco.mj_forward(m, d)
        cam.lookat[:] = (d.qpos[0], 0, 0)
        r.update_scene(d, cam)
        if ours:
            r.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            r.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
            r.scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False
        r.render()
    fps = frames / (time.perf_counter() - t0)
    r.close()
    return fps


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300, help="frames per configuration (900 = the whole video)")
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    ap.add_argument("--record", default=None, help="a pickled RunRecord instead of simulating the paper run")
    ap.add_argument("--keep", default=None, help="directory to keep the videos and stills in")
    ap.add_argument("--camera", default="top")
    ap.add_argument("--pipeline", action="store_true",
                    help="RenderWorkers started, paper run simulated meanwhile, whole video rendered; total wall time")
    args = ap.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))

    from usv_mj.outputs.render import check_gl, render_run
    from usv_mj.outputs.render.gl_backend import renderer_name

    backend = check_gl()
    print(f"GL backend {backend}: {renderer_name(backend)}; cores usable: {len(os.sched_getaffinity(0))}; "
          f"load average at start: {os.getloadavg()[0]:.2f}")
    if args.pipeline:
        return pipeline(width, height, args.camera, Path(args.keep) if args.keep else None)
    rec = paper_record(args.record)
    out_dir = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_render_"))
    results = {}
    for w in (int(v) for v in args.workers.split(",")):
        c0 = cpu_seconds()
        info = render_run(rec, out_dir / f"paper_{args.camera}_w{w}.mp4", width=width, height=height, workers=w,
                          camera=args.camera, max_frames=args.frames, progress=False)
        cpu = cpu_seconds() - c0
        ms = 1e3 * cpu / info["frames"]
        results[w] = info
        print(f"workers={w}: {info['frames']} frames {width}x{height} in {info['wall_s']:.1f} s -> "
              f"{info['fps']:.1f} frames/s wall; CPU {ms:.1f} ms/frame (render + overlay + H.264) -> "
              f"{2e3 / ms:.1f} frames/s on 2 idle cores; load average now {os.getloadavg()[0]:.2f}")
        print(f"    {info['mp4']}  {info['png']}")
    n_bare = min(60, args.frames)
    for ours in (False, True):
        fps = bare_renderer_fps(width, height, n_bare, ours)
        label = "no shadows, no multisampling, no sky" if ours else "MuJoCo defaults (shadows, 4x MSAA)"
        print(f"yardstick: bare mujoco.Renderer.render() {width}x{height}, {label}: {fps:.1f} frames/s "
              f"(1 process, no overlay, no encoding)")
    best = max(results.values(), key=lambda r: r["fps"])
    print(json.dumps({"best_fps": best["fps"], "workers": best["workers"], "frames": best["frames"],
                      "projected_900_frames_s": 900 / best["fps"]}))
    return 0


def pipeline(width, height, camera, keep) -> int:
    """The video part of the main job: workers warm up while the 300 s paper run is simulated, then render."""
    from usv_mj.outputs.render import RenderWorkers, render_run

    out_dir = keep or Path(tempfile.mkdtemp(prefix="bench_render_"))
    t0 = time.perf_counter()
    c0 = cpu_seconds()
    with RenderWorkers(width=width, height=height, camera=camera) as pool:
        rec = paper_record(None)
        t_sim = time.perf_counter() - t0
        info = render_run(rec, out_dir / f"paper_{camera}.mp4", width=width, height=height, camera=camera, pool=pool,
                          progress=False)
    total = time.perf_counter() - t0
    cpu = cpu_seconds() - c0
    print(f"pipeline: simulate {t_sim:.1f} s (workers warming up meanwhile), render {info['frames']} frames "
          f"{width}x{height} in {info['wall_s']:.1f} s ({info['fps']:.1f} frames/s, {info['workers']} workers); "
          f"total {total:.1f} s wall, {cpu:.1f} s CPU; load average now {os.getloadavg()[0]:.2f}")
    print(f"    {info['mp4']}  {info['png']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
