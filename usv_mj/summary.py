"""The numbers of a run that go into ``summary.json`` and the report (works on any RunRecord)."""

from __future__ import annotations

import math

import numpy as np

from .record import RunRecord
from .ship import wrap_angle

CHECK_TIMES = (5.0, 10.0, 20.0)


def _finite(v):
    v = float(v)
    return v if math.isfinite(v) else None


def pose_errors(record: RunRecord) -> dict:
    """x - x_d [m], y - y_d [m] and wrap(psi - psi_d) [rad] at every row (the paper's Table 1 errors)."""
    return {"x": record["x"] - record["x_d"], "y": record["y"] - record["y_d"],
            "psi": wrap_angle(record["psi"] - record["psi_d"])}


def actuator_description(table) -> dict | None:
    """The ``[actuators]`` of a run as the summary gives it: kind, the one-line description and the
    generalized limits (None: open); None when the metadata has no scenario."""
    if not table:
        return None
    from .actuators import ActuatorSpec

    spec = ActuatorSpec(**table)
    return {"kind": spec.kind, "unlimited": spec.unlimited, "description": spec.describe(),
            "limits": dict(zip(("tau_u_min_n", "tau_u_max_n", "tau_r_min_nm", "tau_r_max_nm"),
                               (_finite(v) for v in spec.generalized_limits())))}


def summarize(record: RunRecord) -> dict:
    """A plain dict with the fields of ``summary.json``; None where a value does not exist."""
    if not isinstance(record, RunRecord):
        from .errors import expected

        raise expected("summarize", "record", "a RunRecord (usv_mj.simulate, usv_mj.runlog.read_run)", record)
    meta = record.metadata
    t = record["t"]
    err = pose_errors(record)
    dt = meta.get("control_period_s", t[1] - t[0] if len(t) > 1 else 0.0)
    errors_at = {}
    for tc in CHECK_TIMES:
        k = int(round(tc / dt)) if dt else -1
        if 0 <= k < len(t):
            errors_at[f"{tc:g}"] = {a: _finite(err[a][k]) for a in ("x", "y", "psi")}
        else:
            errors_at[f"{tc:g}"] = {a: None for a in ("x", "y", "psi")}
    after = t > 20.0
    max_after = {a: (_finite(np.max(np.abs(err[a][after]))) if after.any() else None) for a in ("x", "y", "psi")}
    if record.has_funnel:  # the controller declared the funnel block (e, rho, z)
        z = np.stack([record["z1"], record["z2"], record["z3"]])
        viol = np.any(~(np.abs(z) < 1.0), axis=0)
        violations, first = int(viol.sum()), (_finite(t[np.argmax(viol)]) if viol.any() else None)
    else:
        violations, first = None, None
    clamps = int(np.sum(record["s2_clamped"] > 0.5)) if "s2_clamped" in record else None
    saturated = {ch: (float(np.mean(record[f"sat_{ch}"] > 0.5)) if len(t) else 0.0) for ch in ("u", "r")}
    episodes = {ch: 0 for ch in ("u", "r")}
    longest = {ch: 0.0 for ch in ("u", "r")}
    for ch in ("u", "r"):
        flag = record[f"sat_{ch}"] > 0.5
        if flag.any():
            edges = np.diff(np.concatenate(([0], flag.astype(np.int8), [0])))
            starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
            episodes[ch] = int(len(starts))
            longest[ch] = float(np.max(ends - starts) * dt)
    actuators = actuator_description((meta.get("scenario") or {}).get("actuators"))
    return {
        "preset": meta.get("preset"),
        "plant": meta.get("plant"),
        "controller": meta.get("controller"),
        "status": record.status,
        "stop_reason": record.stop_reason or None,
        "duration_s": meta.get("duration_s"),
        "simulated_s": _finite(t[-1]) if len(t) else 0.0,
        "control_period_s": dt,
        "errors_at": errors_at,
        "max_abs_error_after_20s": max_after,
        "funnel_violations": violations,
        "first_violation_s": first,
        "s2_clamps": clamps,
        "saturated_fraction": saturated,
        "saturation_episodes": episodes,
        "longest_saturation_s": longest,
        "actuators": actuators,
        "diagnostic_fields": list(record.diagnostic_fields),
        "quantizer_switches": meta.get("quantizer_switches", {"u": None, "r": None}),
        "wall_time_s": meta.get("wall_time_s"),
        "realtime_factor": meta.get("realtime_factor"),
        "events": len(record.events),
        # obstacles: None / 0 in open water
        "min_clearance_m": (meta.get("obstacles") or {}).get("min_clearance_m"),
        "contacts": (meta.get("obstacles") or {}).get("contacts", 0),
        "obstacles": (meta.get("obstacles") or {}).get("per_obstacle"),
    }
