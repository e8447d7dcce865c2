"""The closed loop of several vessels in one sea: each control period, every vessel's reference,
controller and control step, then one plant step for all (issue 35).

For every vessel the order is the single run's (:mod:`usv_mj.loop.simulate`): the reference at t,
the controller on the vessel's state, its row (time, state, reference, diagnostics), the force check,
the control step (:class:`usv_mj.loop.step.ControlStep`: clip, quantize, actuators, the row's control
columns); then the plant holds every vessel's force over the period (``plant.step_vessels``) and each
state is checked against its own limits. A controller that sees the traffic (a collision-avoidance
law) has a ``traffic(t, states, index, lengths)`` method, called before it, with every vessel's state
(rows of (x, y, psi, u, v, r)), its own row and every hull's length [m]. The contact force between
each pair of hulls is recorded every row (:class:`usv_mj.record.fleet.FleetRecord`).

A vessel that diverges or whose controller fails stops the run for all (the record says which);
Ctrl-C, SIGTERM and SIGHUP stop it as a single run's: every vessel's sinks get each row once and its
end, with the signals held while they finish; a plug-in calling ``sys.exit`` fails the run
(:class:`usv_mj.core.errors.PluginExit`), never ends the program.
"""

from __future__ import annotations

import time

import numpy as np

from usv_mj.builder import channels_of
from usv_mj.core.errors import PluginContractError, PluginExit, message_line
from usv_mj.core.kernels import diag_contract, diag_row_problem
from usv_mj.loop.step import ControlStep
from usv_mj.physics.limits import within_limits
from usv_mj.record.criteria import criterion_of, criterion_to_dict
from usv_mj.record.events import detect_events
from usv_mj.record.fleet import FleetRecord
from usv_mj.record.run_record import COL, SL_REF, SL_STATE, Event, RunRecord
from usv_mj.support.spawning import group_signals_blocked


