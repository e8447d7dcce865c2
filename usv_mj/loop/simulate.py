"""The closed loop: reference -> controller -> quantizer -> actuators -> plant, one control period at a time.

The loop knows its parts only through their interfaces (:mod:`usv_mj.plants.base`,
:mod:`usv_mj.controllers.base`), and gets them from :func:`usv_mj.build` (or from a caller that
built them). Each step it records one row of the :class:`~usv_mj.record.run_record.RunRecord` (the core
columns, then the controller's declared diagnostics); every ``block`` rows it hands the new rows
to the sinks (the MCAP writer, say). A long run's record streams to disk as it is made
(:mod:`usv_mj.record.store`, one file per column, appended every block): only a window of two
blocks is in memory, so a run's memory does not grow with its duration (``store``).

A run stops early, with a recorded event and a status, on divergence (a non-finite or out-of-limit
state or force, :class:`usv_mj.scenario.spec.LimitsSpec`), on an exception in a part, or on Ctrl-C;
the rows up to the stop stay valid and the sinks are always finished.
"""

from __future__ import annotations

import math
import os
import time
from typing import Callable, Iterable, NamedTuple, Protocol

import numpy as np

from usv_mj.core import arguments
from usv_mj.core.errors import PluginContractError, PluginExit, Terminated, message_line
from usv_mj.core.kernels import diag_contract, diag_mismatch, diag_row_problem
from usv_mj.physics.limits import within_limits
from usv_mj.builder import Parts, build, channels_of, make_actuators, make_controller, make_environment, make_quantizers  # noqa: F401 (API)
from usv_mj.builder import FleetParts, build_fleet
from usv_mj.loop.fleet import simulate_fleet
from usv_mj.loop.step import ControlStep
from usv_mj.record.events import detect_events, json_number as _json_number  # noqa: F401 (detect_events: API)
from usv_mj.record.run_record import COL, N_CORE, SL_REF, SL_STATE, Event, RunRecord
from usv_mj.core.layouts import REF_FIELDS
from usv_mj.scenario.spec import Scenario
from usv_mj.references import trajectories

N_REF_RECORDED = len(REF_FIELDS)

#: a record bigger than this (rows x columns x 8 bytes) streams to disk when ``store`` is None
STREAM_BYTES = 256 * 2 ** 20


class RunSink(Protocol):
    """Receives a run as it is made: ``start(record)``, ``rows(record, lo, hi)``, ``finish(record)``."""

    def start(self, record: RunRecord) -> None: ...

    def rows(self, record: RunRecord, lo: int, hi: int) -> None: ...

    def finish(self, record: RunRecord) -> None: ...


def make_reference(scenario: Scenario, duration: float | None = None):
    """The scenario's reference trajectory over ``duration`` [s] (default: the scenario's)."""
    return trajectories.make_reference(scenario.trajectory, scenario.duration if duration is None else duration, scenario)


def state_limit_exceeded(x, ex: float, ey: float, limits) -> bool:
    """True when the state left :class:`usv_mj.scenario.spec.LimitsSpec` (or is not finite): the one check
    of divergence, used by the loop and by the dm_control tasks."""
    return not within_limits(x, float(ex), float(ey), float(limits.max_speed), float(limits.max_yaw_rate),
                             float(limits.max_distance))


