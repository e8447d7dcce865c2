"""The main job: one scenario end to end (simulation, baseline, log, summary, figures, report, video).

``usv-mj run`` is a thin shell around :func:`run_job`, which a notebook can call too::

    from usv_mj import load_scenario
    from usv_mj.main_job import run_job
    result = run_job(load_scenario(preset="paper"), "renders/paper", video=False)
    result.summary["errors_at"]

Outputs in ``out_dir``: ``summary.json``, ``report.md``, ``figures/*.png``, ``run.mcap`` and the
baseline's ``baseline.mcap`` (unless ``log=False``), ``video.mp4`` and ``video.png``, its last frame (unless ``video=False``). Everything is written
from the finished records, so ``usv-mj plot run.mcap`` and ``usv-mj render run.mcap`` remake them.
"""

from __future__ import annotations

import dataclasses
import json
import math
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path

from .figures import draw_figures
from .record import RunRecord
from .report import write_report
from .scenario import Scenario
from .simulation import simulate
from .summary import CHECK_TIMES, pose_errors, summarize


@dataclass
class JobResult:
    """What :func:`run_job` made: the records, their summaries and the files written."""

    out_dir: Path
    record: RunRecord
    summary: dict
    baseline: RunRecord | None = None
    baseline_summary: dict | None = None
    step_check: dict | None = None
    files: dict = field(default_factory=dict)
    render_stats: dict | None = None


def progress_bar(total_s: float, desc: str, enabled: bool, dt: float):
    """A tqdm bar counting simulated seconds; returns (callback(n_steps), close())."""
    if not enabled:
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=round(total_s, 3), desc=desc, unit="s", unit_scale=False, dynamic_ncols=True,
               bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} s sim [{elapsed}<{remaining}]")
    def advance(n_rows: int) -> None:  # rows include t = 0, so the last block would overshoot by dt
        bar.update(min(n_rows * dt, bar.total - bar.n))

    return advance, bar.close


def step_size_check(scenario: Scenario, record: RunRecord, plant_kind: str | None = None) -> dict:
    """SPEC §5: run the first 20 s again at half the control period; how far do the errors at
    5 / 10 / 20 s move? (bound: 1 cm and 0.01 rad)."""
    horizon = max(CHECK_TIMES)
    dt = scenario.control_period
    if record["t"][-1] < horizon:
        return {}
    half = scenario.with_overrides({"control_period": dt / 2, "duration": horizon,
                                    "baseline": {"enabled": False}})
    fine = _simulate(half, plant_kind, None, [], None)
    if fine.status != "completed":
        return {"duration_s": horizon, "dt_half": dt / 2, "max_position_m": math.inf,
                "max_heading_rad": math.inf, "ok": False}
    e_c, e_f = pose_errors(record), pose_errors(fine)
    dpos, dpsi = 0.0, 0.0
    for tc in CHECK_TIMES:
        kc, kf = int(round(tc / dt)), int(round(tc / (dt / 2)))
        dpos = max(dpos, abs(e_c["x"][kc] - e_f["x"][kf]), abs(e_c["y"][kc] - e_f["y"][kf]))
        dpsi = max(dpsi, abs(e_c["psi"][kc] - e_f["psi"][kf]))
    return {"duration_s": horizon, "dt_half": dt / 2, "max_position_m": float(dpos),
            "max_heading_rad": float(dpsi), "ok": bool(dpos < 0.01 and dpsi < 0.01)}


class _VideoJob:
    """render_run in a thread (it only coordinates the worker processes); result() re-raises."""

    def __init__(self, fn):
        import threading

        self._value, self._error = None, None
        self._thread = threading.Thread(target=self._run, args=(fn,), name="usv-mj-video", daemon=True)
        self._thread.start()

    def _run(self, fn):
        try:
            self._value = fn()
        except BaseException as exc:  # handed to the caller in result()
            self._error = exc

    def result(self):
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._value


def _start_video(pool, record: RunRecord, path: Path, render_opts: dict) -> _VideoJob | None:
    if len(record) < 2:
        return None
    from .render import render_run

    return _VideoJob(lambda: render_run(record, path, progress=False, pool=pool, **render_opts))


def _simulate(scenario: Scenario, plant_kind: str, controller_kind: str | None, sinks, progress) -> RunRecord:
    """One closed-loop run through :func:`usv_mj.build` (obstacles, sea and guidance included)."""
    return simulate(scenario, plant_kind=plant_kind, controller_kind=controller_kind, sinks=sinks, progress=progress)