def simulate_fleet(parts, progress=None, block: int = 2000, sinks: dict | None = None) -> FleetRecord:
    """Run the fleet of ``parts`` (:class:`usv_mj.builder.FleetParts`) in closed loop; returns the
    :class:`FleetRecord`. ``progress(n)`` is called with the number of new steps every ``block``;
    ``sinks``: {vessel name: [RunSink, ...]} (a run log's sink per vessel) get each vessel's record
    as a single run's sinks get it (start, rows every block, finish)."""
    scenario, plant, vessels = parts.scenario, parts.plant, parts.vessels
    dt = scenario.control_period
    n = int(round(parts.duration / dt))
    limits = scenario.limits
    names = [v.name for v in vessels]
    own = next(v.name for v in vessels if v.own_ship)
    for v in vessels:   # before anything runs: a kernel's diag against the fields (as a single run's)
        problem = diag_contract(v.controller)
        if problem is not None:
            raise PluginContractError(f"vessel {v.name!r}: {problem}")
    records, steps, fields = {}, [], []
    for v in vessels:
        f = tuple(getattr(v.controller, "diagnostic_fields", ()))
        fields.append(f)
        records[v.name] = RunRecord(n + 1, metadata={
            "preset": v.scenario.preset, "plant": plant.name, "controller": v.controller.name, "vessel_name": v.name,
            "own_ship": v.own_ship, "length_m": float(v.scenario.vessel.model.dimensions.L),
            "duration_s": parts.duration, "control_period_s": dt, "source": v.scenario.source,
            "scenario": v.scenario.to_dict(), "diagnostic_fields": list(f), "loop": "python",
            "loop_reason": "a run of several vessels runs the Python loop",
            "criterion": criterion_to_dict(criterion_of(v.controller)),
            "channels": channels_of(v.scenario, getattr(v.controller, "commands", "forces")).to_metadata(),
        }, diagnostic_fields=f, diagnostic_events=getattr(v.controller, "diagnostic_events", None))
        steps.append(ControlStep(v.quantizers, v.actuators))
    record = FleetRecord(names, records, own, n + 1, metadata={
        "vessels": names, "own_ship": own, "plant": plant.name, "duration_s": parts.duration, "control_period_s": dt,
        "source": scenario.source, "loop": "python"})
    record.statics = parts.statics
    for r in records.values():
        r.statics = parts.statics
    lengths = np.array([v.scenario.vessel.model.dimensions.L for v in vessels])
    for i, v in enumerate(vessels):
        plant.reset_vessel(i, v.scenario.initial.eta, v.scenario.initial.nu, 0.0)
        v.controller.reset()
        steps[i].reset()
    sinks = {name: list((sinks or {}).get(name, ())) for name in names}
    flush = _FleetFlusher(record, sinks)
    seers = [getattr(v.controller, "traffic", None) for v in vessels]
    X = np.array(plant.states)
    F = np.zeros((len(vessels), 2))
    bufs = [records[v.name].buffer for v in vessels]
    sl_diag = [slice(len(COL), len(COL) + len(f)) for f in fields]
    wall0 = time.perf_counter()
    k = 0
    counted = 0
    # the sinks start before the first step, as a single run's (a live server waits for its viewer
    # here: a signal then stops the job before the run has a row)
    flush.start()
    try:
        while True:
            t = k * dt
            refs = []
            for i, v in enumerate(vessels):
                if seers[i] is not None:
                    seers[i](t, X.copy(), i, lengths)
                ref = v.reference.evaluate(t)
                x = X[i].copy()   # its own copy: the row and the actuators keep X[i]
                tau_u, tau_r, diag = v.controller(t, x, ref)
                problem = diag_row_problem(v.controller, diag, len(fields[i]))   # before the row takes it
                if problem is not None:
                    raise PluginContractError(f"vessel {v.name!r}: {problem}")
                row = bufs[i][k]
                row[COL["t"]] = t
                row[SL_STATE] = X[i]
                row[SL_REF] = ref[:7]
                row[sl_diag[i]] = diag
                records[v.name].n_rows = k + 1
                if not (abs(tau_u) < limits.max_force and abs(tau_r) < limits.max_force):
                    _stop(record, "diverged", t, f"vessel {v.name!r}: control force out of limits or not finite: "
                                                 f"tau_u = {tau_u!r}, tau_r = {tau_r!r}")
                    raise _Stop
                F[i] = steps[i](tau_u, tau_r, X[i], row)
                refs.append(ref)
            record.contacts[k] = plant.contacts()
            k += 1
            if k - flush.mark >= block:
                flush(k)
            if progress is not None and k - counted >= block:
                progress(k - counted)
                counted = k
            if k > n:
                break
            plant.step_vessels(F)
            X = np.array(plant.states)
            for i, v in enumerate(vessels):
                ex, ey = X[i, 0] - refs[i][0], X[i, 1] - refs[i][1]
                lim = v.scenario.limits
                if not within_limits(X[i], ex, ey, lim.max_speed, lim.max_yaw_rate, lim.max_distance):
                    _stop(record, "diverged", k * dt, f"vessel {v.name!r}: the state left its limits at "
                                                      f"t = {k * dt:.3f} s")
                    raise _Stop
        record.status = "completed"
    except _Stop:
        pass
    except KeyboardInterrupt as exc:
        who = str(exc) or "the user (Ctrl-C)"
        _stop(record, "interrupted", k * dt, f"interrupted by {who} at t = {k * dt:.3f} s")
    except Exception as exc:
        _stop(record, "failed", k * dt, f"{type(exc).__name__} at t = {k * dt:.3f} s: {message_line(exc)}")
        _finish(record, steps, wall0, flush)
        raise
    except SystemExit as exc:   # a plug-in that ends the program: the run fails, with its rows
        failure = PluginExit.during_run(exc, k * dt)
        _stop(record, "failed", k * dt, str(failure))
        _finish(record, steps, wall0, flush)
        raise failure from exc
    if progress is not None and k > counted:
        progress(k - counted)
    _finish(record, steps, wall0, flush)
    return record


#: a contact force above this [N] between two hulls is a collision (MuJoCo's solver leaves tiny forces at rest)
CONTACT_EVENT_N = 1e-6


