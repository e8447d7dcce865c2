"""The main job: one scenario end to end (simulation, baseline, log, summary, figures, report, video).

``usv-mj run`` is a thin shell around :func:`run_job`, which a notebook can call too::

    from usv_mj import load_scenario
    from usv_mj.jobs.run import run_job
    result = run_job(load_scenario(preset="paper"), "renders/paper", video=False)
    result.summary["errors_at"]

Outputs in ``out_dir``: ``summary.json``, ``report.md``, ``figures/*.png``, ``run.mcap`` and the
baseline's ``baseline.mcap`` (unless ``log=False``), ``video.mp4`` and ``video.png``, its last frame (unless ``video=False``). Everything is written
from the finished records, so ``usv-mj plot run.mcap`` and ``usv-mj render run.mcap`` remake them.
"""

from __future__ import annotations

import dataclasses
import json
import os
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path

from usv_mj.record.criteria import criterion_of_record
from usv_mj.outputs.figures import draw_figures
from usv_mj.record.run_record import RunRecord
from usv_mj.outputs.report import adaptation_section, gains_section, write_report
from usv_mj.scenario.spec import Scenario
from usv_mj.loop.simulate import simulate
from usv_mj.record.summary import CHECK_TIMES, baseline_line, criterion_line, outcome_sentence, pose_errors_at, summarize


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
    """docs/model.md §5: run the first 20 s again at half the control period; how far do the errors at
    5 / 10 / 20 s move? (bound: 1 cm and 0.01 rad)."""
    horizon = max(CHECK_TIMES)
    dt = scenario.control_period
    if record.value("t", -1) < horizon:
        return {}
    half = scenario.with_overrides({"control_period": dt / 2, "duration": horizon,
                                    "baseline": {"enabled": False}})
    # the main run's plan (made for its horizon), not one for 20 s: both runs track one reference
    fine = simulate(half, plant_kind=plant_kind, plan=getattr(record.statics, "plan", None))
    if fine.status != "completed":
        return {"duration_s": horizon, "dt_half": dt / 2, "max_position_m": None,  # JSON has no inf
                "max_heading_rad": None, "ok": False, "status": fine.status, "stop_reason": fine.stop_reason}
    dpos, dpsi = 0.0, 0.0
    for tc in CHECK_TIMES:
        kc, kf = int(round(tc / dt)), int(round(tc / (dt / 2)))
        e_c, e_f = pose_errors_at(record, kc), pose_errors_at(fine, kf)
        dpos = max(dpos, abs(e_c["x"] - e_f["x"]), abs(e_c["y"] - e_f["y"]))
        dpsi = max(dpsi, abs(e_c["psi"] - e_f["psi"]))
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
    from usv_mj.outputs.render import render_run

    return _VideoJob(lambda: render_run(record, path, progress=False, pool=pool, **render_opts))


def _simulate(scenario: Scenario, plant_kind: str, controller_kind: str | None, sinks, progress,
              store=None) -> RunRecord:
    """One closed-loop run through :func:`usv_mj.build` (obstacles, sea and guidance included);
    ``store``: the folder a long run's record streams into (``simulate(store=..., stream_above=...)``)."""
    from usv_mj.loop.simulate import STREAM_BYTES

    return simulate(scenario, plant_kind=plant_kind, controller_kind=controller_kind, sinks=sinks, progress=progress,
                    store=store, stream_above=STREAM_BYTES if store is not None else None)