def simulate(scenario: Scenario | Parts, plant=None, controller=None, *, plant_kind: str | None = None,
             controller_kind: str | None = None, sinks: Iterable[RunSink] = (), block: int = 2000,
             progress: Callable[[int], None] | None = None, duration: float | None = None,
             reference=None, hooks: Iterable[Callable] = (), loop: str = "auto", store=None,
             stream_above: float | None = None, plan=None) -> RunRecord:
    """Run in closed loop and return the :class:`RunRecord`.

    ``scenario`` is a :class:`Scenario` (built here with :func:`usv_mj.build`, with ``plant_kind``,
    ``controller_kind``, ``duration`` and any ready-made ``plant`` / ``controller`` / ``reference``)
    or the :class:`Parts` of an earlier build (``plan``: an earlier build's obstacle plan to run
    again). ``hooks`` are called as ``hook(t, k, plant)`` at
    every control step before the reference is evaluated, after the build's own. ``progress(n)``
    is called with the number of new steps every block. A plant the build made is closed here.
    The record's ``statics`` are the build's (the sea the plant saw, the obstacles, the plan).

    ``loop``: "auto" runs the compiled loop (:mod:`usv_mj.loop.compiled`) when every part has a
    kernel (and the hook, if any: the obstacles' hook has one for standing obstacles without
    guidance), the Python loop otherwise; "python" always runs the Python loop.
    ``record.metadata["loop"]`` says which ran (``"loop_reason"``: why not the compiled one).

    ``store``: where the record's rows go. None: in memory, but a record of more than
    :data:`STREAM_BYTES` streams into a temporary folder (removed with the record); False: in
    memory; True: a temporary folder; a path: that folder, kept (:meth:`RunRecord.open` reads it
    back), or with ``stream_above`` [bytes] only for a record bigger than that (in memory
    otherwise). A streamed record keeps two blocks of rows in memory and has the same values, bit
    for bit.
    """
    if loop not in ("auto", "python"):
        raise ValueError(f"simulate: loop must be 'auto' or 'python', got {loop!r}")
    block = arguments.integer("simulate", "block", block, 1, "the number of rows between the sinks' flushes, "
                              "an integer >= 1")
    arguments.callable_or_none("simulate", "progress", progress, "a callable progress(n_new_steps) or None")
    sinks = arguments.each("simulate", "sinks", sinks, "a run sink (an object with start, rows, finish)",
                           lambda s: all(callable(getattr(s, m, None)) for m in ("start", "rows", "finish")),
                           "a list of run sinks (objects with start, rows, finish)")
    hooks = arguments.each("simulate", "hooks", hooks, "a hook, a callable hook(t, k, plant)", callable,
                           "a list of hooks, callables hook(t, k, plant)")
    duration = arguments.seconds("simulate", "duration", duration)
    if reference is not None:
        arguments.having("simulate", "reference", reference, ("evaluate",), "a reference trajectory")
    if isinstance(scenario, FleetParts) or (isinstance(scenario, Scenario) and scenario.vessels):
        return _simulate_fleet(scenario, plant_kind, duration, progress, block)
    if not isinstance(scenario, Parts):
        from usv_mj.builder import as_scenario

        scenario = as_scenario(scenario, "simulate")  # a preset name is loaded
    if isinstance(scenario, Parts):
        parts = scenario
    else:
        parts = build(scenario, plant_kind=plant_kind, controller_kind=controller_kind, duration=duration,
                      plant=plant, controller=controller, reference=reference, plan=plan)
    try:
        return _run(parts, list(parts.sinks) + list(sinks), block, progress, tuple(parts.hooks) + tuple(hooks),
                    use_compiled=loop == "auto", store=store, stream_above=stream_above)
    finally:
        parts.close()


def _simulate_fleet(scenario, plant_kind, duration, progress, block):
    """A scenario with [[vessels]] (or the parts of one): usv_mj.loop.fleet's loop over its vessels."""
    parts = scenario if isinstance(scenario, FleetParts) else build_fleet(scenario, plant_kind=plant_kind,
                                                                            duration=duration)
    try:
        return simulate_fleet(parts, progress, block)
    finally:
        parts.close()


def _diagnostic_units(controller, fields: tuple) -> dict:
    """``{"diagnostic_units": {field: unit}}`` of the controller's declared units of its diagnostic
    fields (:mod:`usv_mj.controllers.base`), for the figures; {} when it declares none."""
    units = getattr(controller, "diagnostic_units", None) or {}
    units = {str(k): str(v) for k, v in dict(units).items() if k in fields}
    return {"diagnostic_units": units} if units else {}