class _FleetFlusher:
    """Every ``block`` rows: each vessel's new events (usv_mj.record.events) and the contact episodes
    between hulls (a "vessel_contact" event in both vessels' records and the fleet's), then each
    vessel's sinks get the rows. Each part goes on from where it got to: an interrupt (Ctrl-C,
    SIGTERM) that lands inside one sink's ``rows`` never makes the final flush send a sink the same
    rows twice, nor detect the same events twice (as a single run's ``simulate._Flusher``)."""

    def __init__(self, record: FleetRecord, sinks: dict):
        self.record, self.sinks = record, sinks
        self.mark = 0           # rows handed to every part
        self.events_to = {name: 0 for name in record.names}
        self.contacts_to = 0
        self.sent = {name: [0] * len(sinks[name]) for name in record.names}
        self.begun = {name: [False] * len(sinks[name]) for name in record.names}
        self.started = False

    def start(self) -> None:
        """Start every vessel's sinks not started yet, each marked first (one that a signal cut while
        it waited for a live viewer has its start in the file already). A signal that stops the
        wait is raised once every sink has started, so that every vessel's log holds its run."""
        cut = None
        for name in self.record.names:
            for i, s in enumerate(self.sinks[name]):
                if not self.begun[name][i]:
                    self.begun[name][i] = True
                    try:
                        s.start(self.record.records[name])
                    except KeyboardInterrupt as exc:
                        cut = cut or exc
        self.started = True
        if cut is not None:
            raise cut

    def __call__(self, hi: int) -> None:
        if not self.started:
            self.start()
        rec = self.record
        if hi <= self.mark:
            return
        for name in rec.names:
            r = rec.records[name]
            if hi > self.events_to[name]:
                new = detect_events(r, self.events_to[name], hi)
                self.events_to[name] = hi
                r.events.extend(new)
        if hi > self.contacts_to:
            new = self._contacts(self.contacts_to, hi)
            self.contacts_to = hi
            for a, b, event in new:
                rec.events.append(event)
                rec.records[a].events.append(event)
                rec.records[b].events.append(event)
        for name in rec.names:
            for i, s in enumerate(self.sinks[name]):
                if hi > self.sent[name][i]:
                    s.rows(rec.records[name], self.sent[name][i], hi)
                    self.sent[name][i] = hi
        self.mark = hi

    def _contacts(self, lo: int, hi: int) -> list:
        """The contact episodes that start in rows lo..hi: (vessel, vessel, its event)."""
        rec = self.record
        c = rec.contacts
        dt = rec.metadata["control_period_s"]
        new = []
        for p, (i, j) in enumerate(rec.pairs):
            on = c[lo:hi, p] > CONTACT_EVENT_N
            before = bool(lo > 0 and c[lo - 1, p] > CONTACT_EVENT_N)
            edges = np.diff(np.concatenate(([before], on)).astype(np.int8))
            for k in np.flatnonzero(edges == 1):
                t = (lo + k) * dt
                a, b = rec.names[i], rec.names[j]
                new.append((a, b, Event(t, "vessel_contact", f"the hulls of {a!r} and {b!r} touch ({c[lo + k, p]:.4g} N)",
                                        {"pair": [a, b], "force_N": float(c[lo + k, p]), "state": "start"})))
        return new


class _Stop(Exception):
    """The fleet's run stopped early (recorded)."""


def _stop(record: FleetRecord, status: str, t: float, message: str) -> None:
    record.status = status
    record.stop_reason = message
    record.events.append(Event(t, "divergence" if status == "diverged" else status, message))


def _finish(record: FleetRecord, steps, wall0: float, flush) -> None:
    """Every vessel's last rows, status and end to its sinks, with Ctrl-C, SIGTERM and SIGHUP held
    until they are done (a log cut in its end record has no status); they are delivered after."""
    with group_signals_blocked():
        _finish_sinks(record, steps, wall0, flush)


def _finish_sinks(record: FleetRecord, steps, wall0: float, flush) -> None:
    wall = time.perf_counter() - wall0
    # a step that a stop cut (a signal, a failing controller, a force out of limits) gave a row to
    # the vessels before the one it stopped at only: every record ends at the last whole step, so
    # that the vessels' records, logs and summaries hold the same times
    rows = min(r.n_rows for r in record.records.values())
    for r in record.records.values():
        r.n_rows = rows
    flush(record.n_rows)
    for (name, r), step in zip(record.records.items(), steps):
        r.events.sort(key=lambda e: e.t)
        r.status = record.status
        r.stop_reason = record.stop_reason
        r.metadata.update({"status": record.status, "stop_reason": record.stop_reason, "wall_time_s": wall,
                           "quantizer_switches": dict(zip(("u", "r"), step.switches))})
    record.metadata.update({"status": record.status, "stop_reason": record.stop_reason, "wall_time_s": wall})
    for name in record.names:
        for s in flush.sinks[name]:
            s.finish(record.records[name])