def _sea_outputs(scenario: Scenario, record: RunRecord, summary: dict, summary_out: dict, out: Path,
                 plant_kind: str, files: dict) -> str:
    """Issue 7: the sea's figures and summary fields, and the same scenario in calm water beside it."""
    from .sea_figures import draw_sea_figures, sea_summary

    env = record.statics.environment  # the sea the plant saw (from the build, not rebuilt)
    summary_out.update(sea_summary(record, env))
    files["sea_figures"] = draw_sea_figures(record, env, out / "figures")
    calm = scenario.with_overrides({"sea": {}, "baseline": {"enabled": False}})
    calm = dataclasses.replace(calm, sea=type(scenario.sea)())
    calm_summary = summarize(_simulate(calm, plant_kind, None, [], None))
    summary_out["calm"] = {k: calm_summary[k] for k in ("status", "errors_at", "max_abs_error_after_20s",
                                                         "funnel_violations", "first_violation_s")}
    held = "held" if summary["funnel_violations"] == 0 else f"was lost ({summary['funnel_violations']} steps outside)"
    lines = ["## The controller in this sea", "",
             f"Sea: {json.dumps(scenario.sea.to_dict())}; significant wave height seen at the hull "
             f"{summary_out['hs_at_hull_m']:.3f} m. The funnel {held}. The same scenario in calm water beside it "
             "(the controller is not tuned to the sea: the capability study is `usv-mj capability`):", "",
             "| error | t | in this sea | calm water |", "|---|---|---|---|"]
    for axis, unit in (("x", "m"), ("y", "m"), ("psi", "rad")):
        for tc in ("5", "10", "20"):
            a, b = summary["errors_at"][tc][axis], calm_summary["errors_at"][tc][axis]
            lines.append(f"| {axis} [{unit}] | {tc} s | {'—' if a is None else f'{a:.3f}'} | "
                         f"{'—' if b is None else f'{b:.3f}'} |")
    for axis in ("x", "y", "psi"):
        a, b = summary["max_abs_error_after_20s"][axis], calm_summary["max_abs_error_after_20s"][axis]
        lines.append(f"| max after 20 s, {axis} | | {'—' if a is None else f'{a:.3f}'} | "
                     f"{'—' if b is None else f'{b:.3f}'} |")
    lines += ["", "![Sampled wave spectrum against the target](figures/sea_spectrum.png)", "",
              "![Sea loads on the hull over time](figures/sea_loads.png)"]
    return "\n".join(lines)


def _write_json(path: Path, data: dict) -> None:
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
    tmp.replace(path)


