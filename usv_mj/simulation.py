"""The closed loop: reference -> controller -> quantizer -> plant, one control period at a time.

The loop knows the plant and the controller only through their interfaces
(:mod:`usv_mj.plants.base`, :mod:`usv_mj.controllers.base`). Each step it records one row of the
:class:`~usv_mj.record.RunRecord`; every ``block`` rows it hands the new rows to the sinks (the MCAP
writer, say), so that a long run streams out with bounded memory in the writers.

A run stops early, with a recorded event and a status, on divergence (a non-finite or out-of-limit
state or force), on an exception in the plant or controller, or on Ctrl-C; the rows up to the stop
stay valid and the sinks are always finished.
"""

from __future__ import annotations

import math
import time
from typing import Callable, Iterable, Protocol

import numpy as np

from usv_mj.controllers.hysteresis_quantizer import HysteresisQuantizer, QuantizerParams
from usv_mj.controllers.performance_funnel import PerformanceFunnel
from usv_mj.controllers.pi_baseline import PIController
from usv_mj.controllers.ppc import PPCController

from .plants.analytic import AnalyticPlant
from .record import COL, SL_DIAG, SL_REF, SL_STATE, Event, RunRecord
from .scenario import Scenario
from .trajectories import CircleReference, LineReference, PaperReference, WaypointReference


class RunSink(Protocol):
    """Receives a run as it is made: ``start(record)``, ``rows(record, lo, hi)``, ``finish(record)``."""

    def start(self, record: RunRecord) -> None: ...

    def rows(self, record: RunRecord, lo: int, hi: int) -> None: ...

    def finish(self, record: RunRecord) -> None: ...


class DivergenceError(RuntimeError):
    """The state or the control left its limits (see :class:`usv_mj.scenario.LimitsSpec`)."""


# --- building the pieces from a scenario ---------------------------------------------------------


def make_reference(scenario: Scenario):
    spec = scenario.trajectory
    if spec.kind == "paper":
        return PaperReference(duration=scenario.duration, speed=spec.speed)
    if spec.kind == "line":
        return LineReference(spec.start, spec.heading_deg, spec.speed)
    if spec.kind == "circle":
        return CircleReference(spec.center, spec.radius, spec.speed, spec.start_angle_deg, spec.clockwise)
    return WaypointReference(spec.points, spec.speed, spec.turn_radius)


def make_funnels(scenario: Scenario) -> tuple[PerformanceFunnel, PerformanceFunnel]:
    f = scenario.funnel
    return (PerformanceFunnel(f.rho_xy[0], f.rho_xy[1], f.rate), PerformanceFunnel(f.rho_psi[0], f.rho_psi[1], f.rate))


def make_controller(scenario: Scenario, kind: str | None = None):
    kind = kind or scenario.controller.kind
    fxy, fpsi = make_funnels(scenario)
    if kind == "ppc":
        return PPCController(scenario.controller.gains, scenario.ship, fxy, fpsi, scenario.quantizer.delta_u,
                             scenario.quantizer.delta_r, scenario.control_period)
    if kind == "pi":
        return PIController(scenario.baseline.gains, scenario.ship, fxy, fpsi, scenario.control_period)
    raise ValueError(f"unknown controller kind {kind!r}")


def make_quantizers(scenario: Scenario) -> tuple[HysteresisQuantizer, HysteresisQuantizer]:
    q = scenario.quantizer
    return (HysteresisQuantizer(QuantizerParams(q.delta_u, q.u_min_u), q.enabled),
            HysteresisQuantizer(QuantizerParams(q.delta_r, q.u_min_r), q.enabled))


def make_environment(scenario: Scenario, duration: float | None = None):
    """The scenario's sea (waves, current, wind; SEA.md) or None when it is calm."""
    if scenario.sea.calm:
        return None
    from .sea import Environment

    return Environment(scenario.sea, ship=scenario.ship, t_max=(duration or scenario.duration) + 1.0)


def make_plant(scenario: Scenario, kind: str | None = None, environment=None):
    kind = kind or scenario.plant.kind
    if environment is None:
        environment = make_environment(scenario)
    if kind == "analytic":
        return AnalyticPlant(scenario.ship, scenario.disturbance, scenario.control_period, scenario.plant.substeps,
                             environment=environment)
    if kind == "mujoco":
        from .plants.mujoco_plant import MuJoCoPlant

        return MuJoCoPlant(scenario.ship, scenario.disturbance, scenario.control_period, scenario.plant.substeps,
                           environment=environment)
    raise ValueError(f"unknown plant kind {kind!r}")


