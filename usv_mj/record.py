"""The record of one run: every control step in named float64 columns, plus events and metadata.

Rows are control steps k = 0..n at t_k = k dt. Columns (units as in :mod:`usv_mj.ship`):

- ``t``; the state ``x, y, psi, u, v, r`` (psi unwrapped);
- the reference ``x_d, y_d, psi_d, x_d_dot, y_d_dot, r_d, u_d`` (:data:`usv_mj.controllers.base.REF_FIELDS`);
- the controller diagnostics :data:`usv_mj.controllers.base.DIAG_FIELDS` (e1..e3, rho, z, e*, psi_a, ...);
- ``tau_u, tau_r`` (the law's output), ``q_tau_u, q_tau_r`` (what the plant received), ``k_u, k_r``
  (the quantizers' signed level indices).

The input in row k is held from t_k to t_{k+1}; the last row's input is never applied.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usv_mj.controllers.base import DIAG_FIELDS, REF_FIELDS

STATE_FIELDS = ("x", "y", "psi", "u", "v", "r")
CONTROL_FIELDS = ("tau_u", "tau_r", "q_tau_u", "q_tau_r", "k_u", "k_r")
COLUMNS = ("t",) + STATE_FIELDS + REF_FIELDS + DIAG_FIELDS + CONTROL_FIELDS
COL = {name: i for i, name in enumerate(COLUMNS)}
SL_STATE = slice(COL["x"], COL["r"] + 1)
SL_REF = slice(COL["x_d"], COL["u_d"] + 1)
SL_DIAG = slice(COL[DIAG_FIELDS[0]], COL[DIAG_FIELDS[-1]] + 1)
SL_CONTROL = slice(COL["tau_u"], COL["k_r"] + 1)


@dataclass
class Event:
    """Something worth a line in the log: a funnel violation, an s2 clamp, a divergence, a stop."""

    t: float
    kind: str
    message: str
    values: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"t": self.t, "kind": self.kind, "message": self.message, **{"values": self.values}}


class RunRecord:
    """A run in arrays. ``record["x"]`` is the x column of the rows written so far.

    Attributes
    ----------
    data: (rows, len(COLUMNS)) float64; only the first ``n_rows`` rows are valid.
    events: list of :class:`Event`.
    status: "completed", "diverged", "interrupted" or "failed".
    stop_reason: one sentence when status is not "completed".
    metadata: scenario, versions, timing; filled by the loop.
    """

    def __init__(self, capacity: int, metadata: dict | None = None):
        self.data = np.full((capacity, len(COLUMNS)), np.nan)
        self.n_rows = 0
        self.events: list[Event] = []
        self.status = "running"
        self.stop_reason = ""
        self.metadata = dict(metadata or {})

    @classmethod
    def from_arrays(cls, columns: dict, events=(), metadata=None, status="completed", stop_reason=""):
        n = len(columns["t"])
        rec = cls(n, metadata)
        for name, values in columns.items():
            if name in COL:
                rec.data[:, COL[name]] = values
        rec.n_rows = n
        rec.events = list(events)
        rec.status, rec.stop_reason = status, stop_reason
        return rec

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[: self.n_rows, COL[name]]

    @property
    def columns(self) -> dict:
        return {name: self[name] for name in COLUMNS}

    def __len__(self) -> int:
        return self.n_rows

    def events_of(self, kind: str) -> list[Event]:
        return [e for e in self.events if e.kind == kind]
