"""The events of a record: episodes that start in its rows (funnel violations and recoveries,
actuator saturation per channel, a controller's declared 0/1 event fields), detected vectorised,
block by block, by the loops (and again from a log)."""

from __future__ import annotations

import math

import numpy as np

from usv_mj.record.run_record import COL, Event, RunRecord


def json_number(v) -> float | None:
    """A float for an event's values, None where it is not finite (the log stores null)."""
    v = float(v)
    return v if math.isfinite(v) else None


def detect_events(record: RunRecord, lo: int, hi: int) -> list[Event]:
    """Episodes that start in rows [lo, hi) (vectorised): funnel violations and recoveries when the
    controller declared the funnel block, actuator saturation per channel (start and end, from
    sat_u / sat_r: "actuator_saturation" with values channel, state), and the episodes of its declared 0/1 event fields (the
    PPC law's s2 clamps)."""
    events = []
    col = record.col
    data = record.buffer[lo - record.base - (1 if lo > 0 else 0):hi - record.base]  # from the row before lo
    lo, hi = (1, hi - lo + 1) if lo > 0 else (0, hi - lo)    # rows of ``data`` from here on
    t = data[lo:hi, COL["t"]]
    if record.has_funnel:
        for axis in (1, 2, 3):
            cz = col[f"z{axis}"]
            z = data[lo:hi, cz]
            bad = ~(np.abs(z) < 1.0)
            prev = bool(lo > 0 and not abs(data[lo - 1, cz]) < 1.0)
            starts = np.flatnonzero(bad & ~np.concatenate(([prev], bad[:-1])))
            ends = np.flatnonzero(~bad & np.concatenate(([prev], bad[:-1])))
            for i in starts:
                e = data[lo + i, col[f"e{axis}"]]
                rho = data[lo + i, col[f"rho{axis}"]]
                events.append(Event(float(t[i]), "funnel_violation",
                                    f"e{axis} = {e:.4g} left the funnel |e{axis}| < rho{axis} = {rho:.4g} "
                                    f"(z{axis} = {z[i]:.4g})", {"axis": axis, "e": json_number(e),
                                                                 "rho": json_number(rho), "z": json_number(z[i])}))
            for i in ends:
                events.append(Event(float(t[i]), "funnel_recovered", f"e{axis} is back inside its funnel",
                                    {"axis": axis}))
    for ch, what, unit in (("u", "surge force", "N"), ("r", "yaw moment", "N m")):  # the actuators' limits
        cs = COL[f"sat_{ch}"]
        flag = data[lo:hi, cs] > 0.5
        prev = bool(lo > 0 and data[lo - 1, cs] > 0.5)
        shifted = np.concatenate(([prev], flag[:-1]))
        for i in np.flatnonzero(flag & ~shifted):
            q, f = data[lo + i, COL[f"q_tau_{ch}"]], data[lo + i, COL[f"f_{ch}"]]
            events.append(Event(float(t[i]), "actuator_saturation",
                                f"the {what} command Q = {q:.4g} {unit} is cut to {f:.4g} {unit} by the actuators",
                                {"channel": ch, "state": "start", "command": json_number(q),
                                 "applied": json_number(f)}))
        for i in np.flatnonzero(~flag & shifted):
            events.append(Event(float(t[i]), "actuator_saturation", f"the {what} is back within the actuators' limits",
                                {"channel": ch, "state": "end"}))
    for name, kind in record.diagnostic_events.items():
        c = col[name]
        flag = data[lo:hi, c] > 0.5
        prev = bool(lo > 0 and data[lo - 1, c] > 0.5)
        for i in np.flatnonzero(flag & ~np.concatenate(([prev], flag[:-1]))):
            values = {"field": name}
            message = f"{name} was set (a {kind} episode starts)"
            if kind == "s2_clamp" and "s2" in col:  # the PPC law's clamp names the value it held
                values["s2"] = json_number(data[lo + i, col["s2"]])
                message = f"s2 = tanh(gamma_2) was clamped at its limit after ({data[lo + i, col['s2']]:.9f})"
            events.append(Event(float(t[i]), kind, message, values))
    return events
