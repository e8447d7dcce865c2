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
from pathlib import Path

import numpy as np

from usv_mj.core.layouts import DIAG_FIELDS, FUNNEL_FIELDS, REF_FIELDS, STATE_FIELDS
from usv_mj.record.store import CHUNK_ROWS

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

    A record lives in memory (``data``: all its rows), or on disk (:mod:`usv_mj.record.store`: one
    column file per column, appended block by block while the run goes on, only a window of rows
    in memory): ``record["x"]`` is then the column memory-mapped, and :meth:`column_chunks` reads a
    column in chunks without keeping it resident (what the reductions over a long run use).
    :meth:`open` reads a stored record back lazily; :meth:`save` stores an in-memory one.

    Attributes
    ----------
    data: (rows, len(columns)) float64 of an in-memory record; only the first ``n_rows`` rows are
        valid (a stored record has none: use ``record[name]``, :meth:`block`, :meth:`column_chunks`).
    buffer: the rows in memory: rows [base, base + len(buffer)) (``data`` itself when in memory).
    columns_names: the core columns, then ``diagnostic_fields``.
    diagnostic_fields: the controller's declared block.
    events: list of :class:`Event`.
    status: "completed", "diverged", "interrupted" or "failed".
    stop_reason: one sentence when status is not "completed".
    metadata: scenario, versions, timing; filled by the loop.
    statics: what the outputs need beside the rows (the sea, the obstacles, the plan), or None.
    path: the folder of a stored record, else None.
    """

    def __init__(self, capacity: int, metadata: dict | None = None,
                 diagnostic_fields: tuple[str, ...] = DIAG_FIELDS, diagnostic_events: dict | None = None,
                 *, store=None):
        self.diagnostic_fields = tuple(diagnostic_fields)
        clash = set(self.diagnostic_fields) & set(CORE_COLUMNS)
        if clash or len(set(self.diagnostic_fields)) != len(self.diagnostic_fields):
            raise ValueError(f"diagnostic fields must be unique and not core columns: {sorted(clash) or diagnostic_fields}")
        self.column_names = CORE_COLUMNS + self.diagnostic_fields
        self.col = {name: i for i, name in enumerate(self.column_names)}
        self.diagnostic_events = dict(diagnostic_events or {})
        self.buffer = np.full((capacity, len(self.column_names)), np.nan)
        self.base = 0
        self.n_rows = 0
        self.events: list[Event] = []
        self.status = "running"
        self.stop_reason = ""
        self.metadata = dict(metadata or {})
        self.statics = None
        self._store = store

    @classmethod
    def streamed(cls, directory, window: int, metadata: dict | None = None,
                 diagnostic_fields: tuple[str, ...] = DIAG_FIELDS, diagnostic_events: dict | None = None,
                 temporary: bool = False) -> "RunRecord":
        """An empty record that keeps ``window`` rows in memory and its columns in ``directory``
        (:mod:`usv_mj.record.store`); ``temporary``: the folder goes with the record."""
        from usv_mj.record.store import ColumnStore

        rec = cls(window, metadata, diagnostic_fields, diagnostic_events)
        rec._store = ColumnStore(directory, rec.column_names, temporary=temporary)
        rec._store._write_meta(rec._info())   # status "running" until the run ends
        return rec

    @classmethod
    def open(cls, path) -> "RunRecord":
        """A stored record (a folder written by :meth:`save` or by a streamed run), read lazily:
        its columns are memory-mapped, nothing is read until it is used."""
        from usv_mj.record.store import ColumnStore

        store, meta = ColumnStore.open(path)
        if meta.get("status") == "running":   # the process ended inside the run: the rows it wrote
            meta = {**meta, "status": "interrupted",
                    "stop_reason": f"the run ended at row {store.rows} before its record was finished"}
        names = store.column_names
        fields = tuple(meta.get("diagnostic_fields", [c for c in names if c not in COL]))
        if tuple(CORE_COLUMNS + fields) != tuple(names):
            raise ValueError(f"{path}: the stored columns are not a record's (core columns, then {list(fields)})")
        rec = cls(0, meta.get("metadata"), fields, meta.get("diagnostic_events"), store=store)
        rec.n_rows = store.rows
        rec.base = store.rows
        rec.status = meta.get("status", "interrupted")
        rec.stop_reason = meta.get("stop_reason", "")
        rec.events = [Event(float(e["t"]), e["kind"], e["message"], dict(e.get("values") or {}))
                      for e in meta.get("events", [])]
        return rec

    def save(self, path) -> Path:
        """Store the record in the folder ``path`` (column files and record.json); returns it."""
        from usv_mj.record.store import ColumnStore

        store = ColumnStore(path, self.column_names)
        for lo in range(0, self.n_rows, CHUNK_ROWS):
            store.append(self.block(lo, min(self.n_rows, lo + CHUNK_ROWS)))
        store.finish(self._info())
        return Path(path)

    def _info(self) -> dict:
        return {"status": self.status, "stop_reason": self.stop_reason,
                "diagnostic_fields": list(self.diagnostic_fields), "diagnostic_events": self.diagnostic_events,
                "events": [{"t": e.t, "kind": e.kind, "message": e.message, "values": e.values} for e in self.events],
                "metadata": self.metadata}

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

    # storage
    @property
    def stored(self) -> bool:
        """True when the rows are on disk (a streamed or opened record)."""
        return self._store is not None

    @property
    def path(self) -> Path | None:
        return self._store.directory if self._store is not None else None

    def relocated(self, path) -> None:
        """The stored record's folder was moved (renamed) to ``path``: its open files stay valid."""
        if self._store is not None:
            self._store.directory = Path(path)

    @property
    def data(self) -> np.ndarray:
        if self._store is not None:
            raise AttributeError("a stored record has no data array: read record[name], record.block(lo, hi) "
                                 "or record.column_chunks(name)")
        return self.buffer

    def spill(self, hi: int) -> None:
        """Append the rows up to ``hi`` that the store does not have yet (a stored record; the loop
        calls it every block, before the sinks)."""
        store = self._store
        if store is not None and hi > store.rows and not store.finished:
            store.append(self.buffer[store.rows - self.base:hi - self.base])

    def slide(self, hi: int) -> None:
        """Every row before ``hi`` went to the store and the sinks: keep only row hi - 1 (the events'
        and the plant's previous row) and the rows after it in the window."""
        if self._store is None or hi <= self.base + 1:
            return
        keep = hi - 1
        if self._store.rows < min(hi, self.n_rows):
            self.spill(min(hi, self.n_rows))
        tail = self.buffer[keep - self.base:self.n_rows - self.base].copy()
        self.buffer[:len(tail)] = tail
        self.base = keep

    def finish_store(self) -> None:
        """Write every row left in the window, the headers and record.json (again after a change of
        the status, the events or the metadata: call it then)."""
        if self._store is not None:
            if not self._store.finished:
                self.spill(self.n_rows)
            self._store.finish(self._info())

    def block(self, lo: int, hi: int) -> np.ndarray:
        """Rows [lo, hi) with every column, (hi - lo, columns): a view of the window when they are in
        memory, else read from the store."""
        if self.base <= lo and hi - self.base <= len(self.buffer) and (self._store is None or hi <= self.n_rows):
            return self.buffer[lo - self.base:hi - self.base]
        self._store.flush()
        return np.stack([self._store.read(c, lo, hi) for c in self.column_names], axis=1)

    def value(self, name: str, k: int) -> float:
        """Column ``name`` at row ``k`` (negative: from the end)."""
        k = k + self.n_rows if k < 0 else k
        if not 0 <= k < self.n_rows:
            raise IndexError(f"row {k} of a record of {self.n_rows} rows")
        if self.base <= k < self.base + len(self.buffer):  # (k < n_rows: a row of the window)
            return float(self.buffer[k - self.base, self.col[name]])
        self.spill(self.n_rows)
        return float(self._store.read(name, k, k + 1)[0])

    def take(self, name: str, rows) -> np.ndarray:
        """Column ``name`` at the given row indices (ints in [0, n_rows)), float64: indexing of an
        in-memory record; a stored one reads only those rows (one pread per run of consecutive
        rows), never the whole column (the video's frames of a long run: usv_mj.outputs.render.planner)."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if rows.size and (rows.min() < 0 or rows.max() >= self.n_rows):
            raise IndexError(f"rows {int(rows.min())}..{int(rows.max())} of a record of {self.n_rows} rows")
        if self._store is None:
            return np.array(self.buffer[: self.n_rows, self.col[name]][rows], dtype=float)
        if name not in self.col:
            raise KeyError(name)
        self.spill(self.n_rows)
        wanted, where = np.unique(rows, return_inverse=True)
        values = np.empty(wanted.size)
        breaks = np.flatnonzero(np.diff(wanted) != 1) + 1
        for lo, hi in zip(np.r_[0, breaks], np.r_[breaks, wanted.size]):
            values[lo:hi] = self._store.read(name, int(wanted[lo]), int(wanted[hi - 1]) + 1)
        return values[where.reshape(-1)]

    def column_chunks(self, name: str, rows: int = CHUNK_ROWS):
        """Column ``name`` in consecutive chunks of at most ``rows`` rows: views of an in-memory
        record, reads of a stored one (no page of it stays resident)."""
        if name not in self.col:
            raise KeyError(name)
        if self._store is None:
            c = self.col[name]
            for lo in range(0, self.n_rows, rows):
                yield self.buffer[lo:min(lo + rows, self.n_rows), c]
            return
        self.spill(self.n_rows)
        yield from self._store.chunks(name, rows)

    def __getitem__(self, name: str) -> np.ndarray:
        if self._store is None:
            return self.buffer[: self.n_rows, self.col[name]]
        if name not in self.col:
            raise KeyError(name)
        self.spill(self.n_rows)
        return self._store.column(name)

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