# --- the loop ------------------------------------------------------------------------------------


def simulate(scenario: Scenario, plant=None, controller=None, *, plant_kind: str | None = None,
             controller_kind: str | None = None, sinks: Iterable[RunSink] = (), block: int = 2000,
             progress: Callable[[int], None] | None = None, duration: float | None = None,
             reference=None, hooks: Iterable[Callable] = ()) -> RunRecord:
    """Run ``scenario`` in closed loop and return its :class:`RunRecord`.

    ``plant``, ``controller`` and ``reference`` default to the scenario's; pass your own to run
    anything that follows the interfaces. ``hooks`` are called as ``hook(t, k, plant)`` at every
    control step before the reference is evaluated (the obstacles' clearance and guidance, say).
    ``progress(n)`` is called with the number of new steps every block. Plants built here are
    closed here.
    """
    duration = scenario.duration if duration is None else float(duration)
    dt = scenario.control_period
    n = int(round(duration / dt))
    own_plant = plant is None
    plant = plant if plant is not None else make_plant(scenario, plant_kind)
    controller = controller if controller is not None else make_controller(scenario, controller_kind)
    if reference is None:
        reference = make_reference(scenario) if duration <= scenario.duration else make_reference(
            scenario.with_overrides({"duration": duration}))
    hooks = tuple(hooks)
    quant_u, quant_r = make_quantizers(scenario)
    limits = scenario.limits
    record = RunRecord(n + 1, metadata={
        "preset": scenario.preset, "plant": plant.name, "controller": controller.name,
        "duration_s": duration, "control_period_s": dt, "source": scenario.source,
        "scenario": scenario.to_dict(),
    })
    sinks = list(sinks)
    for sink in sinks:
        sink.start(record)
    plant.reset(scenario.initial.eta, scenario.initial.nu, 0.0)
    controller.reset()
    quant_u.reset()
    quant_r.reset()
    data = record.data
    c_t = COL["t"]
    c_tau_u, c_tau_r, c_q_u, c_q_r, c_k_u, c_k_r = (COL[c] for c in ("tau_u", "tau_r", "q_tau_u", "q_tau_r", "k_u", "k_r"))
    flushed = 0
    wall0 = time.perf_counter()
    k = 0
    try:
        x = plant.state
        while True:
            t = k * dt
            for hook in hooks:
                hook(t, k, plant)
            ref = reference.evaluate(t)
            tau_u, tau_r, diag = controller(t, x, ref)
            if not (abs(tau_u) < limits.max_force and abs(tau_r) < limits.max_force):
                _stop_diverged(record, t, f"control force out of limits or not finite: tau_u = {tau_u!r}, "
                               f"tau_r = {tau_r!r}", {"tau_u": float(tau_u), "tau_r": float(tau_r)}, data, k,
                               x, ref, diag)
                k += 1
                break
            q_u = quant_u.step(tau_u)
            q_r = quant_r.step(tau_r)
            row = data[k]
            row[c_t] = t
            row[SL_STATE] = x
            row[SL_REF] = ref
            row[SL_DIAG] = diag
            row[c_tau_u] = tau_u  # scalar stores: cheaper than building an array per step
            row[c_tau_r] = tau_r
            row[c_q_u] = q_u
            row[c_q_r] = q_r
            row[c_k_u] = quant_u.k
            row[c_k_r] = quant_r.k
            k += 1
            record.n_rows = k
            if k - flushed >= block:
                _flush(record, sinks, flushed, k, progress)
                flushed = k
            if k > n:
                break
            plant.step(q_u, q_r)
            x = plant.state
            ex, ey = x[0] - ref[0], x[1] - ref[1]
            if not (abs(x[3]) < limits.max_speed and abs(x[4]) < limits.max_speed
                    and abs(x[5]) < limits.max_yaw_rate and abs(ex) + abs(ey) < limits.max_distance
                    and math.isfinite(x[2])):
                t_next = k * dt
                record.events.append(Event(t_next, "divergence",
                    f"state left its limits at t = {t_next:.3f} s: {_which_limit(x, ex, ey, limits)}; "
                    f"(x, y, psi, u, v, r) = ({', '.join(f'{v:.4g}' for v in x)})",
                    {"state": [float(v) for v in x]}))
                record.status = "diverged"
                record.stop_reason = record.events[-1].message
                break
        if record.status == "running":
            record.status = "completed"
    except KeyboardInterrupt:
        record.status = "interrupted"
        record.stop_reason = f"interrupted by the user (Ctrl-C) at t = {k * dt:.3f} s"
        record.events.append(Event(k * dt, "interrupted", record.stop_reason))
    except Exception as exc:  # recorded, then re-raised after the sinks are finished
        record.status = "failed"
        record.stop_reason = f"{type(exc).__name__} at t = {k * dt:.3f} s: {exc}"
        record.events.append(Event(k * dt, "failed", record.stop_reason))
        _finish(record, sinks, flushed, progress, wall0, quant_u, quant_r, own_plant, plant)
        raise
    _finish(record, sinks, flushed, progress, wall0, quant_u, quant_r, own_plant, plant)
    return record