def _new_record(rows: int, block: int, store, metadata: dict, fields: tuple, events,
                stream_above: float | None = None) -> RunRecord:
    """The empty record of a run of ``rows`` rows: in memory, or streamed (``store``, see simulate)."""
    size = rows * (N_CORE + len(fields)) * 8
    if store is None:
        store = size > STREAM_BYTES
    elif store is not False and store is not True and stream_above is not None and size <= stream_above:
        store = False
    if store is False:
        return RunRecord(rows, metadata=metadata, diagnostic_fields=fields, diagnostic_events=events)
    import tempfile

    temporary = store is True
    folder = tempfile.mkdtemp(prefix="usv_mj_record_") if temporary else store
    window = min(rows, 2 * block + 2)   # a block, the row before it, and room for a block not yet flushed
    return RunRecord.streamed(folder, window, metadata, fields, events, temporary=temporary)


class _Start(NamedTuple):
    """A run made ready by :func:`_start`: its first row is next."""

    record: RunRecord
    step: ControlStep
    compiled: dict | None       # the parts' kernels (taken again after the resets), or None: the Python loop
    flush: "_Flusher"
    limits: object
    dt: float
    n: int
    wall0: float


def _start(parts: Parts, sinks: list, block: int, progress, hooks: tuple, use_compiled: bool = True,
           store=None, stream_above=None) -> _Start:
    """What a run does before its first row (the single run's :func:`_run`, and each episode of a
    batch, usv_mj.loop.batch): the record and its metadata, the sinks started, the parts reset."""
    scenario, plant, controller = parts.scenario, parts.plant, parts.controller
    duration = parts.duration
    dt = scenario.control_period
    n = int(round(duration / dt))
    actuators = parts.actuators if parts.actuators is not None else make_actuators(scenario, getattr(controller, "commands", "forces"))
    step = ControlStep(parts.quantizers, actuators)   # clip -> quantize -> actuators -> the row (usv_mj.loop.step)
    limits = scenario.limits
    fields = tuple(getattr(controller, "diagnostic_fields", ()))
    problem = diag_contract(controller)   # before anything runs: a kernel's diag against the fields
    if problem is not None:
        raise PluginContractError(problem)
    from usv_mj.loop.compiled import kernels_of
    from usv_mj.record.criteria import criterion_of, criterion_to_dict

    compiled, why = (None, "asked for (loop='python')") if not use_compiled else kernels_of(parts, hooks)
    loop = {"loop": "compiled"} if compiled is not None else {"loop": "python", "loop_reason": why}
    record = _new_record(n + 1, block, store, {
        "preset": scenario.preset, "plant": plant.name, "controller": controller.name,
        "duration_s": duration, "control_period_s": dt, "source": scenario.source,
        "scenario": scenario.to_dict(), "diagnostic_fields": list(fields), **_diagnostic_units(controller, fields),
        **parts.metadata, **loop,
        "criterion": criterion_to_dict(criterion_of(controller)),  # how the outputs judge the run (usv_mj.record.criteria)
        "channels": channels_of(scenario, getattr(controller, "commands", "forces")).to_metadata(),  # what tau and f hold
    }, fields, getattr(controller, "diagnostic_events", None), stream_above)
    record.statics = parts.statics
    for sink in sinks:
        sink.start(record)
        if hasattr(sink, "scene") and hasattr(plant, "scene_xml"):  # the run log keeps the scene the plant ran
            sink.scene(plant.scene_xml())
    plant.reset(scenario.initial.eta, scenario.initial.nu, 0.0)
    controller.reset()
    step.reset()
    flush = _Flusher(record, sinks, progress)
    return _Start(record, step, compiled, flush, limits, dt, n, time.perf_counter())