def _sea_outputs(scenario: Scenario, record: RunRecord, summary: dict, summary_out: dict, out: Path,
                 plant_kind: str, files: dict) -> str:
    """Issue 7: the sea's figures and summary fields, and the same scenario in calm water beside it."""
    from usv_mj.outputs.sea_figures import draw_sea_figures, sea_summary

    env = record.statics.environment  # the sea the plant saw (from the build, not rebuilt)
    summary_out.update(sea_summary(record, env))
    files["sea_figures"] = draw_sea_figures(record, env, out / "figures")
    calm = scenario.with_overrides({"sea": {}, "baseline": {"enabled": False}})
    calm = dataclasses.replace(calm, sea=type(scenario.sea)())
    calm_summary = summarize(_simulate(calm, plant_kind, None, [], None))
    summary_out["calm"] = {k: calm_summary[k] for k in ("status", "errors_at", "max_abs_error_after_20s", "criterion",
                                                         "funnel_violations", "first_violation_s") if k in calm_summary}
    lines = ["## The controller in this sea", "",
             f"Sea: {scenario.sea.describe()} (compass degrees clockwise from north; waves and wind coming "
             f"from, the current setting toward; every setting in summary.json); significant wave height seen at the hull "
             f"{summary_out['hs_at_hull_m']:.3f} m. {outcome_sentence(summary['criterion'])} "
             "The same scenario in calm water beside it "
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


def write_json(path: Path, data: dict) -> None:
    """``data`` as indented JSON at ``path``, whole or not at all (a temporary file, then renamed);
    NaN or inf is refused (ValueError)."""
    tmp = path.with_suffix(".json.tmp")
    try:
        tmp.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


# --- endings: staging, signals, crashes ----------------------------------------------


class RunFailed(RuntimeError):
    """The run could not finish: the loop crashed, or an output could not be written (disk full, a
    worker that did not start). ``str()`` is the one line to print; ``summary`` is what
    ``summary.json`` in ``out_dir`` holds (when it could be written); ``traceback`` names the file
    with the traceback, if any."""

    def __init__(self, message: str, out_dir: Path, summary: dict | None = None, traceback: Path | None = None):
        super().__init__(message)
        self.out_dir, self.summary, self.traceback = out_dir, summary, traceback


class _OutLock:
    """One job at a time per output folder: an exclusive lock on ``.NAME.lock`` beside it, held for
    the whole job (a second run into the same --out while one is running is refused, exit 2)."""

    def __init__(self, out: Path):
        self.path = out.parent / f".{out.name}.lock"
        self.fd = None

    def __enter__(self):
        import fcntl
        import os

        from usv_mj.core.errors import ScenarioError

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fd = os.open(self.path, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            raise ScenarioError(f"--out {self.path.parent / self.path.name[1:-5]}: another run is writing "
                                "into it now; wait for it or choose another folder") from None
        return self

    def __exit__(self, *exc):
        import os

        if self.fd is not None:
            try:
                os.unlink(self.path)
            except OSError:
                pass
            os.close(self.fd)
            self.fd = None
        return False


from usv_mj.core.errors import Terminated, compiler_summary, expected, plain_text  # noqa: E402  (Terminated: SIGTERM / SIGHUP as Ctrl-C)


class _Signals:
    """While a job runs in the main thread: SIGTERM and SIGHUP raise :class:`Terminated` as Ctrl-C
    raises KeyboardInterrupt; the first signal only: after it the job finishes (summary, report)
    and later ones are noted in :attr:`received`. :meth:`deferred` holds every one of them back
    over a section that must not be cut (closing the log, moving the outputs into place).
    Handlers restored on exit."""

    NAMES = {"SIGINT": "Ctrl-C", "SIGTERM": "SIGTERM", "SIGHUP": "SIGHUP"}

    def __init__(self):
        import signal
        import threading

        self.signal = signal
        self.active = threading.current_thread() is threading.main_thread()
        self.received: list[str] = []     # every signal seen, in order
        self.stopping = False              # a signal has stopped the job: the next ones only noted
        self._old = {}

    def _raise(self, signum, frame):
        name = self.NAMES.get(self.signal.Signals(signum).name, self.signal.Signals(signum).name)
        self.received.append(name)
        if self.stopping:
            # a burst (SIGTERM, Ctrl-C, SIGHUP ms apart): the first stops the job, the others are noted.
            # Two signals that arrive together are handled at once, the second at the first bytecode
            # of the first one's except clause: raising there would skip the summary.
            return
        self.stopping = True
        raise (KeyboardInterrupt if name == "Ctrl-C" else Terminated)(name)

    def __enter__(self):
        import sys

        if self.active:
            for sig in (self.signal.SIGINT, self.signal.SIGTERM, self.signal.SIGHUP):
                self._old[sig] = self.signal.signal(sig, self._raise)
            # a signal that lands inside a weakref callback or a __del__ cannot propagate: Python
            # would print "Exception ignored in ..." with a traceback. Keep it quiet; the signal is
            # in self.received and the job stops at its next check.
            self._old_hook = sys.unraisablehook

            def hook(unraisable, previous=self._old_hook):
                if not isinstance(unraisable.exc_value, KeyboardInterrupt):
                    previous(unraisable)

            sys.unraisablehook = hook
        return self

    def __exit__(self, *exc):
        import sys

        for sig, handler in self._old.items():
            self.signal.signal(sig, handler)
        if self._old:
            sys.unraisablehook = self._old_hook
        self._old = {}
        return False

    @property
    def last(self) -> str:
        return self.received[-1] if self.received else "Ctrl-C"

    def deferred(self):
        from contextlib import contextmanager

        @contextmanager
        def hold():
            if not self._old:
                yield
                return
            held = []
            for sig in self._old:
                self.signal.signal(sig, lambda signum, frame: held.append(signum))
            try:
                yield
            finally:
                for sig in self._old:
                    self.signal.signal(sig, self._raise)
                for signum in held:
                    self.received.append(self.NAMES.get(self.signal.Signals(signum).name, "signal"))
        return hold()


def _relocate(obj, stage: Path, out: Path):
    """``obj`` with every path (or path string) under ``stage`` moved under ``out``."""
    if isinstance(obj, dict):
        return {k: _relocate(v, stage, out) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_relocate(v, stage, out) for v in obj]
    if isinstance(obj, (Path, str)):
        text = str(obj)
        if text.startswith(str(stage)):
            moved = str(out) + text[len(str(stage)):]
            return Path(moved) if isinstance(obj, Path) else moved
    return obj


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        where = exc.filename or ""
        return f"{where}: {exc.strerror}" if where else exc.strerror
    summary = compiler_summary(str(exc))   # numba's dozens of highlighted lines: what failed, and where
    if summary is not None:
        return f"{type(exc).__name__}: {summary}"
    text = [line.strip() for line in plain_text(exc).strip().splitlines() if line.strip()]
    if type(exc).__name__ in ("RunLogError", "RenderWorkerError") and text:
        return text[-1]
    # every line: a message's first line is often its reason (MuJoCo's "Error: mass and inertia of
    # moving bodies must be larger than mjMINVAL", then "Element name 'hull', id 1, line 54")
    return f"{type(exc).__name__}: {'; '.join(text)}".rstrip(": ")


def run_job(scenario: Scenario, out_dir, *, plant_kind: str | None = None, baseline: bool | None = None,
            video: bool = True, log: bool = True, progress: bool = True, step_check: bool = True,
            render_options: dict | None = None, overwrite: bool = False, log_rate: float | None = None,
            live=None, extra_outputs=None) -> JobResult:
    """Run ``scenario`` and write every output into ``out_dir`` (see the module docstring).

    Every input is checked first (:func:`usv_mj.jobs.preflight.check_run`: a ScenarioError leaves
    ``out_dir`` as it was); ``out_dir`` holding an earlier usv_mj output is refused unless
    ``overwrite``, and then replaced whole; a folder holding anything usv_mj did not write is
    always refused (:mod:`usv_mj.outputs.outdir`). The outputs are written into a staging folder
    beside ``out_dir`` and moved into place when the job ends (completed, diverged, interrupted).
    Ctrl-C, SIGTERM and SIGHUP stop the job (the summary says where and which outputs are
    missing); a crash or an output that cannot be written raises :class:`RunFailed` after the
    summary, the report and ``traceback.txt`` are written: into ``out_dir``, or, when it holds an
    earlier run, beside it (``.NAME.failed-PID``, cleared by the next run into it: the earlier run
    stays; ``RunFailed.out_dir`` says where).
    ``log_rate`` [Hz]: the MCAP logs every n-th control step (None: every step). A run whose
    record exceeds ``simulation.STREAM_BYTES`` streams it into ``record/`` (``baseline_record/``):
    ``RunRecord.open`` reads it back.
    ``live``: a :class:`usv_mj.outputs.log.live.LiveServer` that serves the logs' messages to Foxglove.

    ``extra_outputs(record, out)`` (a manoeuvre's measures, say) writes its own files into the
    staging folder ``out`` after the figures and returns (report sections, {name: path})."""
    from usv_mj.jobs.preflight import check_run
    from usv_mj.outputs.log.writer import log_every

    if not isinstance(scenario, Scenario):
        raise expected("run_job", "scenario", "a Scenario (usv_mj.load_scenario)", scenario)
    if not isinstance(out_dir, (str, os.PathLike)):
        raise expected("run_job", "out_dir", "the output folder's path (str or pathlib.Path)", out_dir)
    log_every(log_rate, scenario.control_period)   # a bad rate is refused before anything is written
    from usv_mj.outputs.outdir import Staging

    out = Path(out_dir)
    render_opts = dict(render_options or {})
    check_run(scenario, out, video=video, render_options=render_opts, overwrite=overwrite)
    from usv_mj.builder import check_commands

    run_baseline = scenario.baseline.enabled if baseline is None else baseline
    check_commands(scenario, scenario.controller.kind)
    if run_baseline and scenario.baseline.kind != scenario.controller.kind:
        check_commands(scenario, scenario.baseline.kind, " (it is the baseline: --no-baseline skips it)")
    from usv_mj.jobs.preflight import check_controller

    check_controller(scenario)   # a plug-in's contracts, before anything is written
    if run_baseline and scenario.baseline.kind != scenario.controller.kind:
        check_controller(scenario, scenario.baseline.kind)
    with _OutLock(out), _Signals() as signals:
        stage = Staging(out)
        failed = None
        try:
            result = _run_staged(scenario, stage.path, out, signals, plant_kind=plant_kind, baseline=baseline,
                                 video=video, log=log, progress=progress, step_check=step_check,
                                 render_opts=render_opts, log_rate=log_rate, live=live,
                                 extra_outputs=extra_outputs)
        except RunFailed as exc:
            failed = exc
            raise
        finally:
            with signals.deferred():
                # a run that failed (a crash, an output that could not be written) never replaces
                # an earlier one: that stays, and the failed run's files are kept beside it
                staged = stage.path
                place = stage.finish(failed is not None)
                if failed is not None:
                    _failed_in(failed, staged, out, place)
    result.out_dir = out
    for rec in (result.record, result.baseline):   # a streamed record's folder moved with the outputs
        if rec is not None and rec.stored:
            rec.relocated(_relocate(rec.path, stage.path, out))
    result.files = _relocate(result.files, stage.path, out)
    result.summary = _relocate(result.summary, stage.path, out)
    result.render_stats = _relocate(result.render_stats, stage.path, out)
    return result


def _failed_in(exc: RunFailed, staged: Path, out: Path, aside: Path | None) -> None:
    """``exc`` of a run staged in ``staged``, its files now in ``out`` (``aside`` None) or, when
    ``out`` kept an earlier run, in ``aside``: its paths and its line say where they are."""
    where = aside if aside is not None else out
    exc.out_dir, exc.summary = where, _relocate(exc.summary, staged, where)
    exc.traceback = _relocate(exc.traceback, staged, where)
    text = str(exc).replace(str(staged), str(where))
    if aside is not None:
        text = text.replace(f"{out}/", f"{aside}/") + (f"; {out} still holds the earlier run (--overwrite replaces "
                                                      f"it only with a run that ends; the next run into it "
                                                      f"clears {aside}/)")
    exc.args = (text,)


def _failed_summary(scenario: Scenario, plant_kind: str, status: str, reason: str, missing: list) -> dict:
    return {"preset": scenario.preset, "plant": plant_kind, "controller": scenario.controller.kind,
            "status": status, "stop_reason": reason, "missing_outputs": missing}


def _write_failure(stage: Path, summary: dict, tb: str | None) -> None:
    """Best effort (the disk may be full): summary.json, report.md and traceback.txt of a run that
    has no record to summarize."""
    try:
        if tb:
            (stage / "traceback.txt").write_text(tb)
        write_json(stage / "summary.json", summary)
        (stage / "report.md").write_text(
            f"# Run report\n\n**The run {summary['status']}:** {summary['stop_reason']}\n\n"
            + (f"Missing outputs: {', '.join(summary['missing_outputs'])}.\n" if summary["missing_outputs"] else "")
            + ("\nThe traceback is in `traceback.txt`.\n" if tb else ""))
    except OSError:
        pass


class _StagedJob:
    """The job itself, writing into the staging folder ``out``, in the phases :func:`_run_staged`
    calls in turn: :meth:`main_run` (the render workers, the log, the simulation), :meth:`outputs`
    (the baseline, the summaries, the half-step check, the figures, the report, the video) and
    :meth:`finish` (summary.json, and the report of a job that stopped early). The phases share the
    job's state: the files written, why the outputs stopped, an output that could not be written."""

    def __init__(self, scenario: Scenario, out: Path, final_out: Path, signals: _Signals, *, plant_kind, baseline,
                 video, log, progress, step_check, render_opts, log_rate=None, live=None, extra_outputs=None):
        self.scenario, self.out, self.final_out, self.signals = scenario, out, final_out, signals
        self.plant_kind = plant_kind or scenario.plant.kind
        run_baseline = scenario.baseline.enabled if baseline is None else baseline
        self.run_baseline = run_baseline and scenario.controller.kind != scenario.baseline.kind
        self.video, self.log, self.progress, self.step_check = video, log, progress, step_check
        self.render_opts, self.log_rate, self.live = render_opts, log_rate, live
        self.extra_outputs = extra_outputs   # (record, out) -> (report sections, {name: path}), or None
        self.dt = scenario.control_period
        self.files: dict = {}
        self.expected = ["summary.json", "report.md", "figures"] + (["run.mcap"] if log else []) + \
                        (["video.mp4", "video.png"] if video else [])
        self.stack = ExitStack()
        self.writer = self.base_writer = None
        self.every = None        # the log's n-th step
        self.pool = None
        self.stopped = None      # why the outputs after the simulation stopped (interrupt or fault)
        self.fault = None        # an output that could not be written: one line
        self.record = self.base_rec = self.check = None
        self.summary = self.base_summary = self.summary_out = None
        self.render_stats = None
        self.phase = "starting the video"
        self.seen_in_loop = 0    # the signals the loop itself reported (1: the one that interrupted it)

    def close_all(self) -> None:
        """Close the log (then the render pool) whatever comes in between; the log error, if any."""
        with self.signals.deferred():
            try:
                self.stack.close()
            except Exception as exc:       # RunLogError (disk full, worker gone) or OSError
                self.fault = self.fault or _one_line(exc)

    # --- the main run --------------------------------------------------------------------------

    def main_run(self) -> None:
        """The render workers (opening while the ship is simulated), the log and the main run; a
        failure or an interrupt here writes the failure's summary and raises :class:`RunFailed`."""
        import traceback

        scenario, out, render_opts, signals = self.scenario, self.out, self.render_opts, self.signals
        try:
            if self.video:
                from usv_mj.outputs.render import RenderWorkers

                if scenario.obstacles and "model" not in render_opts:
                    from usv_mj.scene.compose import compose_scene, export_scene

                    render_opts["model"] = export_scene(compose_scene(scenario.obstacles))
                # the render workers open their GL contexts while the ship is simulated
                from usv_mj.outputs.render.world import hull_dimensions

                self.pool = self.stack.enter_context(RenderWorkers(hull=hull_dimensions(scenario), **{
                    k: v for k, v in render_opts.items() if k in ("width", "height", "camera", "workers", "gl",
                                                                  "model", "shadows")}))
            sink_main = []
            if self.log:
                from usv_mj.outputs.log import RunLogWriter

                self.writer = self.stack.enter_context(RunLogWriter(out / "run.mcap", scenario, live=self.live))
                from usv_mj.outputs.log.writer import log_every

                self.every = log_every(self.log_rate, self.dt)
                sink_main = [self.writer.sink(run="main", log_every=self.every)]
                self.files["mcap"] = out / "run.mcap"
            cb, close = progress_bar(scenario.duration, f"{scenario.controller.kind.upper()} on {self.plant_kind}",
                                     self.progress, self.dt)
            try:
                self.record = _simulate(scenario, self.plant_kind, None, sink_main, cb, store=out / "record")
            finally:
                close()
        except KeyboardInterrupt:
            # outside the loop's own handler (setting up, or a second signal while it finished)
            self.close_all()
            reason = f"interrupted ({signals.last}) before the run could be summarized"
            with signals.deferred():      # a burst of signals: the next ones wait until the summary is written
                _write_failure(out, _failed_summary(scenario, self.plant_kind, "interrupted", reason,
                                                    [n for n in self.expected if n not in ("summary.json", "report.md",
                                                                                           "run.mcap")]), None)
            raise RunFailed(f"{reason}; outputs in {self.final_out}/", self.final_out, None) from None
        except Exception as exc:
            self.close_all()
            from usv_mj.outputs.render import GLUnavailableError

            if isinstance(exc, GLUnavailableError):
                raise
            tb = traceback.format_exc()
            reason = _one_line(exc) if self.fault is None else self.fault
            status = "failed"
            if signals.received:
                # a signal that landed inside compiled code can come out as another exception (SystemError)
                status, reason = "interrupted", f"interrupted by {signals.last} ({reason})"
            missing = [name for name in self.expected if name not in ("summary.json", "report.md", "run.mcap")]
            summary_fail = _failed_summary(scenario, self.plant_kind, status, reason, missing)
            summary_fail["traceback"] = "traceback.txt"
            _write_failure(out, summary_fail, tb)
            raise RunFailed(f"the run {status}: {reason} (traceback in {self.final_out}/traceback.txt)",
                            self.final_out, summary_fail, out / "traceback.txt") from None
        self._name_the_signal()

    def _name_the_signal(self) -> None:
        """The loop says Ctrl-C for every KeyboardInterrupt; say which signal it was (in a burst, the first)."""
        record, signals = self.record, self.signals
        first = signals.received[0] if signals.received else "Ctrl-C"     # the one that stopped the loop
        if record.status == "interrupted" and first != "Ctrl-C":
            record.stop_reason = record.stop_reason.replace("the user (Ctrl-C)", first)
            if record.events and record.events[-1].kind == "interrupted":
                record.events[-1] = dataclasses.replace(record.events[-1], message=record.stop_reason)
            record.finish_store()   # a streamed record's record.json says it too

    # --- the outputs ---------------------------------------------------------------------------

    def outputs(self) -> None:
        """The baseline, the summaries, the half-step check, the figures, the report and the video;
        an interrupt or an output that cannot be written stops them (:attr:`stopped` says where)."""
        scenario, out, record, signals = self.scenario, self.out, self.record, self.signals
        video_job = None
        # a signal whose exception was swallowed (raised inside a weakref callback, say) still stops the job
        self.seen_in_loop = 1 if record.status == "interrupted" else 0
        try:
            if len(signals.received) > self.seen_in_loop:
                raise KeyboardInterrupt(signals.last)
            # The video of the main run is drawn by the render workers while this process simulates the
            # baseline and the half-step check and draws the figures (the job then uses both cores).
            video_job = _start_video(self.pool, record, out / "video.mp4", self.render_opts) \
                if self.pool is not None else None
            if self.run_baseline and record.status != "interrupted":
                self.phase = f"running the {scenario.baseline.kind.upper()} baseline"
                self.base_rec = self._baseline()
            self.summary = summarize(record)
            # the baseline judged as the main run is (its criterion and its words)
            self.base_summary = summarize(self.base_rec, criterion_of_record(record)) \
                if self.base_rec is not None else None
            self.phase = "running the half-step check"
            self.check = step_size_check(scenario, record, self.plant_kind) \
                if self.step_check and record.status == "completed" else None
            self.summary_out = _summary_out(self.summary, self.base_summary, self.check)
            self.phase = "drawing the figures"
            self.files["figures"] = draw_figures(record, out / "figures", self.base_rec, obstacles=scenario.obstacles)
            adaptation = adaptation_section(record)   # a run whose controller adapts network weights
            extra_sections = [adaptation] if adaptation else []
            gains = gains_section(record, self.base_rec)   # the gains each law ran with (docs/gains.md)
            extra_sections += [gains] if gains else []
            if self.extra_outputs is not None:
                self.phase = "writing the manoeuvre's outputs"
                sections, extra_files = self.extra_outputs(record, out)
                extra_sections += list(sections)
                self.files.update(extra_files)
            if not scenario.sea.calm:
                self.phase = "drawing the sea figures"
                extra_sections.append(_sea_outputs(scenario, record, self.summary, self.summary_out, out,
                                                   self.plant_kind, self.files))
            self.phase = "writing the report"
            self.files["report"] = write_report(out / "report.md", self.summary, self.base_summary, self.check,
                                                extra_sections)
            self.phase = "rendering the video"
            self.render_stats = video_job.result() if video_job is not None else None
            if self.render_stats is not None:
                self.files["video"] = out / "video.mp4"
                self.files["still"] = Path(self.render_stats["png"])
                self.summary_out["render"] = {k: (str(v) if isinstance(v, Path) else v)
                                              for k, v in self.render_stats.items()
                                              if isinstance(v, (int, float, str, Path))}
        except KeyboardInterrupt:
            self.stopped = f"interrupted ({signals.last}) while {self.phase}"
        except (Exception, SystemExit) as exc:   # an output that cannot be written (disk full, read-only),
            self.fault = _one_line(exc)           # a worker, or a plug-in (a criterion) calling sys.exit
            self.stopped = f"stopped while {self.phase}: {self.fault}"

    def _baseline(self) -> RunRecord:
        """The baseline controller's run, logged beside the main run's log."""
        scenario, out = self.scenario, self.out
        sink_base = []
        if self.log:  # one file per run, each in log-time order; read_run(run.mcap) finds this one beside it
            from usv_mj.outputs.log import RunLogWriter

            base_writer = self.base_writer = self.stack.enter_context(RunLogWriter(
                out / "baseline.mcap", scenario, companion_of=self.writer, live=self.live))
            sink_base = [base_writer.sink(run="baseline", log_every=self.every)]
            self.files["baseline_mcap"] = out / "baseline.mcap"
        cb, close = progress_bar(scenario.duration, f"{scenario.baseline.kind.upper()} baseline", self.progress,
                                 self.dt)
        try:
            return _simulate(scenario, self.plant_kind, scenario.baseline.kind, sink_base, cb,
                             store=out / "baseline_record")
        finally:
            close()

    # --- the finish ----------------------------------------------------------------------------

    def finish(self) -> JobResult:
        """Close the log and the workers, write summary.json (and, when the job stopped early, the
        report that says so); :class:`RunFailed` when an output could not be written."""
        out, final_out, signals, files = self.out, self.final_out, self.signals, self.files
        self.close_all()
        if self.fault and not self.stopped:
            self.stopped = self.fault
        if not self.stopped and len(signals.received) > self.seen_in_loop:
            self.stopped = f"interrupted ({signals.last}) while {self.phase}"
        hold = signals.deferred()       # the finish holds further signals: the summary and report are written whole
        hold.__enter__()
        try:
            if self.summary is None:
                self.summary = summarize(self.record)
            if self.summary_out is None:
                self.summary_out = _summary_out(self.summary, self.base_summary, self.check)
            if self.stopped:
                self._stopped_report()
            files["summary"] = out / "summary.json"
            write_json(files["summary"], _relocate(self.summary_out, out, final_out))
        except KeyboardInterrupt:
            self.stopped = self.stopped or f"interrupted ({signals.last}) while writing the summary"
        except OSError as exc:
            self.fault = self.fault or _one_line(exc)
            files.pop("summary", None)
        finally:
            hold.__exit__(None, None, None)
        if self.fault:
            stopped, fault = self.stopped, self.fault
            message = stopped if stopped and fault in stopped else f"{fault}; {stopped}" if stopped else fault
            rec = self.record
            if rec is not None and rec.status in ("diverged", "failed"):   # the run's own end first: not hidden
                message = f"the run {rec.status}: {rec.stop_reason}; then {message}"
            raise RunFailed(f"{message} (what was written is in {final_out}/)".replace(str(out), str(final_out)),
                            final_out, self.summary_out)
        return JobResult(out, self.record, self.summary_out, self.base_rec, self.base_summary, self.check, files,
                         self.render_stats)

    def _stopped_report(self) -> None:
        """summary.json and report.md of a job whose outputs stopped early (what is missing)."""
        out, final_out, stopped, summary_out = self.out, self.final_out, self.stopped, self.summary_out
        if self.run_baseline and self.base_rec is None and self.record.status != "interrupted":
            summary_out["baseline"] = {"status": "not run", "stop_reason": stopped}
        summary_out["job_stopped"] = stopped
        summary_out["missing_outputs"] = self._missing_now()
        # the summary first: a second Ctrl-C while the report is written ends the job at once
        self.files["summary"] = out / "summary.json"
        write_json(self.files["summary"], _relocate(summary_out, out, final_out))
        try:
            write_report(out / "report.md", self.summary, self.base_summary, self.check,
                         [f"## The job stopped early\n\n{stopped}. Missing outputs: "
                          f"{', '.join(m for m in summary_out['missing_outputs'] if m != 'report.md') or 'none'}."])
            self.files["report"] = out / "report.md"
        except KeyboardInterrupt:
            summary_out["job_stopped"] = f"{stopped}; interrupted again ({self.signals.last}) while writing the report"
        summary_out["missing_outputs"] = self._missing_now()

    def _missing_now(self) -> list:
        """The expected outputs not (all) there, a log whose writer failed included (it holds the
        rows up to its last complete chunk, not the run's: issue 38)."""
        missing = _missing(self.out, self.expected, self.log)
        for writer in (self.writer, self.base_writer):
            if writer is not None and writer.failed and writer.path.name not in missing:
                missing.append(writer.path.name)
        return missing


def _run_staged(scenario: Scenario, out: Path, final_out: Path, signals: _Signals, *, plant_kind, baseline,
                video, log, progress, step_check, render_opts, log_rate=None, live=None,
                extra_outputs=None) -> JobResult:
    """The job itself, writing into the staging folder ``out``: the main run, the outputs, the finish
    (:class:`_StagedJob`)."""
    job = _StagedJob(scenario, out, final_out, signals, plant_kind=plant_kind, baseline=baseline, video=video,
                     log=log, progress=progress, step_check=step_check, render_opts=render_opts,
                     log_rate=log_rate, live=live, extra_outputs=extra_outputs)
    job.main_run()
    job.outputs()
    return job.finish()


def _summary_out(summary: dict, base_summary: dict | None, check: dict | None) -> dict:
    summary_out = dict(summary)
    if base_summary:
        summary_out["baseline"] = {k: base_summary[k] for k in (
            "status", "errors_at", "max_abs_error_after_20s", "criterion", "funnel_violations", "first_violation_s",
            "quantizer_switches") if k in base_summary}
    if check:
        summary_out["step_check"] = check
    return summary_out


def _missing(out: Path, expected: list, log: bool, summary_written: bool = True) -> list:
    """The expected outputs that are not (all) in ``out``: figures/ counts when it has all 7 figures."""
    missing = []
    for name in expected:
        p = out / name
        if name == "summary.json" and summary_written:
            continue
        if name == "figures":
            if len(list(p.glob("fig*.png"))) < 7:
                missing.append("figures/")
        elif not p.exists():
            missing.append(name)
    return missing


def one_screen_summary(result: JobResult, wall_s: float) -> str:
    """The lines ``usv-mj run`` prints at the end."""
    s = result.summary
    vessel = "" if s.get("vessel", "paper") == "paper" else f", vessel {s['vessel']}"
    lines = [f"usv-mj run: preset {s['preset']}{vessel}, {s['plant']} plant, {s['controller']} controller: "
             f"{s['status']}"]
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
    lines.append(criterion_line(s))
    if "baseline" in s:
        lines.append(baseline_line(s["baseline"]))
    if "step_check" in s:
        c = s["step_check"]
        if c.get("max_position_m") is None:
            lines.append(f"  half-step check: did not finish ({c.get('status', '?')})")
        else:
            lines.append(f"  half-step check: errors moved {c['max_position_m']*100:.3f} cm, {c['max_heading_rad']:.1e} rad")
    if s.get("min_clearance_m") is not None:
        lines.append(f"  obstacles: min clearance {s['min_clearance_m']:.3f} m, contacts {s['contacts']}")
    if s.get("job_stopped"):
        lines.append(f"  job stopped early: {s['job_stopped']}; missing outputs: "
                     f"{', '.join(s.get('missing_outputs') or []) or 'none'}")
    if result.record.metadata.get("note"):
        lines.append(f"  note: {result.record.metadata['note']}")
    if "render" in s:
        r = s["render"]
        lines.append(f"  video: {r.get('frames')} frames {r.get('width')}x{r.get('height')} in {r.get('wall_s', 0):.1f} s "
                     f"({r.get('fps', 0):.1f} frames/s rendered, {r.get('gl')}), played at {r.get('speedup', 0):.1f}x")
    lines.append(f"  outputs in {result.out_dir}/: " + ", ".join(written_outputs(result)))
    return "\n".join(lines)


def written_outputs(result: JobResult) -> list[str]:
    """The names in ``result.out_dir`` of what the job wrote and is there: files by name, a folder
    as ``figures/`` (every figure, the sea's too, is in that folder); nothing that was not written."""
    base = Path(result.out_dir).resolve()
    names = set()

    def add(value):
        if isinstance(value, dict):
            value = list(value.values())
        if isinstance(value, (list, tuple)):
            for v in value:
                add(v)
        elif isinstance(value, (str, Path)) and value and Path(value).exists():
            try:
                rel = Path(value).resolve().relative_to(base)
            except ValueError:
                return
            names.add(rel.parts[0] + ("/" if len(rel.parts) > 1 or Path(value).is_dir() else ""))

    add(result.files)
    return sorted(names)