def _which_limit(x, ex, ey, limits) -> str:
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


def _stop_diverged(record, t, message, values, data, k, x, ref, diag):
    row = data[k]
    row[COL["t"]] = t
    row[SL_STATE] = x
    row[SL_REF] = ref
    row[SL_DIAG] = diag
    record.n_rows = k + 1
    record.events.append(Event(t, "divergence", message, values))
    record.status = "diverged"
    record.stop_reason = message


def _flush(record, sinks, lo, hi, progress):
    if hi > lo:
        record.events.extend(detect_events(record, lo, hi))
        for sink in sinks:
            sink.rows(record, lo, hi)
        if progress is not None:
            progress(hi - lo)


def _finish(record, sinks, flushed, progress, wall0, quant_u, quant_r, own_plant, plant):
    _flush(record, sinks, flushed, record.n_rows, progress)
    record.events.sort(key=lambda e: e.t)
    wall = time.perf_counter() - wall0
    sim_t = record["t"][-1] if record.n_rows else 0.0
    record.metadata.update({
        "status": record.status, "stop_reason": record.stop_reason, "wall_time_s": wall,
        "realtime_factor": sim_t / wall if wall > 0 else float("inf"),
        "quantizer_switches": {"u": quant_u.switches, "r": quant_r.switches},
    })
    if own_plant:
        plant.close()
    for sink in sinks:
        sink.finish(record)


def detect_events(record: RunRecord, lo: int, hi: int) -> list[Event]:
    """Funnel-violation and s2-clamp episodes that start in rows [lo, hi) (vectorised)."""
    events = []
    data = record.data
    t = data[lo:hi, COL["t"]]
    for axis in (1, 2, 3):
        z = data[lo:hi, COL[f"z{axis}"]]
        bad = ~(np.abs(z) < 1.0)
        prev = bool(lo > 0 and not abs(data[lo - 1, COL[f"z{axis}"]]) < 1.0)
        starts = np.flatnonzero(bad & ~np.concatenate(([prev], bad[:-1])))
        ends = np.flatnonzero(~bad & np.concatenate(([prev], bad[:-1])))
        for i in starts:
            e = data[lo + i, COL[f"e{axis}"]]
            rho = data[lo + i, COL[f"rho{axis}"]]
            events.append(Event(float(t[i]), "funnel_violation",
                                f"e{axis} = {e:.4g} left the funnel |e{axis}| < rho{axis} = {rho:.4g} "
                                f"(z{axis} = {z[i]:.4g})", {"axis": axis, "e": float(e), "rho": float(rho),
                                                             "z": float(z[i])}))
        for i in ends:
            events.append(Event(float(t[i]), "funnel_recovered", f"e{axis} is back inside its funnel",
                                {"axis": axis}))
    clamp = data[lo:hi, COL["s2_clamped"]] > 0.5
    prev = bool(lo > 0 and data[lo - 1, COL["s2_clamped"]] > 0.5)
    for i in np.flatnonzero(clamp & ~np.concatenate(([prev], clamp[:-1]))):
        events.append(Event(float(t[i]), "s2_clamp", f"s2 = tanh(gamma_2) was clamped at its limit after "
                            f"({data[lo + i, COL['s2']]:.9f})", {"s2": float(data[lo + i, COL["s2"]])}))
    return events