def _run(parts: Parts, sinks: list, block: int, progress, hooks: tuple, use_compiled: bool = True,
         store=None, stream_above=None) -> RunRecord:
    record, step, compiled, flush, limits, dt, n, wall0 = _start(parts, sinks, block, progress, hooks, use_compiled,
                                                                 store, stream_above)
    from usv_mj.loop.compiled import kernels_of

    plant, controller, reference = parts.plant, parts.controller, parts.reference
    fields = record.diagnostic_fields
    data = record.buffer   # the rows from record.base on (all of them when in memory)
    base = 0
    sl_diag = slice(len(COL), len(COL) + len(fields))
    n_fields = len(fields)
    c_t = COL["t"]
    k = 0
    try:
        if compiled is not None:
            compiled, _ = kernels_of(parts, hooks, step)  # again after the resets: the kernels' state is theirs
            k = _run_compiled(record, parts, compiled, block, flush, limits, dt, n, hooks)
            raise _Done
        x = plant.state
        while True:
            t = k * dt
            for hook in hooks:
                hook(t, k, plant)
            ref = reference.evaluate(t)
            tau_u, tau_r, diag = controller(t, x.copy(), ref)  # its own copy: the row and the actuators keep x
            problem = diag_row_problem(controller, diag, n_fields)   # before the row takes it
            if problem is not None:
                raise PluginContractError(problem)
            if not (abs(tau_u) < limits.max_force and abs(tau_r) < limits.max_force):
                _stop_diverged(record, t, f"control force out of limits or not finite: tau_u = {tau_u!r}, "
                               f"tau_r = {tau_r!r}", {"tau_u": _json_number(tau_u), "tau_r": _json_number(tau_r)},
                               data, k - base, x, ref, diag, sl_diag)
                k += 1
                break
            row = data[k - base]
            row[c_t] = t
            row[SL_STATE] = x
            row[SL_REF] = ref[:N_REF_RECORDED]   # the record's 7 reference columns (the accelerations are not recorded)
            row[sl_diag] = diag
            f_u, f_r = step(tau_u, tau_r, x, row)   # clip -> quantize -> actuators, the row's control columns
            k += 1
            record.n_rows = k
            if k - flush.mark >= block:
                flush(k)
                base = record.base
            if k > n:
                break
            plant.step(f_u, f_r)
            x = plant.state
            ex, ey = x[0] - ref[0], x[1] - ref[1]
            if state_limit_exceeded(x, ex, ey, limits):
                _state_diverged(record, k * dt, x, ex, ey, limits)
                break
        if record.status == "running":
            record.status = "completed"
    except _Done:
        if record.status == "running":
            record.status = "completed"
    except KeyboardInterrupt as exc:  # Ctrl-C, or a signal the caller raises as one (str: its name)
        k = record.n_rows if compiled is not None else k
        _interrupted(record, exc, k * dt)
    except Exception as exc:  # recorded, then re-raised after the sinks are finished
        k = record.n_rows if compiled is not None else k
        if _failed(record, exc, k * dt):  # a signal that landed in compiled code surfaces as SystemError
            _finish_run(record, sinks, flush, wall0, step)
            return record
        _finish_run(record, sinks, flush, wall0, step)
        raise
    except SystemExit as exc:  # a plug-in that ends the program: the run fails, with its rows
        k = record.n_rows if compiled is not None else k
        failure = PluginExit.during_run(exc, k * dt)
        record.status, record.stop_reason = "failed", str(failure)
        record.events.append(Event(k * dt, "failed", record.stop_reason))
        _finish_run(record, sinks, flush, wall0, step)
        raise failure from exc
    _finish_run(record, sinks, flush, wall0, step)
    return record


