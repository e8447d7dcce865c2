"""The tracking errors of a record: x - x_d, y - y_d [m] and wrap(psi - psi_d) [rad] (the paper's Table 1 errors).

Read by the summary and by the criteria a controller declares (:mod:`usv_mj.record.summary`,
:mod:`usv_mj.record.criteria`).
"""

from __future__ import annotations

from usv_mj.physics.ship import wrap_angle
from usv_mj.record.run_record import RunRecord


def pose_errors(record: RunRecord) -> dict:
    """x - x_d [m], y - y_d [m] and wrap(psi - psi_d) [rad] at every row (the paper's Table 1 errors)."""
    return {"x": record["x"] - record["x_d"], "y": record["y"] - record["y_d"],
            "psi": wrap_angle(record["psi"] - record["psi_d"])}


def pose_errors_at(record: RunRecord, k: int) -> dict:
    """The pose errors of :func:`pose_errors` at row ``k`` only (floats; a single read of each column)."""
    v = {c: record.value(c, k) for c in ("x", "x_d", "y", "y_d", "psi", "psi_d")}
    return {"x": v["x"] - v["x_d"], "y": v["y"] - v["y_d"], "psi": float(wrap_angle(v["psi"] - v["psi_d"]))}
