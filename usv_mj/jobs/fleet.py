"""The main job of a scenario with several vessels (``[[vessels]]``, issue 35): one run, every output.

What ``usv-mj run --scenario FLEET.toml`` writes into ``--out`` (staged, moved into place when the
job ends, completed, diverged or interrupted, as a single run's job: :mod:`usv_mj.jobs.run`):

- ``run.mcap``: the own ship's run log (run "main": ``/usv/...`` topics), and beside it one
  companion log per other vessel, ``vessel-NAME.mcap`` (run NAME: ``/NAME/usv/...`` topics and the
  frame ``NAME/base_link``), which :func:`usv_mj.outputs.log.read_run` of ``run.mcap`` reads with it
  (Foxglove: open them together); each with its events (a contact between hulls is one);
- ``summary.json``: each vessel's summary (:func:`usv_mj.record.summary.summarize`) and the
  encounter's (:func:`usv_mj.record.encounters.encounter_summary`: closest approaches, CPA,
  contacts, the own ship's safety domain);
- ``figures/``: the own ship's figures as a single run's, and ``fleet_tracks.png``,
  ``fleet_ranges.png`` (:mod:`usv_mj.outputs.fleet_figures`);
- ``report.md``: the vessels and the encounter in tables;
- ``video.mp4`` and ``video.png``: every vessel drawn (its hull, wake trail and name), the own
  ship's safety domain about it (:func:`usv_mj.outputs.render.planner.add_fleet`).

A job that fails (a crash, a plug-in's ``sys.exit``, an output the file system refused) raises
:class:`usv_mj.jobs.run.RunFailed` naming where its files and ``traceback.txt`` are: ``--out``, or,
when that holds an earlier run, ``.NAME.failed-PID`` beside it (the earlier run stays), as a single
run's job does.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from usv_mj.builder import build_fleet
from usv_mj.core.errors import ScenarioError
from usv_mj.jobs.run import RunFailed, _failed_in, _one_line, _OutLock, _Signals, progress_bar, write_json
from usv_mj.loop.fleet import simulate_fleet
from usv_mj.outputs.figures import draw_figures
from usv_mj.outputs.fleet_figures import draw_fleet_figures
from usv_mj.outputs.fleet_report import write_fleet_report
from usv_mj.outputs.outdir import Staging, check_folder
from usv_mj.record.encounters import encounter_summary
from usv_mj.record.summary import summarize


@dataclass
class FleetJobResult:
    out_dir: Path
    record: object
    summary: dict
    files: dict = field(default_factory=dict)


def log_name(vessel: str, own: str) -> str:
    """The run log file of a vessel: ``run.mcap`` for the own ship, ``vessel-NAME.mcap`` beside it."""
    return "run.mcap" if vessel == own else f"vessel-{vessel}.mcap"


def run_fleet_job(scenario, out_dir, *, plant_kind: str | None = None, log: bool = True, progress: bool = True,
                  overwrite: bool = False, live=None, video: bool = True, render_options: dict | None = None) -> FleetJobResult:
    """Run the fleet ``scenario`` and write every output into ``out_dir`` (module docstring)."""
    out = Path(out_dir)
    check_folder(out, overwrite)
    parts = build_fleet(scenario, plant_kind=plant_kind)    # every input checked before anything is created
    with _OutLock(out), _Signals() as signals:
        stage = Staging(out)
        failed = None
        try:
            result = _run(parts, stage.path, log, progress, live, signals, video, dict(render_options or {}))
        except (Exception, SystemExit) as exc:    # SystemExit: a plug-in's, outside the loop (a hook of render)
            from usv_mj.outputs.render import GLUnavailableError

            if isinstance(exc, (ScenarioError, GLUnavailableError)):    # bad input, no OpenGL: exit 2, 3
                raise
            failed = _failure(exc, stage.path)
            raise failed from exc
        finally:
            parts.close()
            with signals.deferred():
                # a job that failed never replaces an earlier run: that stays, its files go beside it
                staged = stage.path
                place = stage.finish(failed is not None)
                if failed is not None:
                    _failed_in(failed, staged, out, place)
    result.out_dir = out
    result.files = {k: out / Path(v).relative_to(stage.path) if isinstance(v, Path) else v
                    for k, v in result.files.items()}
    return result


def _failure(exc: BaseException, stage: Path) -> RunFailed:
    """The :class:`RunFailed` of a fleet's job that ``exc`` ended, its traceback written into
    ``stage`` (best effort: the disk may be full)."""
    where = stage / "traceback.txt"
    try:
        where.write_text("".join(traceback.format_exception(exc)))
    except OSError:
        where = None
    return RunFailed(f"the run failed: {_one_line(exc)}" + (f" (traceback in {where})" if where else
                                                           f" (what was written is in {stage}/)"),
                     stage, None, where)


def _run(parts, out: Path, log: bool, progress: bool, live, signals, video: bool, render_opts: dict) -> FleetJobResult:
    from contextlib import ExitStack

    scenario = parts.scenario
    own = next(v.name for v in parts.vessels if v.own_ship)
    files: dict = {}
    with ExitStack() as stack:
        sinks = {}
        if log:
            from usv_mj.outputs.log import RunLogWriter

            main = stack.enter_context(RunLogWriter(out / "run.mcap", next(v.scenario for v in parts.vessels
                                                                           if v.own_ship), live=live))
            files["mcap"] = out / "run.mcap"
            for v in parts.vessels:
                if v.name == own:
                    sinks[v.name] = [main.sink(run="main")]
                    continue
                writer = stack.enter_context(RunLogWriter(out / log_name(v.name, own), v.scenario, companion_of=main,
                                                          live=live))
                sinks[v.name] = [writer.sink(run=v.name)]
                files[f"mcap_{v.name}"] = out / log_name(v.name, own)
        cb, close = progress_bar(parts.duration, f"{len(parts.vessels)} vessels on {parts.plant.name}", progress,
                                 scenario.control_period)
        t0 = time.perf_counter()
        try:
            record = simulate_fleet(parts, progress=cb, sinks=sinks)
        finally:
            close()
    summaries = {name: summarize(record[name]) for name in record.names}
    encounters = encounter_summary(record)
    summary = {"vessels": summaries, "encounters": encounters, "own_ship": own, "status": record.status,
               "stop_reason": record.stop_reason, "plant": parts.plant.name, "duration_s": parts.duration,
               "wall_time_s": time.perf_counter() - t0}
    files["figures"] = draw_figures(record.own_record, out / "figures") + \
        draw_fleet_figures(record, out / "figures", summary=encounters)
    if video:
        from usv_mj.outputs.render import render_run

        stats = render_run(record.own_record, out / "video.mp4", fleet=record, domain=encounters.get("safety_domain_m")
                           or 0.0, progress=progress, **{k: v for k, v in render_opts.items()
                                                         if k in ("width", "height", "fps", "speedup", "camera",
                                                                  "workers", "gl")})
        files["video"], files["still"] = out / "video.mp4", Path(stats["png"])
        summary["render"] = {k: v for k, v in stats.items() if isinstance(v, (int, float, str))}
    files["report"] = write_fleet_report(out / "report.md", summary)
    files["summary"] = out / "summary.json"
    write_json(files["summary"], summary)
    return FleetJobResult(out, record, summary, files)


def one_screen_fleet_summary(result: FleetJobResult, wall_s: float) -> str:
    """What ``usv-mj run`` prints for a fleet: each vessel's status, the closest approaches, the files."""
    s = result.summary
    enc = s["encounters"]
    lines = [f"usv-mj run: {len(s['vessels'])} vessels on the {s['plant']} plant, {s['duration_s']:g} s: {s['status']}"
             + (f" ({s['stop_reason']})" if s["stop_reason"] else "") + f" in {wall_s:.1f} s"]
    for name, p in enc["pairs"].items():
        contact = f", contact at t = {p['contacts'][0]['t_s']:.1f} s" if p["contacts"] else \
            (f", hulls overlap from t = {p['hulls_overlap_from_s']:.1f} s (a collision)"
             if "hulls_overlap_from_s" in p else "")
        domain = ""
        if "safety_domain_entered" in p:
            domain = " (inside the own ship's safety domain)" if p["safety_domain_entered"] else " (outside the safety domain)"
        lines.append(f"  {name}: closest {p['min_range_m']:.2f} m at t = {p['t_min_range_s']:.1f} s{domain}{contact}")
    lines.append(f"outputs in {result.out_dir}/ (run.mcap and one log per other vessel, summary.json, report.md, figures/)")
    return "\n".join(lines)
