"""The numbers of a run that go into ``summary.json`` and the report (works on any RunRecord).

The whole-run reductions (the max error after 20 s, the funnel violations, the s2 clamps, the
saturation fractions and episodes) read the columns chunk by chunk (``RunRecord.column_chunks``),
and the errors at 5 / 10 / 20 s read single rows, so summarizing a ten-hour record streamed to disk
needs a few MB, and gives the same numbers as the same record in memory.
"""

from __future__ import annotations

import math

import numpy as np

from usv_mj.record.run_record import RunRecord
from usv_mj.record.tracking import pose_errors, pose_errors_at  # noqa: F401 (the summary's API)
from usv_mj.physics.actuators import ActuatorSpec
from usv_mj.physics.channels import RunChannels
from usv_mj.physics.ship import wrap_angle

CHECK_TIMES = (5.0, 10.0, 20.0)


def _finite(v):
    v = float(v)
    return v if math.isfinite(v) else None


def column_chunks(record: RunRecord, names) -> "iter":
    """Aligned chunks of several columns: tuples of arrays, one per name (RunRecord.column_chunks)."""
    return zip(*(record.column_chunks(n) for n in names))


def _episodes(record: RunRecord, name: str) -> tuple[int, int, int]:
    """(rows where ``name`` > 0.5, episodes of consecutive such rows, the longest episode's rows)."""
    total = episodes = longest = run = 0
    for (chunk,) in column_chunks(record, (name,)):
        flag = chunk > 0.5
        if not flag.any():
            run = 0
            continue
        total += int(flag.sum())
        edges = np.diff(np.concatenate(([0], flag.astype(np.int8), [0])))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        lengths = ends - starts
        if run and starts[0] == 0:   # the episode that the chunk before ended in goes on
            lengths[0] += run
            episodes -= 1
        episodes += len(starts)
        longest = max(longest, int(lengths.max()))
        run = int(lengths[-1]) if ends[-1] == len(flag) else 0
    return total, episodes, longest


def actuator_description(table, channels="forces") -> dict | None:
    """The ``[actuators]`` of a run as the summary gives it: kind, the one-line description and the
    generalized limits (None: open); None when the metadata has no scenario. ``channels``: the
    record's ``metadata["channels"]`` (:class:`usv_mj.physics.channels.RunChannels`): the limits act
    on the applied channels (on a ruddered vessel, n_P's and the rudder's)."""
    if not table:
        return None
    spec = ActuatorSpec(**table)
    applied = RunChannels.from_metadata(channels).applied
    return {"kind": spec.kind, "unlimited": spec.unlimited, "description": spec.describe(applied),
            "limits": dict(zip(("tau_u_min_n", "tau_u_max_n", "tau_r_min_nm", "tau_r_max_nm"),
                               (_finite(v) for v in spec.generalized_limits())))}


def verdict(block: dict) -> str:
    """The outcome of a ``criterion`` block (:func:`summarize`) in words, for the console and reports."""
    if block.get("error"):   # a plug-in's criterion that broke its contract (usv_mj.record.criteria.judge)
        return f"not judged: {block['error']}"
    if block["passed"] is None:
        if block["kind"] == "not_judged":
            return "not judged"
        return ("not judged: the run stopped before the criterion could be judged" if block["judged_steps"]
                else "not judged: no control step in the criterion's time window")
    if block["passed"]:
        return "passed"
    return "not passed" + _violations(block)


def _violations(block: dict) -> str:
    """": N control steps outside, the first at t = T s", the parts a criterion gave (a plug-in's
    may give neither: None is allowed by the contract)."""
    n, first = block.get("violations"), block.get("first_violation_s")
    words = ([f"{n} control steps outside"] if n is not None else []) + \
        ([f"the first at t = {first:.2f} s"] if first is not None else [])
    return (": " + ", ".join(words)) if words else ""


def outcome_sentence(block: dict) -> str:
    """One sentence on the criterion of a ``criterion`` block ("The funnel held.")."""
    noun = block["noun"][:1].upper() + block["noun"][1:]
    if block["kind"] == "not_judged":
        return f"The run is {block['description']}."
    if block.get("error"):
        return f"{noun} could not be judged ({block['error']})."
    if block["violations"] or block["passed"] is False:
        detail = _violations(block)[2:]
        return f"{noun} was lost" + (f" ({detail})." if detail else ".")
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

    ``criterion``: judge the run by this criterion (:mod:`usv_mj.record.criteria`) instead of its own
    (the record's ``metadata["criterion"]``): the baseline judged as the main run is. The block
    ``criterion`` holds :meth:`evaluate`'s result; ``funnel_violations`` / ``first_violation_s``
    are there only when the criterion is the funnel."""
    if not isinstance(record, RunRecord):
        from usv_mj.core.errors import expected

        raise expected("summarize", "record", "a RunRecord (usv_mj.simulate, usv_mj.outputs.log.read_run)", record)
    from usv_mj.record.criteria import criterion_of_record, judge

    criterion = criterion_of_record(record) if criterion is None else criterion
    judged = judge(criterion, record)
    meta = record.metadata
    n = len(record)
    dt = meta.get("control_period_s", record.value("t", 1) - record.value("t", 0) if n > 1 else 0.0)
    errors_at = {}
    for tc in CHECK_TIMES:
        k = int(round(tc / dt)) if dt else -1
        if 0 <= k < n:
            errors_at[f"{tc:g}"] = {a: _finite(e) for a, e in pose_errors_at(record, k).items()}
        else:
            errors_at[f"{tc:g}"] = {a: None for a in ("x", "y", "psi")}
    peak = {a: None for a in ("x", "y", "psi")}
    for t, x, x_d, y, y_d, psi, psi_d in column_chunks(record, ("t", "x", "x_d", "y", "y_d", "psi", "psi_d")):
        after = t > 20.0
        if after.any():
            for a, e in (("x", x - x_d), ("y", y - y_d), ("psi", wrap_angle(psi - psi_d))):
                m = np.max(np.abs(e[after]))
                peak[a] = m if peak[a] is None else np.maximum(peak[a], m)   # NaN, as np.max, wins
    max_after = {a: (_finite(v) if v is not None else None) for a, v in peak.items()}
    clamps = _episodes(record, "s2_clamped")[0] if "s2_clamped" in record else None
    saturated, episodes, longest = {}, {}, {}
    for ch in ("u", "r"):
        total, count, rows = _episodes(record, f"sat_{ch}")
        saturated[ch] = float(total / n) if n else 0.0
        episodes[ch] = count
        longest[ch] = float(rows * dt)
    actuators = actuator_description((meta.get("scenario") or {}).get("actuators"), meta.get("channels", "forces"))
    funnel = {"funnel_violations": judged["violations"], "first_violation_s": judged["first_violation_s"]} \
        if judged["kind"] == "funnel" else {}
    return {
        "preset": meta.get("preset"),
        "vessel": ((meta.get("scenario") or {}).get("vessel") or {}).get("kind", "paper"),
        "plant": meta.get("plant"),
        "controller": meta.get("controller"),
        "status": record.status,
        "stop_reason": record.stop_reason or None,
        "duration_s": meta.get("duration_s"),
        "simulated_s": _finite(record.value("t", -1)) if n else 0.0,
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
        # the clearance monitor's reach [m] when its broad phase ran (obstacles never within it have
        # no minimum; docs/obstacles.md), else None
        "beyond_reach_m": (meta.get("obstacles") or {}).get("beyond_reach_m"),
    }
