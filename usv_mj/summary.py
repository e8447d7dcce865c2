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


def verdict(block: dict) -> str:
    """The outcome of a ``criterion`` block (:func:`summarize`) in words, for the console and reports."""
    if block["passed"] is None:
        if block["kind"] == "not_judged":
            return "not judged"
        return ("not judged: the run stopped before the criterion could be judged" if block["judged_steps"]
                else "not judged: no control step in the criterion's time window")
    if block["passed"]:
        return "passed"
    return (f"not passed: {block['violations']} control steps outside, the first at "
            f"t = {block['first_violation_s']:.2f} s")


def outcome_sentence(block: dict) -> str:
    """One sentence on the criterion of a ``criterion`` block ("The funnel held.")."""
    noun = block["noun"][:1].upper() + block["noun"][1:]
    if block["kind"] == "not_judged":
        return f"The run is {block['description']}."
    if block["violations"]:
        return f"{noun} was lost ({block['violations']} control steps outside, the first at t = " \
               f"{block['first_violation_s']:.2f} s)."
    if block["passed"] is None:
        return f"{noun} could not be judged ({verdict(block)[len('not judged: '):]})."
    return f"{noun} held."


def criterion_line(s: dict) -> str:
    """The console line of a summary's criterion, its clamps and the quantizer's switch counts."""
    q = s["quantizer_switches"]
    tail = ("" if s.get("s2_clamps") is None else f"; s2 clamps: {s['s2_clamps']}") + \
        f"; quantizer switches: u {q['u']}, r {q['r']}"
    if "funnel_violations" in s:  # the paper's line
        first = s["first_violation_s"]
        return f"  funnel violations: {s['funnel_violations']} steps" + \
            (f" (first at {first:.2f} s)" if first is not None else "") + tail
    return f"  criterion: {s['criterion']['description']}: {verdict(s['criterion'])}" + tail


def baseline_line(b: dict) -> str:
    """The console line of the baseline's summary block (``summary.json``'s ``baseline``)."""
    if "funnel_violations" in b:
        return f"  PI baseline: {b['status']}, funnel violations {b['funnel_violations']}" + \
            (f" (first at {b['first_violation_s']:.2f} s)" if b.get("first_violation_s") is not None else "")
    if "criterion" in b:
        return f"  PI baseline: {b['status']}, {verdict(b['criterion'])}"
    # not run (the job was stopped before it): its status and why
    return f"  PI baseline: {b.get('status', '?')}" + (f" ({b['stop_reason']})" if b.get("stop_reason") else "")


def summarize(record: RunRecord, criterion=None) -> dict:
    """A plain dict with the fields of ``summary.json``; None where a value does not exist.

    ``criterion``: judge the run by this criterion (:mod:`usv_mj.criteria`) instead of its own
    (the record's ``metadata["criterion"]``): the baseline judged as the main run is. The block
    ``criterion`` holds :meth:`evaluate`'s result; ``funnel_violations`` / ``first_violation_s``
    are there only when the criterion is the funnel."""
    from .criteria import criterion_of_record

    criterion = criterion_of_record(record) if criterion is None else criterion
    judged = criterion.evaluate(record)
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
    funnel = {"funnel_violations": judged["violations"], "first_violation_s": judged["first_violation_s"]} \
        if judged["kind"] == "funnel" else {}
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
        "criterion": judged,
        **funnel,
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