def interrupter(exc: BaseException) -> str:
    """Who interrupted a run, in words: "the user (Ctrl-C)", a signal's name (SIGTERM, SIGHUP), the
    reason usv_mj's own code gave ("closing the viewer"), or a KeyboardInterrupt a part raised
    (a plug-in's: where, and its text), which is not a signal."""
    text = str(exc)
    if text in ("", "Ctrl-C"):
        return "the user (Ctrl-C)"
    if isinstance(exc, Terminated):
        return text
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    where = os.path.abspath(tb.tb_frame.f_code.co_filename) if tb is not None else ""
    if where.startswith(_PACKAGE_DIR):
        return text
    return f"a KeyboardInterrupt raised at {os.path.basename(where)}:{tb.tb_lineno} ({text!r}), not a signal" \
        if tb is not None else f"a KeyboardInterrupt ({text!r}), not a signal"


_PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep   # usv_mj/


def _failed(record: RunRecord, exc: BaseException, t: float) -> bool:
    """Record a run stopped by ``exc`` at t [s]: interrupted (True: a signal behind it, nothing to
    raise) or failed (False: the caller raises it once the sinks are finished)."""
    cause = interrupt_in_chain(exc)
    if cause is not None:
        _interrupted(record, cause, t)
        return True
    record.status = "failed"
    record.stop_reason = f"{type(exc).__name__} at t = {t:.3f} s: {message_line(exc)}"
    record.events.append(Event(t, "failed", record.stop_reason))
    return False


def _interrupted(record: RunRecord, exc: BaseException, t: float) -> None:
    who = interrupter(exc)
    record.status = "interrupted"
    record.stop_reason = f"interrupted by {who} at t = {t:.3f} s"
    record.events.append(Event(t, "interrupted", record.stop_reason))