def run_job(scenario: Scenario, out_dir, *, plant_kind: str | None = None, baseline: bool | None = None,
            video: bool = True, log: bool = True, progress: bool = True, step_check: bool = True,
            render_options: dict | None = None) -> JobResult:
    """Run ``scenario`` and write every output into ``out_dir`` (see the module docstring)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plant_kind = plant_kind or scenario.plant.kind
    run_baseline = scenario.baseline.enabled if baseline is None else baseline
    run_baseline = run_baseline and scenario.controller.kind != scenario.baseline.kind
    dt = scenario.control_period
    files: dict = {}
    render_opts = dict(render_options or {})
    with ExitStack() as stack:
        pool = None
        if video:
            from .render import RenderWorkers

            if scenario.obstacles and "model" not in render_opts:
                from .obstacles.compose import compose_scene, export_scene

                render_opts["model"] = export_scene(compose_scene(scenario.obstacles))
            # the render workers open their GL contexts while the ship is simulated
            pool = stack.enter_context(RenderWorkers(**{k: v for k, v in render_opts.items()
                                                        if k in ("width", "height", "camera", "workers", "gl",
                                                                 "model", "shadows")}))
        sink_main, sink_base = [], []
        if log:
            from .runlog import RunLogWriter

            writer = stack.enter_context(RunLogWriter(out / "run.mcap", scenario))
            sink_main = [writer.sink(run="main")]
            files["mcap"] = out / "run.mcap"
        cb, close = progress_bar(scenario.duration, f"{scenario.controller.kind.upper()} on {plant_kind}", progress, dt)
        try:
            record = _simulate(scenario, plant_kind, None, sink_main, cb)
        finally:
            close()
        # The video of the main run is drawn by the render workers while this process simulates the
        # baseline and the half-step check and draws the figures (the job then uses both cores).
        video_job = _start_video(pool, record, out / "video.mp4", render_opts) if pool is not None else None
        base_rec = None
        if run_baseline and record.status != "interrupted":
            if log:  # one file per run, each in log-time order; read_run(run.mcap) finds this one beside it
                base_writer = stack.enter_context(RunLogWriter(out / "baseline.mcap", scenario, companion_of=writer))
                sink_base, files["baseline_mcap"] = [base_writer.sink(run="baseline")], out / "baseline.mcap"
            cb, close = progress_bar(scenario.duration, f"{scenario.baseline.kind.upper()} baseline", progress, dt)
            try:
                base_rec = _simulate(scenario, plant_kind, scenario.baseline.kind, sink_base, cb)
            finally:
                close()
        summary = summarize(record)
        base_summary = summarize(base_rec) if base_rec is not None else None
        check = step_size_check(scenario, record, plant_kind) if step_check and record.status == "completed" else None
        summary_out = dict(summary)
        if base_summary:
            summary_out["baseline"] = {k: base_summary[k] for k in (
                "status", "errors_at", "max_abs_error_after_20s", "funnel_violations", "first_violation_s",
                "quantizer_switches")}
        if check:
            summary_out["step_check"] = check
        files["figures"] = draw_figures(record, out / "figures", base_rec, obstacles=scenario.obstacles)
        extra_sections = []
        if not scenario.sea.calm:
            extra_sections.append(_sea_outputs(scenario, record, summary, summary_out, out, plant_kind, files))
        files["report"] = write_report(out / "report.md", summary, base_summary, check, extra_sections)
        render_stats = video_job.result() if video_job is not None else None
        if render_stats is not None:
            files["video"] = out / "video.mp4"
            files["still"] = Path(render_stats["png"])
            summary_out["render"] = {k: (str(v) if isinstance(v, Path) else v) for k, v in render_stats.items()
                                     if isinstance(v, (int, float, str, Path))}
    files["summary"] = out / "summary.json"
    _write_json(files["summary"], summary_out)
    return JobResult(out, record, summary_out, base_rec, base_summary, check, files, render_stats)


def one_screen_summary(result: JobResult, wall_s: float) -> str:
    """The lines ``usv-mj run`` prints at the end."""
    s = result.summary
    lines = [f"usv-mj run: preset {s['preset']}, {s['plant']} plant, {s['controller']} controller: {s['status']}"]
    if s["status"] != "completed":
        lines.append(f"  stopped: {s['stop_reason']}")
    lines.append(f"  simulated {s['simulated_s']:.1f} s in {s['wall_time_s']:.2f} s "
                 f"({s['realtime_factor']:.0f}x real time); whole job {wall_s:.1f} s")
    lines.append("  errors x-x_d / y-y_d / psi-psi_d:")
    for tc, e in s["errors_at"].items():
        vals = " / ".join("—" if e[a] is None else f"{e[a]:+.3f}" for a in ("x", "y", "psi"))
        lines.append(f"    t = {tc:>2} s: {vals}")
    m = s["max_abs_error_after_20s"]
    if m["x"] is not None:
        lines.append(f"  max |error| after 20 s: {m['x']:.3f} m, {m['y']:.3f} m, {m['psi']:.3f} rad")
    lines.append(f"  funnel violations: {s['funnel_violations']} steps"
                 + (f" (first at {s['first_violation_s']:.2f} s)" if s["first_violation_s"] is not None else "")
                 + f"; s2 clamps: {s['s2_clamps']}; quantizer switches: u {s['quantizer_switches']['u']}, "
                   f"r {s['quantizer_switches']['r']}")
    if "baseline" in s:
        b = s["baseline"]
        lines.append(f"  PI baseline: {b['status']}, funnel violations {b['funnel_violations']}"
                     + (f" (first at {b['first_violation_s']:.2f} s)" if b["first_violation_s"] is not None else ""))
    if "step_check" in s:
        c = s["step_check"]
        lines.append(f"  half-step check: errors moved {c['max_position_m']*100:.3f} cm, {c['max_heading_rad']:.1e} rad")
    if s.get("min_clearance_m") is not None:
        lines.append(f"  obstacles: min clearance {s['min_clearance_m']:.3f} m, contacts {s['contacts']}")
    if result.record.metadata.get("note"):
        lines.append(f"  note: {result.record.metadata['note']}")
    if "render" in s:
        r = s["render"]
        lines.append(f"  video: {r.get('frames')} frames {r.get('width')}x{r.get('height')} in {r.get('wall_s', 0):.1f} s "
                     f"({r.get('fps', 0):.1f} frames/s rendered, {r.get('gl')}), played at {r.get('speedup', 0):.1f}x")
    lines.append(f"  outputs in {result.out_dir}/: " + ", ".join(sorted(
        p.name if isinstance(p, Path) else k for k, p in result.files.items())))
    return "\n".join(lines)


