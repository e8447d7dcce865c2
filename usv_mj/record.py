"""The record of one run: every control step in named float64 columns, plus events and metadata.

Rows are control steps k = 0..n at t_k = k dt. The columns are a core that every run has, then
the block that the run's controller declares (its ``diagnostic_fields``):

- ``t`` [s]; the state ``x, y, psi`` [m, m, rad] and ``u, v, r`` [m/s, m/s, rad/s] (psi unwrapped);
- the reference ``x_d, y_d, psi_d, x_d_dot, y_d_dot, r_d, u_d`` (:data:`usv_mj.controllers.base.REF_FIELDS`);
- ``tau_u, tau_r`` (the law's output [N, N m]), ``q_tau_u, q_tau_r`` (the quantized command, what
  is transmitted), ``k_u, k_r`` (the quantizers' signed level indices), ``f_u, f_r`` (the force
  the actuators realize, what the plant receives: Q(tau) when they are unlimited) and ``sat_u,
  sat_r`` (1 where an actuator limit cut the command);
- the controller's block, e.g. the PPC law's e1..e3, rho1..3, z1..3, e*, psi_a, ... (its fields
  are in ``record.diagnostic_fields``; a controller with a funnel declares e, rho and z).

The input in row k is held from t_k to t_{k+1}; the last row's input is never applied.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usv_mj.controllers.base import DIAG_FIELDS, FUNNEL_FIELDS, REF_FIELDS

STATE_FIELDS = ("x", "y", "psi", "u", "v", "r")
CONTROL_FIELDS = ("tau_u", "tau_r", "q_tau_u", "q_tau_r", "k_u", "k_r", "f_u", "f_r", "sat_u", "sat_r")
CORE_COLUMNS = ("t",) + STATE_FIELDS + REF_FIELDS + CONTROL_FIELDS
#: the core's indices (the same in every record: the core comes first)
COL = {name: i for i, name in enumerate(CORE_COLUMNS)}
SL_STATE = slice(COL["x"], COL["r"] + 1)
SL_REF = slice(COL["x_d"], COL["u_d"] + 1)
SL_CONTROL = slice(COL["tau_u"], COL["sat_r"] + 1)
N_CORE = len(CORE_COLUMNS)
SL_DIAG = slice(N_CORE, None)
#: the columns of a run of the paper's PPC law (the default layout)
COLUMNS = CORE_COLUMNS + DIAG_FIELDS


@dataclass
class Event:
    """Something worth a line in the log: a funnel violation, an s2 clamp, a divergence, a stop."""

    t: float
    kind: str
    message: str
    values: dict = field(default_factory=dict)


class RunRecord:
    """A run in arrays. ``record["x"]`` is the x column of the rows written so far.

    Attributes
    ----------
    data: (rows, len(columns)) float64; only the first ``n_rows`` rows are valid.
    columns_names: the core columns, then ``diagnostic_fields``.
    diagnostic_fields: the controller's declared block.
    events: list of :class:`Event`.
    status: "completed", "diverged", "interrupted" or "failed".
    stop_reason: one sentence when status is not "completed".
    metadata: scenario, versions, timing; filled by the loop.
    statics: what the outputs need beside the rows (the sea, the obstacles, the plan), or None.
    """

    def __init__(self, capacity: int, metadata: dict | None = None,
                 diagnostic_fields: tuple[str, ...] = DIAG_FIELDS, diagnostic_events: dict | None = None):
        self.diagnostic_fields = tuple(diagnostic_fields)
        clash = set(self.diagnostic_fields) & set(CORE_COLUMNS)
        if clash or len(set(self.diagnostic_fields)) != len(self.diagnostic_fields):
            raise ValueError(f"diagnostic fields must be unique and not core columns: {sorted(clash) or diagnostic_fields}")
        self.column_names = CORE_COLUMNS + self.diagnostic_fields
        self.col = {name: i for i, name in enumerate(self.column_names)}
        self.diagnostic_events = dict(diagnostic_events or {})
        self.data = np.full((capacity, len(self.column_names)), np.nan)
        self.n_rows = 0
        self.events: list[Event] = []
        self.status = "running"
        self.stop_reason = ""
        self.metadata = dict(metadata or {})
        self.statics = None

    @classmethod
    def from_arrays(cls, columns: dict, events=(), metadata=None, status="completed", stop_reason="",
                    diagnostic_fields: tuple[str, ...] | None = None, diagnostic_events: dict | None = None):
        """A record from named arrays; ``diagnostic_fields`` defaults to the names beyond the core."""
        n = len(columns["t"])
        if diagnostic_fields is None:
            diagnostic_fields = tuple(k for k in columns if k not in COL)
        rec = cls(n, metadata, diagnostic_fields, diagnostic_events)
        for name, values in columns.items():
            if name in rec.col:
                rec.data[:, rec.col[name]] = values
        rec.n_rows = n
        rec.events = list(events)
        rec.status, rec.stop_reason = status, stop_reason
        return rec

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[: self.n_rows, self.col[name]]

    def __contains__(self, name: str) -> bool:
        return name in self.col

    @property
    def has_funnel(self) -> bool:
        """True when the controller declared the funnel block (e, rho, z of Eqs. 9 and 14)."""
        return all(f in self.col for f in FUNNEL_FIELDS)

    @property
    def columns(self) -> dict:
        return {name: self[name] for name in self.column_names}

    def __len__(self) -> int:
        return self.n_rows

    def events_of(self, kind: str) -> list[Event]:
        return [e for e in self.events if e.kind == kind]