def interrupt_in_chain(exc: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt behind ``exc`` (its cause or context), if any: Python raises a
    signal handler's exception inside a numba kernel as a SystemError caused by it."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


class _Done(Exception):
    """The compiled loop ended (internal: joins the Python loop's normal exit)."""


def _run_compiled(record, parts, kernels, block, flush, limits, dt, n, hooks=()) -> int:
    """The compiled loop (usv_mj.loop.compiled) until the run stops, with the Python loop's events."""
    from usv_mj.loop.compiled import DIAG_MISMATCH, run_compiled

    k, status, x, out = run_compiled(record, parts, kernels, block, flush, limits, dt, n, hooks)
    if status == DIAG_MISMATCH:   # the Python loop raises it from the same row
        raise PluginContractError(diag_mismatch(parts.controller, int(out[0])))
    return _compiled_stop(record, k, status, x, out, limits, dt)


def _compiled_stop(record, k, status, x, out, limits, dt) -> int:
    """The Python loop's events for the compiled loop's stop (``status``, usv_mj.loop.compiled) after
    ``k`` rows; returns the rows the run has."""
    from usv_mj.loop.compiled import DIVERGED, FORCE_LIMIT

    if status == FORCE_LIMIT:
        tau_u, tau_r = float(out[0]), float(out[1])
        t = k * dt
        message = (f"control force out of limits or not finite: tau_u = {tau_u!r}, tau_r = {tau_r!r}")
        record.events.append(Event(t, "divergence", message, {"tau_u": _json_number(tau_u),
                                                              "tau_r": _json_number(tau_r)}))
        record.status = "diverged"
        record.stop_reason = message
        return k + 1
    if status == DIVERGED:
        row = record.buffer[k - 1 - record.base]
        ex, ey = x[0] - row[COL["x_d"]], x[1] - row[COL["y_d"]]
        _state_diverged(record, k * dt, x, ex, ey, limits)
    return k


def _state_diverged(record: RunRecord, t_next: float, x, ex: float, ey: float, limits) -> None:
    """Record the divergence event and the stop (both loops): which limit the state left, and the state."""
    record.events.append(Event(t_next, "divergence",
        f"state left its limits at t = {t_next:.3f} s: {which_limit(x, ex, ey, limits)}; "
        f"(x, y, psi, u, v, r) = ({', '.join(f'{v:.4g}' for v in x)})",
        {"state": [_json_number(v) for v in x]}))
    record.status = "diverged"
    record.stop_reason = record.events[-1].message


def which_limit(x, ex, ey, limits) -> str:
    """Name the first state value that is not finite or over its limit (for the divergence event)."""
    checks = (("surge speed u", x[3], limits.max_speed, "limits.max_speed", "m/s"),
              ("sway speed v", x[4], limits.max_speed, "limits.max_speed", "m/s"),
              ("yaw rate r", x[5], limits.max_yaw_rate, "limits.max_yaw_rate", "rad/s"),
              ("distance to the reference |dx| + |dy|", abs(ex) + abs(ey), limits.max_distance,
               "limits.max_distance", "m"))
    for name, value, limit, key, unit in checks:
        if not math.isfinite(value):
            return f"{name} is not finite ({value})"
        if abs(value) >= limit:
            return f"|{name}| = {abs(value):.4g} {unit} reached {key} = {limit:g} {unit}"
    return "heading psi is not finite"


def _stop_diverged(record, t, message, values, data, i, x, ref, diag, sl_diag):
    row = data[i]   # i: the row's index in the window
    row[COL["t"]] = t
    row[SL_STATE] = x
    row[SL_REF] = ref[:N_REF_RECORDED]
    row[sl_diag] = diag
    record.n_rows = record.base + i + 1
    record.events.append(Event(t, "divergence", message, values))
    record.status = "diverged"
    record.stop_reason = message


class _Flusher:
    """Hands rows [.., hi) to the sinks, the event detector and the progress bar, each from where it
    got to: an interrupt (Ctrl-C, SIGTERM) that lands inside one sink's ``rows`` never makes the
    final flush send another sink the same rows twice, nor detect the same events twice."""

    def __init__(self, record, sinks, progress):
        self.record, self.sinks, self.progress = record, list(sinks), progress
        self.sent = [0] * len(self.sinks)
        self.events_to = 0
        self.counted = 0
        self.mark = 0

    def __call__(self, hi: int) -> None:
        self.mark = max(self.mark, hi)
        self.record.spill(hi)   # a streamed record's rows to its column files first
        if hi > self.events_to:
            new = detect_events(self.record, self.events_to, hi)
            self.events_to = hi
            self.record.events.extend(new)
        for i, sink in enumerate(self.sinks):
            if hi > self.sent[i]:
                sink.rows(self.record, self.sent[i], hi)
                self.sent[i] = hi
        if self.record.stored:   # every part has these rows: a streamed record drops them from memory
            with _signals_held():   # (no Ctrl-C between moving the window and its new base)
                self.record.slide(hi)
        if self.progress is not None and hi > self.counted:
            n, self.counted = hi - self.counted, hi
            self.progress(n)


def _finish_run(record, sinks, flush, wall0, step):
    with _signals_held():
        _finish_sinks(record, sinks, flush, wall0, step)


def _signals_held():
    """Ctrl-C, SIGTERM and SIGHUP wait while the sinks finish (a log cut in its end record has no
    status); they are delivered when it is done."""
    import contextlib
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return contextlib.nullcontext()

    @contextlib.contextmanager
    def held():
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)

    return held()


def _finish_sinks(record, sinks, flush, wall0, step):
    flush(record.n_rows)
    record.events.sort(key=lambda e: e.t)
    wall = time.perf_counter() - wall0
    sim_t = record.value("t", -1) if record.n_rows else 0.0
    record.metadata.update({
        "status": record.status, "stop_reason": record.stop_reason, "wall_time_s": wall,
        "realtime_factor": sim_t / wall if wall > 0 else float("inf"),
        "quantizer_switches": dict(zip(("u", "r"), step.switches)),
    })
    record.finish_store()   # a streamed record's last rows, headers and record.json, before the sinks end
    for sink in sinks:
        sink.finish(record)
