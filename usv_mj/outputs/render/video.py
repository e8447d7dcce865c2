"""Rendering a finished run to an H.264 mp4 and a PNG still, on all cores.

Pipeline: the parent process plans the frames (:mod:`usv_mj.outputs.render.planner`, numpy only), a pool of
worker processes each owning one GL context and one :class:`~usv_mj.outputs.render.replay.FrameRenderer` draws
them (frames are independent; ``imap`` keeps their order), and the parent feeds them to ffmpeg
(imageio-ffmpeg's bundled binary, libx264, yuv420p) and keeps the last one for the PNG.

Workers are started with the ``spawn`` method, after :func:`usv_mj.outputs.render.gl_backend.select_backend`
has exported ``MUJOCO_GL``: each worker imports mujoco fresh with the right backend, whatever the
parent imported before. (A script that calls :func:`render_run` with more than one worker needs the
usual ``if __name__ == "__main__":`` guard.) With one worker and a compatible (or not yet imported)
mujoco the frames are drawn in the parent itself.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from usv_mj.outputs.render.defaults import CAMERAS_HELP, MAX_FPS  # noqa: F401 (the renderer's limits, read here too)
from usv_mj.outputs.render.defaults import DEFAULT_FPS, DEFAULT_HEIGHT, DEFAULT_WIDTH, check_size
from usv_mj.outputs.render.gl_backend import GLUnavailableError  # noqa: F401 (what render_run raises)
from usv_mj.outputs.render.gl_backend import in_process_backend, renderer_name, select_backend
from usv_mj.outputs.render.planner import LAYERS, Plan, add_fleet, plan_frames


# --- workers -------------------------------------------------------------------------------------

_worker_renderer = None
_worker_counter = None


def worker_init(env: dict, renderer_kwargs: dict, counter=None) -> None:
    # A pool replaces a worker whose initializer raises, forever: keep the worker alive and
    # hand the reason to the first task instead, which fails the render with it.
    global _worker_error
    try:
        _worker_init_renderer(env, renderer_kwargs, counter)
    except Exception as exc:
        _worker_error = f"a render worker could not start: {exc}"


_worker_error = None


class RenderWorkerError(RuntimeError):
    """A render worker could not start (its GL context or scene); the message says why."""


def _check_worker():
    if _worker_error is not None:
        raise RenderWorkerError(_worker_error)


def _worker_init_renderer(env: dict, renderer_kwargs: dict, counter=None) -> None:
    os.environ.update(env)
    if env.get("MUJOCO_GL") == "glfw":
        os.environ.pop("PYOPENGL_PLATFORM", None)
    global _worker_renderer, _worker_counter
    from usv_mj.outputs.render.replay import FrameRenderer

    _worker_renderer = FrameRenderer(**renderer_kwargs)
    _worker_counter = counter
    # llvmpipe compiles a shader variant the first time each kind of draw is seen (~0.5 s in all):
    # do it now, while the pool warms up, rather than in the first frame of the video
    _worker_renderer.render(warmup_frame())


def warmup_frame():
    """A frame with every layer in it (hull, ghost, trail, path, funnel, overlay), for warming up a renderer."""
    from usv_mj.outputs.render.planner import FrameSpec, TopView

    line = np.array([[-3.0, 0.0], [-1.5, 0.2], [0.0, 0.0]])
    hud = {"t": 0.0, "t_end": 1.0, "speedup": 1.0, "title": "", "e": (0.1, -0.1, 0.01), "rho": (1.0, 1.0, 1.0),
           "tau_u": 1.0, "q_tau_u": 1.0, "tau_r": -1.0, "q_tau_r": -1.0, "tau_u_scale": 2.0, "tau_r_scale": 2.0}
    return FrameSpec(0, 0.0, (0.0, 0.0, 0.0), (1.0, 0.5, 0.1), (1.0, 0.5), (2.0, 2.0), True, line, line + 1.0,
                     TopView(0.0, 0.0, 6.0), hud)


def worker_render(spec):
    _check_worker()
    return _worker_renderer.render(spec)


def worker_close() -> None:
    """Free the worker's renderer now, so that nothing is left for its exit (a pool terminates
    its workers with SIGTERM, which may land while one is exiting)."""
    global _worker_renderer
    if _worker_renderer is not None:
        _worker_renderer.close()
        _worker_renderer = None


def _open_writer(path, width, height, fps, encoder):
    import imageio_ffmpeg

    writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264", pix_fmt_in="rgb24",
                                         pix_fmt_out="yuv420p", macro_block_size=1, ffmpeg_log_level="error",
                                         # one x264 thread: the workers are the parallelism (frame threads cost 8 % more CPU a frame)
                                         output_params=["-preset", encoder["preset"], "-crf", str(encoder["crf"]),
                                                        "-threads", "1"])
    writer.send(None)
    return writer


def _encode_segment(frames, path, width, height, fps, encoder, png=None, tick=None) -> int:
    """Encode the RGB ``frames`` (an iterator that renders them) into one H.264 mp4; ``tick()`` after each."""
    writer = _open_writer(path, width, height, fps, encoder)
    last, n = None, 0
    try:
        for frame in frames:
            writer.send(frame)
            last, n = frame, n + 1
            if tick is not None:
                tick()
    finally:
        writer.close()
    if png is not None and last is not None:
        from PIL import Image

        Image.fromarray(np.asarray(last)).save(png)
    return n


def _worker_segment(task):
    """One contiguous block of the video, rendered and encoded by this worker: (index, frames written)."""
    index, specs, path, width, height, fps, encoder, png = task
    _check_worker()
    frames = (_worker_renderer.render(s) for s in specs)
    return index, _encode_segment(frames, path, width, height, fps, encoder, png, _count_frame)


def _count_frame():
    if _worker_counter is not None:
        with _worker_counter.get_lock():
            _worker_counter.value += 1


class _FrameSource:
    """Frames of a plan, drawn in this process or by a pool of spawned workers (in order)."""

    def __init__(self, backend: str, workers: int, renderer_kwargs: dict):
        self.backend, self.workers, self.kwargs = backend, workers, renderer_kwargs
        self.pool = None
        self.local = None
        here = in_process_backend()
        self.in_process = workers == 1 and (here is None or here == backend)

    def __enter__(self):
        if self.in_process:
            from usv_mj.outputs.render.replay import FrameRenderer

            self.local = FrameRenderer(**self.kwargs)
        else:
            from usv_mj.outputs.render.gl_backend import backend_environment

            from usv_mj.support.spawning import spawn_context

            self.pool = spawn_context().Pool(self.workers, initializer=worker_init,
                                             initargs=(backend_environment(self.backend), self.kwargs))
        return self

    def frames(self, specs):
        if self.local is not None:
            return (self.local.render(s) for s in specs)
        return self.pool.imap(worker_render, specs, chunksize=2)

    def __exit__(self, exc_type, exc, tb):
        if self.local is not None:
            self.local.close()
        if self.pool is not None:
            if exc_type is None:
                self.pool.close()
            else:
                self.pool.terminate()
            self.pool.join()
        return False


def check_camera(camera: str, model=None) -> None:
    """ValueError naming the cameras there are when ``camera`` is not "top" nor a camera of the render
    model (compiled without GL, so it is cheap enough to check before anything starts)."""
    if camera == "top":
        return
    from usv_mj.outputs.render.replay import camera_names

    names = camera_names(model)
    if camera not in names:
        raise ValueError(f"camera {camera!r} is not in the render model; choose one of {', '.join(names)}")


def _default_workers(n_frames: int) -> int:
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, n_frames))


# --- public API ----------------------------------------------------------------------------------


def render_frames(record, *, width: int = 320, height: int = 240, camera: str = "top", rows=None,
                  fps: float = DEFAULT_FPS, speedup: float | None = None, max_frames: int | None = None,
                  layers=LAYERS, views=None, workers: int = 1, gl: str | None = None, model=None,
                  shadows: bool = False, samples: int = 0, hull="record", fleet=None,
                  domain: float = 0.0) -> list[np.ndarray]:
    """Frames of ``record`` as (height, width, 3) uint8 arrays, without writing a video.

    ``rows``: draw exactly these record rows (one frame each) instead of the video's time mapping.
    ``views``: a :class:`~usv_mj.outputs.render.planner.TopView` (or one per frame) to pin the top camera.
    ``hull``: the drawn hull's (L, B, T) [m]; "record" (default): the record's vessel's
    (:func:`usv_mj.outputs.render.world.hull_dimensions`); None: the model file's hull.
    ``fleet``, ``domain``: every other vessel of a fleet too, as :func:`render_run` draws them.
    """
    check_size(width, height)
    plan = _plan(record, fps=fps, speedup=speedup, width=width, height=height, camera=camera, max_frames=max_frames,
                 rows=rows)
    if fleet is not None:
        plan = add_fleet(plan, fleet, width, height, domain=domain)
    specs = plan.frames
    if views is not None:
        views = list(views) if isinstance(views, (list, tuple)) else [views] * len(specs)
        for s, v in zip(specs, views):
            s.view = v
    backend = select_backend(gl)
    kwargs = dict(width=width, height=height, camera=camera, model_path=model, layers=tuple(layers),
                  shadows=shadows, samples=samples, hull=_hull(record, hull))
    with _FrameSource(backend, max(1, int(workers)), kwargs) as source:
        return [np.array(f) for f in source.frames(specs)]


def _hull(record, hull):
    """The (L, B, T) the video draws: ``hull`` itself, or the record's vessel's for "record"."""
    if isinstance(hull, str) and hull == "record":
        from usv_mj.outputs.render.world import hull_dimensions

        return hull_dimensions(record)
    return None if hull is None else tuple(float(v) for v in hull)


def _plan(record, *, fps, speedup, width, height, camera, max_frames=None, rows=None) -> Plan:
    return plan_frames(record, fps=fps, speedup=speedup, width=width, height=height, camera=camera,
                       max_frames=max_frames, rows=rows)


def render_run(record, out_path, *, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT,
               fps: float = DEFAULT_FPS, speedup: float | None = None, camera: str = "top",
               workers: int | None = None, progress: bool = True, gl: str | None = None, model=None,
               shadows: bool = False, samples: int = 0, layers=LAYERS, crf: int = 23, preset: str = "ultrafast",
               max_frames: int | None = None, segment_frames: int = 120, pool: "RenderWorkers | None" = None,
               hull="record", fleet=None, domain: float = 0.0) -> dict:
    """Render ``record`` (a finished :class:`~usv_mj.record.run_record.RunRecord`) to an mp4 and a PNG of its last frame.

    Parameters
    ----------
    out_path: the .mp4 to write, or a directory (then ``<dir>/run.mp4``); the PNG goes beside it
        with the same stem.
    width, height: pixels (even). fps: frames per second of the video.
    speedup: run seconds per video second; default max(1, duration / 30 s) (a 300 s run -> 30 s).
    camera: "top", "chase", "overview", "chart" or another camera of the model (:data:`CAMERAS_HELP`).
    workers: rendering processes (default: the usable cores). With more than one, each worker renders
        and encodes contiguous blocks of ``segment_frames`` frames into its own H.264 segment, and
        the segments are joined without re-encoding (ffmpeg's concat demuxer): no frame crosses a
        process boundary.
    gl: "egl", "osmesa" or None (auto: the MUJOCO_GL variable, else EGL, else OSMesa).
    model: the scene MJCF (default models/scene.xml). shadows: MuJoCo's shadow pass (slow on Mesa).
    pool: :class:`RenderWorkers` started earlier (same size, camera and options, and the same hull:
        ``RenderWorkers(hull=hull_dimensions(scenario))``); not closed here.
    hull: the drawn hull's (L, B, T) [m]; "record" (default): the record's vessel's, scaled as the
        MuJoCo plant scales it (:func:`usv_mj.outputs.render.world.hull_dimensions`); None: the model file's.
    samples: multisampling. crf, preset: libx264 quality and speed (ultrafast: about 15 ms of CPU a
        720p frame, veryfast about 35 ms). max_frames: cap (tests).
    fleet: the :class:`usv_mj.record.fleet.FleetRecord` whose own ship ``record`` is: every other
        vessel drawn too (its hull, trail and name; :func:`usv_mj.outputs.render.planner.add_fleet`),
        with the own ship's safety domain of ``domain`` [m] (0: none).

    Returns a dict: frames, fps (frames rendered and encoded per wall second, planning and start-up
    included), wall_s, mp4, png, width, height, video_fps, video_s, speedup (as played), camera,
    workers, gl, gl_renderer, model.

    Raises GLUnavailableError (a RuntimeError) with the install message when no GL backend starts,
    ValueError for bad options.
    """
    wall0 = time.perf_counter()
    check_size(width, height)
    check_camera(camera, model)  # before the progress bar and any worker (RenderWorkers checks again)
    if not (isinstance(crf, int) and 0 <= crf <= 51):
        raise ValueError(f"crf = {crf!r}: libx264's quality must be an integer in [0, 51]")
    if preset not in X264_PRESETS:
        raise ValueError(f"preset = {preset!r}: use one of libx264's presets {', '.join(X264_PRESETS)}")
    out = Path(out_path)
    if out.suffix.lower() != ".mp4":
        out = out / "run.mp4"
    out.parent.mkdir(parents=True, exist_ok=True)
    _remove_dead_render_folders(out.parent)
    png = out.with_suffix(".png")
    kwargs = dict(width=width, height=height, camera=camera, model_path=model, layers=tuple(layers),
                  shadows=shadows, samples=samples, hull=_hull(record, hull))
    if pool is not None:
        if pool.pool is None:
            raise ValueError("pool: these RenderWorkers are closed")
        if not pool.matches(kwargs):
            raise ValueError(f"pool: the workers were started for {pool.kwargs}, the video asks for {kwargs}")
        backend = pool.backend
    else:
        backend = select_backend(gl)
    plan = plan_frames(record, fps=fps, speedup=speedup, width=width, height=height, camera=camera,
                       max_frames=max_frames)
    if fleet is not None:
        plan = add_fleet(plan, fleet, width, height, domain=domain)
    n = len(plan.frames)
    workers = _default_workers(n) if workers is None else max(1, min(int(workers), n))
    encoder = {"preset": preset, "crf": crf}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, unit="frame", desc=f"render {out.name}", file=sys.stderr, dynamic_ncols=True)
    if png.exists():
        png.unlink()
    try:
        if pool is None and _in_process(backend, workers):
            from usv_mj.outputs.render.replay import FrameRenderer

            renderer = FrameRenderer(**kwargs)
            model_label = renderer.model_label
            try:
                count = _encode_segment((renderer.render(s) for s in plan.frames), out, width, height, fps,
                                        encoder, png, (lambda: bar.update(1)) if bar is not None else None)
            finally:
                renderer.close()
            workers_used = 1
        else:
            if pool is not None:
                count = _render_segments(plan, out, png, pool, encoder, fps, segment_frames, bar)
                workers_used = pool.workers
            else:
                with RenderWorkers(workers=workers, gl=backend, **_pool_options(kwargs)) as own:
                    count = _render_segments(plan, out, png, own, encoder, fps, segment_frames, bar)
                workers_used = workers
            model_label = None
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - wall0
    if model_label is None:
        from usv_mj.outputs.render.replay import DEFAULT_SCENE  # noqa: imports mujoco; the backend is already chosen

        model_label = str(model) if model is not None else (str(DEFAULT_SCENE) if DEFAULT_SCENE.is_file()
                                                            else "built-in stand-in scene")
    return {
        "frames": count, "fps": count / wall if wall > 0 else math.inf, "wall_s": wall,
        "mp4": str(out), "png": str(png) if png.exists() else None,
        "width": width, "height": height, "video_fps": float(fps), "video_s": count / float(fps),
        "speedup": plan.played_speedup, "camera": camera, "workers": workers_used,
        "gl": backend, "gl_renderer": renderer_name(backend), "model": model_label,
        "hull_LBT_m": kwargs["hull"],
    }


X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow")


class RenderWorkers:
    """A pool of rendering processes started ahead of time (e.g. while the simulation runs).

    Each worker imports mujoco, compiles the scene and opens its GL context as soon as it starts,
    which takes 1-3 s; pass the pool to :func:`render_run` (``pool=``) to skip that wait::

        with RenderWorkers(width=1280, height=720, camera="top") as pool:
            record = simulate(scenario)                  # the workers warm up meanwhile
            info = render_run(record, "renders/run.mp4", pool=pool)

    The size, camera, layers and GL options of the pool are the ones the video gets.
    """

    def __init__(self, *, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT, camera: str = "top",
                 workers: int | None = None, gl: str | None = None, model=None, shadows: bool = False,
                 samples: int = 0, layers=LAYERS, hull=None):
        from usv_mj.outputs.render.gl_backend import backend_environment

        check_size(width, height)
        check_camera(camera, model)       # before any worker starts: a bad name fails every one of them
        self.backend = select_backend(gl)
        self.workers = _default_workers(1 << 30) if workers is None else max(1, int(workers))
        self.kwargs = dict(width=width, height=height, camera=camera, model_path=model, layers=tuple(layers),
                           shadows=shadows, samples=samples, hull=_hull(None, hull))
        from usv_mj.support.spawning import spawn_context

        ctx = spawn_context()
        self.counter = ctx.Value("i", 0)
        env = backend_environment(self.backend)
        if "LP_NUM_THREADS" not in os.environ:
            # one llvmpipe thread per worker: with a process per core, more threads only contend
            # (measured 60 vs 70 ms of CPU a 720p frame with 2 workers on 2 cores)
            env["LP_NUM_THREADS"] = "1"
        self.pool = ctx.Pool(self.workers, initializer=worker_init, initargs=(env, self.kwargs, self.counter))

    def matches(self, kwargs: dict) -> bool:
        return kwargs == self.kwargs

    def close(self, terminate: bool = True) -> None:
        """Stop the workers. They hold no unfinished output once render_run returned, so by default they
        are terminated: a clean interpreter exit of a worker (module teardown) took about 2 s here."""
        if self.pool is None:
            return
        if terminate:
            self.pool.terminate()
        else:
            self.pool.close()
        self.pool.join()
        self.pool = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close()
        return False


def _render_segments(plan, out, png, workers: RenderWorkers, encoder, fps, segment_frames, bar) -> int:
    """Workers render-and-encode blocks of frames into segment files; ffmpeg joins them into ``out``."""
    import tempfile

    n = len(plan.frames)
    per = max(1, min(int(segment_frames), math.ceil(n / workers.workers)))
    bounds = list(range(0, n, per)) + [n]
    width, height = workers.kwargs["width"], workers.kwargs["height"]
    with workers.counter.get_lock():
        workers.counter.value = 0
    with tempfile.TemporaryDirectory(prefix=f".render-{os.getpid()}-", dir=out.parent) as tmp:
        tasks = []
        for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            seg = Path(tmp) / f"seg{i:05d}.mp4"
            tasks.append((i, plan.frames[a:b], str(seg), width, height, fps, encoder,
                          str(png) if b == n else None))
        result = workers.pool.map_async(_worker_segment, tasks, chunksize=1)
        while not result.ready():
            result.wait(0.25)
            if bar is not None:
                bar.update(workers.counter.value - bar.n)
        written = dict(result.get())
        if bar is not None:
            bar.update(workers.counter.value - bar.n)
        _concat(sorted(Path(tmp).glob("seg*.mp4")), out)
    return int(sum(written.values()))


def _pool_options(kwargs: dict) -> dict:
    k = dict(kwargs)
    k["model"] = k.pop("model_path")
    return k


def _concat(segments, out: Path) -> None:
    """Join H.264 mp4 segments made with identical settings, without re-encoding."""
    import subprocess

    import imageio_ffmpeg

    listing = out.parent / (out.name + ".segments.txt")
    listing.write_text("".join(f"file '{p.resolve()}'\n" for p in segments))
    try:
        proc = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error", "-f", "concat",
                               "-safe", "0", "-i", str(listing), "-c", "copy", "-movflags", "+faststart", str(out)],
                              capture_output=True, text=True)
    finally:
        listing.unlink(missing_ok=True)
    if proc.returncode != 0:
        raise RuntimeError(f"ffmpeg could not join the video segments into {str(out)!r}: {proc.stderr.strip()}")


def _in_process(backend, workers):
    here = in_process_backend()
    return workers == 1 and (here is None or here == backend)


def check_gl(gl: str | None = None) -> str:
    """The GL backend rendering will use ("egl" or "osmesa"), or RuntimeError with what to install."""
    return select_backend(gl)


def _remove_dead_render_folders(folder: Path) -> None:
    """The segment folders (``.render-PID-*``) that a killed render left in ``folder``."""
    import shutil

    for p in folder.glob(".render-*-*"):
        try:
            pid = int(p.name.split("-")[1])
            os.kill(pid, 0)
        except ProcessLookupError:
            shutil.rmtree(p, ignore_errors=True)
        except (ValueError, PermissionError, OSError):
            continue


def load_run_record(path: str | os.PathLike):
    """The RunRecord of a run directory (its run.mcap) or of an .mcap file (via usv_mj.outputs.log)."""
    log, p = load_run_log(path)
    return log.record, p


def stored_record(path: str | os.PathLike):
    """(the stored RunRecord, the run's .mcap path) of a run directory that kept its record on disk
    (``record/``: runs too long to hold in memory, usv_mj.jobs.run), or None. It is read lazily: the
    video reads only the rows it draws (usv_mj.outputs.render.planner), where the MCAP would be read whole."""
    p = Path(path)
    if not (p.is_dir() and (p / "record" / "record.json").is_file()):
        return None
    from usv_mj.record.run_record import RunRecord

    return RunRecord.open(p / "record"), p / "run.mcap"


def load_run_log(path: str | os.PathLike):
    """(the RunLog, the .mcap path) of a run directory (its run.mcap) or of an .mcap file."""
    p = Path(path)
    if p.is_dir():
        candidates = [p / "run.mcap"] + sorted(p.glob("*.mcap"))
        mcap = next((c for c in candidates if c.is_file()), None)
        if mcap is None:
            raise FileNotFoundError(f"run directory {str(p)!r} holds no run.mcap")
        p = mcap
    elif not p.is_file():
        raise FileNotFoundError(f"run {str(p)!r} does not exist (give a run directory or an .mcap file)")
    if p.suffix.lower() != ".mcap":
        raise ValueError(f"run {str(p)!r}: expected an .mcap file or a run directory")
    try:
        from usv_mj.outputs.log import read_run
    except ImportError as exc:  # pragma: no cover - until the MCAP issue lands
        raise RuntimeError(f"reading {str(p)!r} needs usv_mj.outputs.log (the MCAP run log): {exc}") from exc
    return read_run(p), p


def default_output(run_path: Path, mcap_path: Path) -> Path:
    """Beside the run: ``<run dir>/run.mp4`` for a directory, ``<stem>.mp4`` beside an .mcap file."""
    if Path(run_path).is_dir():
        return Path(run_path) / "run.mp4"
    return mcap_path.with_suffix(".mp4")


def output_path(out, run_path, mcap_path: Path) -> Path:
    """Where ``usv-mj render --out OUT`` writes: OUT itself (an .mp4), or, when OUT is a folder that
    exists, the default name (:func:`default_output`) in it; no OUT: :func:`default_output`."""
    default = default_output(Path(run_path), mcap_path)
    if not out:
        return default
    p = Path(out)
    return p / default.name if p.is_dir() else p
