"""The obstacle log: clearance and contact force per control step, and the obstacle events.

:class:`ObstacleLog` is a :class:`usv_mj.loop.simulate.RunSink` (``start``/``rows``/``finish``) that is
also fed once per control step by :class:`usv_mj.obstacles.hooks.ObstacleHook` with
:meth:`ObstacleLog.record_step` (or, in the compiled loop, by its kernel in
:mod:`usv_mj.obstacles.native_step`). It keeps, per step k (the record's row k):

- ``clearance[k, i]``: signed distance [m] hull <-> obstacle i (negative: penetration); NaN when the
  monitor's broad phase left obstacle i out: beyond reach, at least ``exact_within`` away
  (:data:`BEYOND_REACH`; docs/obstacles.md);
- ``normal_force[k, i]``: summed normal contact force [N] between the hull and obstacle i;
- ``obstacle_xy[k, i]``: obstacle i's centre [m] (moving obstacles move);

and appends :class:`usv_mj.record.run_record.Event` s to the record as they happen:

- ``near_miss``: clearance to an obstacle fell under ``margin`` (start of an episode; values:
  obstacle, clearance);
- ``contact``: the hull touches an obstacle (MuJoCo contact; values: obstacle, normal force at the
  first step); ``contact_end`` closes the episode with its peak force and duration;
- ``collision``: plants without contact physics, clearance reached zero (the note of the monitor
  says once that the hull passes through);
- ``replan`` (from :class:`usv_mj.references.planner.Guidance`, via :meth:`add_event`).

Memory: with an in-memory record the arrays hold every row; with a streamed record (one on disk,
:mod:`usv_mj.record.store`) only a window of rows is in memory and the rows go to
``<record folder>/obstacles/`` as sparse entries (:class:`SparseRows`), so a long run's memory does
not depend on its duration; ``clearance`` etc. are then :class:`LazyRows` (``[lo:hi]`` reads those
rows), and :class:`StoredObstacleLog` reads such a folder back lazily.

:meth:`summary` gives the ``summary.json`` fields ``min_clearance_m`` (over the run and all
obstacles) and ``contacts`` (number of contact or collision events) plus per-obstacle minima, reduced
online as the rows come (the same values as a reduction over all of them); ``finish`` also stores
it in ``record.metadata["obstacles"]``.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from usv_mj.record.run_record import Event

#: what a run's log holds for an obstacle out of the monitor's reach (its broad phase:
#: :mod:`usv_mj.obstacles.clearance`)
BEYOND_REACH = ("NaN: beyond reach, not measured this step; its bounding-circle lower bound, hence its "
                "clearance, is at least exact_within_m")


class ObstacleLog:
    """Per-step clearance / contact-force arrays and obstacle events (module docstring)."""

    def __init__(self, obstacles, n_rows: int, margin: float, control_period: float, note: str = "",
                 inflation=None, exact_within: float | None = None):
        """``inflation``: per obstacle, the safety boundary distance [m] to display (NaN: none).
        ``exact_within`` [m]: the monitor's reach when it has the broad phase (entries beyond it are
        NaN: :data:`usv_mj.obstacles.clearance.BEYOND_REACH`), stated in the summary; None: none."""
        self.obstacles = tuple(obstacles)
        n = len(self.obstacles)
        self.margin = float(margin)
        self.dt = float(control_period)
        self.note = note
        self.exact_within = None if exact_within is None else float(exact_within)
        self.inflation = None if inflation is None else np.asarray(inflation, dtype=float)
        self.capacity = int(n_rows)
        self.events: list[Event] = []
        self.n_rows = 0
        self.record = None
        self.kernel_rows = np.zeros(1, np.int64)   # rows the compiled loop's kernel stored (ObstacleLog.n_rows)
        self._base = np.zeros(1, np.int64)         # the window holds rows base[0] .. base[0] + len(window)
        self._near = np.zeros(n, dtype=bool)
        self._contact = np.zeros(n, dtype=bool)
        self._any_contact = False
        self._contact_start = np.zeros(n)
        self._contact_peak = np.zeros(n)
        self._contacts = 0
        self._noted = False
        self._center0 = np.array([o.center for o in self.obstacles], dtype=float).reshape(n, 2)
        self._velocity = np.array([o.velocity for o in self.obstacles], dtype=float).reshape(n, 2)
        self._any_moving = any(o.moving for o in self.obstacles)
        # the online reductions of summary(): per obstacle the least finite clearance and its first row,
        # whether any entry was finite, the peak normal force; rows before ``_reduced`` are in them
        self._min = np.full(n, np.inf)
        self._min_row = np.zeros(n, np.int64)
        self._any_ok = np.zeros(n, dtype=bool)
        self._peak = np.zeros(n)
        self._force_top = 0   # rows from here on have no contact force
        self._reduced = 0
        self._store = None   # a streamed log's files (SparseRows per array): start(), or a big log
        self._temporary = None
        # a log bigger than LOG_STREAM_BYTES streams even beside an in-memory record (many obstacles:
        # 1000 of them make 16 kB a row), into a temporary folder; it never holds all its rows
        self._big = self.capacity * n * 16 > LOG_STREAM_BYTES
        self._window(min(self.capacity, WINDOW_ROWS) if self._big else self.capacity)

    def _window(self, rows: int) -> None:
        """The in-memory rows: all of them (``rows`` = the capacity), or a window of a streamed log."""
        n = len(self.obstacles)
        self._clear = np.full((rows, n), np.nan)
        self._force = np.zeros((rows, n))  # pages untouched until a contact: no memory
        self._force_dirty = False
        self._views()

    def _views(self) -> None:
        """``clearance``, ``normal_force``, ``obstacle_xy``: the arrays (in memory) or :class:`LazyRows`."""
        n, rows = len(self.obstacles), len(self._clear)
        self._xy = None
        if self._store is None:
            self.clearance, self.normal_force = self._clear, self._force
            # static obstacles stay (a read-only view of the centres: no rows x obstacles array to fill);
            # moving ones are written per step
            self._xy = (np.repeat(self._center0[None], rows, axis=0) if self._any_moving
                        else np.broadcast_to(self._center0, (rows, n, 2)))
            self.obstacle_xy = self._xy
        else:
            self.clearance = LazyRows(self, 0)
            self.normal_force = LazyRows(self, 1)
            self.obstacle_xy = LazyRows(self, 2)

    # --- fed by the stepper ----------------------------------------------------------------------

    def record_step(self, t: float, clearance: np.ndarray, normal_force: np.ndarray, in_contact: np.ndarray) -> None:
        """Store step k = round(t / dt) and raise the events that start at it."""
        k = int(round(t / self.dt))
        if k >= self.capacity:
            return
        j = k - int(self._base[0])
        if j < 0:   # a row before the window (never: the rows come in order); it went to the files already
            return
        if j >= len(self._clear):
            if self._store is None:
                if not self._big:
                    return
                self._open_store(None, len(self._clear))
            self._slide(k)
            j = 0
        self._clear[j] = clearance
        if normal_force.any():   # (the rows are zeros until a contact: a window's are cleared when it slides)
            self._force[j] = normal_force
            self._force_dirty = True
            self._force_top = max(self._force_top, k + 1)
        if self._any_moving and self._store is None:
            self._xy[k] = self._center0 + self._velocity * t
        if k >= self.n_rows:
            self.n_rows = k + 1
        near = clearance < self.margin
        if (near & ~self._near).any():
            for i in np.flatnonzero(near & ~self._near):
                o = self.obstacles[i]
                self.add_event(Event(t, "near_miss", f"clearance to {o.name} fell to {clearance[i]:.3f} m "
                                     f"(< margin {self.margin:g} m)",
                                     {"obstacle": o.name, "index": int(i), "clearance_m": float(clearance[i])}))
        self._near[:] = near              # in place: the compiled loop's hook kernel holds it
        if self._any_contact or in_contact.any():
            kind = "contact" if not self.note else "collision"
            for i in np.flatnonzero(in_contact & ~self._contact):
                o = self.obstacles[i]
                if self.note and not self._noted:
                    self._noted = True
                    self.add_event(Event(t, "note", self.note, {}))
                self._contacts += 1
                self._contact_start[i] = t
                self._contact_peak[i] = normal_force[i]
                msg = (f"hull touches {o.name}: normal force {normal_force[i]:.1f} N" if kind == "contact" else
                       f"hull reaches {o.name} (clearance {clearance[i]:.3f} m; no contact physics)")
                self.add_event(Event(t, kind, msg, {"obstacle": o.name, "index": int(i),
                                                    "normal_force_N": float(normal_force[i]),
                                                    "clearance_m": float(clearance[i])}))
            both = in_contact & self._contact
            self._contact_peak[both] = np.maximum(self._contact_peak[both], normal_force[both])
            for i in np.flatnonzero(~in_contact & self._contact):
                o = self.obstacles[i]
                self.add_event(Event(t, f"{kind}_end", f"hull leaves {o.name} after {t - self._contact_start[i]:.3f} s "
                                     f"(peak normal force {self._contact_peak[i]:.1f} N)",
                                     {"obstacle": o.name, "index": int(i), "duration_s": float(t - self._contact_start[i]),
                                      "peak_normal_force_N": float(self._contact_peak[i])}))
            self._contact[:] = in_contact
            self._any_contact = bool(self._contact.any())

    def kernel_state(self) -> tuple:
        """(clearance rows, their first row (base, (1,) int64), near-miss flags, contact flags,
        margin [m]): what the compiled loop's hook kernel (usv_mj.obstacles.native_step) reads and
        writes in place of :meth:`record_step` (it answers "Python" for a row outside the window);
        :attr:`kernel_rows` is the (1,) array it counts its rows in."""
        return self._clear, self._base, self._near, self._contact, float(self.margin)

    def add_event(self, event: Event) -> None:
        self.events.append(event)
        if self.record is not None:
            self.record.events.append(event)

    # --- streaming ---------------------------------------------------------------------------------

    @property
    def stored(self) -> bool:
        """True when the rows stream to disk (the record does): only a window of rows in memory."""
        return self._store is not None

    def _rows_known(self) -> int:
        return min(self.capacity, max(self.n_rows, int(self.kernel_rows[0])))

    def _slide(self, k: int) -> None:
        """Every row before ``k`` to the files; the window then starts at row k."""
        self.n_rows = self._rows_known()
        self._spill(self.n_rows)
        self._base[0] = k
        if self._force_dirty:
            self._force[:] = 0.0
            self._force_dirty = False

    def _spill(self, hi: int) -> None:
        """Rows [reduced, hi) into the summary's reductions and (a streamed log) its files."""
        lo = self._reduced
        hi = min(hi, self._rows_known())
        if hi <= lo:
            return
        base = int(self._base[0])
        c, f = self._clear[lo - base:hi - base], self._force[lo - base:hi - base]
        if self._store is not None:
            self._store[0].append(lo, c, ~np.isnan(c))
            self._store[1].append(lo, f, f != 0.0)
        self._reduce(lo, c, f)
        self._reduced = hi

    def _reduce(self, lo: int, c: np.ndarray, f: np.ndarray) -> None:
        """The summary's reductions over rows [lo, lo + len(c)): per obstacle the least finite entry
        and the first row holding it (the rows come in order, so this is numpy's argmin over all of
        them with the non-finite entries left out), the peak force. One pass of ``np.fmin`` (NaN:
        beyond reach, skipped) over the block; the rows of the least entries are looked up only
        for the obstacles whose minimum it lowers."""
        if not len(c):
            return
        least = np.fmin.reduce(c, axis=0)
        if np.isneginf(least).any():   # an entry of -inf (not finite: left out), never in practice
            least = np.where(np.isfinite(c), c, np.inf).min(axis=0)
        ok = np.isfinite(least)
        better = np.flatnonzero(ok & (least < self._min))
        if better.size:
            first = np.argmax(c[:, better] == least[better], axis=0)
            self._min[better] = c[first, better]   # (that row's value: of 0.0 and -0.0, the first)
            self._min_row[better] = lo + first
        self._any_ok |= ok
        if self._force_top > lo:   # a contact force in these rows
            np.maximum(self._peak, f.max(axis=0), out=self._peak)

    def block(self, lo: int, hi: int) -> tuple:
        """Rows [lo, hi) as (clearance (r, m), normal force (r, m), centres (r, m, 2)) arrays: from the
        window, a streamed log's files, and NaN for rows past the log's end."""
        lo, hi = max(0, int(lo)), max(int(lo), int(hi))
        m = len(self.obstacles)
        r = hi - lo
        if self._store is None:
            have = max(0, min(hi, self.capacity) - lo)
            if have == r:
                return self._clear[lo:hi], self._force[lo:hi], self._xy[lo:hi]
            c, f, xy = np.full((r, m), np.nan), np.full((r, m), np.nan), np.full((r, m, 2), np.nan)
            c[:have], f[:have], xy[:have] = self._clear[lo:lo + have], self._force[lo:lo + have], self._xy[lo:lo + have]
            return c, f, xy
        c, f = np.full((r, m), np.nan), np.full((r, m), np.nan)
        known = self._rows_known()
        top = min(hi, self.capacity)
        f[:max(0, top - lo)] = 0.0
        if lo < self._reduced:   # on disk
            a, b = lo, min(hi, self._reduced)
            self._store[0].read(a, b, c[:b - a])
            self._store[1].read(a, b, f[:b - a])
        base = int(self._base[0])
        a, b = max(lo, self._reduced, base), min(hi, known)
        if b > a:   # in the window
            c[a - lo:b - lo] = self._clear[a - base:b - base]
            f[a - lo:b - lo] = self._force[a - base:b - base]
        if self._any_moving:   # as record_step places them in memory
            xy = self._center0[None] + self._velocity[None] * (np.arange(lo, hi) * self.dt)[:, None, None]
        else:
            xy = np.repeat(self._center0[None], r, axis=0)
        xy[max(0, top - lo):] = np.nan
        return c, f, xy

    # --- RunSink -----------------------------------------------------------------------------------

    def start(self, record) -> None:
        """A streamed record (``record.stored``) gets a streamed log: its rows go to
        ``<record folder>/obstacles/`` (:class:`SparseRows` files, removed with a temporary record's
        folder) and a window of as many rows as the record's is kept in memory."""
        self.record = record
        if self._store is None and self.n_rows == 0:
            if getattr(record, "stored", False):
                self._open_store(Path(record.path) / OBSTACLE_FOLDER, max(2, min(self.capacity, len(record.buffer))))
            elif self._big:
                self._open_store(None, min(self.capacity, WINDOW_ROWS))

    def _open_store(self, folder, window: int) -> None:
        """Stream from here on into ``folder`` (None: a temporary one, removed with the log) with a
        window of ``window`` rows in memory; rows recorded before (a big log fed without a run) go
        to the files first and stay in the window."""
        import tempfile
        import weakref

        if folder is None:
            folder = Path(tempfile.mkdtemp(prefix="usv_mj_obstacles_"))
            self._temporary = weakref.finalize(self, _remove_folder, str(folder))
        folder.mkdir(parents=True, exist_ok=True)
        m = len(self.obstacles)
        self._store = (SparseRows(folder, "clearance", m, np.nan), SparseRows(folder, "normal_force", m, 0.0))
        self._folder = folder
        self._write_meta("running")
        self.n_rows = self._rows_known()
        if self._reduced:   # reduced before there were files (the window starts at row 0: no slide yet)
            c, f = self._clear[:self._reduced], self._force[:self._reduced]
            self._store[0].append(0, c, ~np.isnan(c))
            self._store[1].append(0, f, f != 0.0)
        self._spill(self.n_rows)
        if self.n_rows == 0:
            self._window(window)
        else:
            self._views()

    def _write_meta(self, status: str) -> None:
        meta = {"format": "usv_mj obstacle log 1", "status": status, "rows": self._reduced,
                "control_period_s": self.dt, "obstacles": [o.name for o in self.obstacles],
                "center": self._center0.tolist(), "velocity": self._velocity.tolist(),
                "exact_within_m": self.exact_within, "beyond_reach": BEYOND_REACH if self.exact_within else None}
        tmp = self._folder / "obstacles.json.tmp"
        tmp.write_text(json.dumps(meta, indent=1))
        os.replace(tmp, self._folder / "obstacles.json")

    def rows(self, record, lo: int, hi: int) -> None:
        """The rows up to ``hi`` into the reductions (and a streamed log's files): they are complete."""
        self._spill(hi)

    def finish(self, record) -> None:
        self.n_rows = self._rows_known()
        self._spill(self.n_rows)
        if self._store is not None:
            for part in self._store:
                part.finish()
            self._write_meta("completed")
        record.metadata["obstacles"] = self.summary()
        if getattr(record, "stored", False):   # its record.json (written before the sinks end) gets it too
            record.finish_store()

    # --- results -----------------------------------------------------------------------------------

    def summary(self) -> dict:
        """``min_clearance_m``, ``contacts`` and per-obstacle ``min_clearance_m`` / time / peak force
        (from the online reductions: every row recorded so far). ``beyond_reach_m``: with the broad
        phase, the reach (an obstacle never within it has ``min_clearance_m`` None)."""
        self.n_rows = self._rows_known()
        self._spill(self.n_rows)
        per = []
        for i, o in enumerate(self.obstacles):
            k = int(self._min_row[i]) if self._any_ok[i] else -1
            per.append({"name": o.name, "kind": o.kind, "moving": o.moving,
                        "min_clearance_m": float(self._min[i]) if k >= 0 else None,
                        "t_min_s": float(k * self.dt) if k >= 0 else None,
                        "peak_normal_force_N": float(self._peak[i]),
                        "inflation_m": self._inflation(i)})
        finite = self._min[self._any_ok]
        kinds = [e.kind for e in self.events]
        out = {
            "min_clearance_m": float(finite.min()) if finite.size else None,
            "contacts": self._contacts,
            "near_misses": kinds.count("near_miss"),
            "replans": kinds.count("replan"),
            "contact_physics": not bool(self.note),
            "per_obstacle": per,
        }
        if self.exact_within is not None:
            out["beyond_reach_m"] = self.exact_within
        return out

    def _inflation(self, i: int):
        """The safety boundary [m] drawn around obstacle i (the plan's G + margin at the pass), or None."""
        if self.inflation is None or not math.isfinite(self.inflation[i]):
            return None
        return float(self.inflation[i])

    def frame(self, k: int) -> dict:
        """What the MCAP topic ``/usv/obstacles`` and the renderer need at row k (plain data)."""
        c, f, xy = (a[0] for a in self.block(k, k + 1))
        return {
            "t": k * self.dt,
            "obstacles": [{"name": o.name, "kind": o.kind, "center": xy[i].tolist(),
                           "radius": o.radius, "size": list(o.size), "yaw": o.yaw, "moving": o.moving,
                           "inflation_m": self._inflation(i),
                           "clearance_m": float(c[i]), "normal_force_N": float(f[i])}
                          for i, o in enumerate(self.obstacles)],
        }


OBSTACLE_FOLDER = "obstacles"
#: an obstacle log bigger than this (rows x obstacles x 16 bytes) streams to disk even when the record
#: stays in memory (the record's own threshold: usv_mj.loop.simulate.STREAM_BYTES)
LOG_STREAM_BYTES = 256 * 2 ** 20
#: rows of a streamed log's window when the record has none (an in-memory record)
WINDOW_ROWS = 4002


def _remove_folder(folder: str) -> None:
    import shutil

    shutil.rmtree(folder, ignore_errors=True)


class LazyRows:
    """A streamed log's clearance (0), normal force (1) or centres (2) as an array-like of
    ``capacity`` rows: ``rows[lo:hi]`` (and ``rows[k]``, ``rows[lo:hi, i]``) reads just those rows
    (:meth:`ObstacleLog.block`); ``np.asarray(rows)`` reads them all."""

    def __init__(self, log: ObstacleLog, which: int):
        self.log, self.which = log, which

    def __len__(self) -> int:
        return self.log.capacity

    @property
    def shape(self) -> tuple:
        m = len(self.log.obstacles)
        return (self.log.capacity, m, 2) if self.which == 2 else (self.log.capacity, m)

    def __getitem__(self, key):
        rest = ()
        if isinstance(key, tuple):
            key, rest = key[0], key[1:]
        if isinstance(key, (int, np.integer)):
            k = int(key) + (self.log.capacity if key < 0 else 0)
            if not 0 <= k < self.log.capacity:
                raise IndexError(f"row {key} of an obstacle log of {self.log.capacity} rows")
            out = self.log.block(k, k + 1)[self.which][0]
        elif isinstance(key, slice):
            lo, hi, step = key.indices(self.log.capacity)
            out = self.log.block(lo, max(lo, hi))[self.which][::step]
        else:
            raise TypeError(f"a streamed obstacle log's rows are read by an index or a slice, not {key!r}")
        return out[rest] if rest else out

    def __array__(self, dtype=None, copy=None):
        out = self[:]
        return out if dtype is None else out.astype(dtype)


class SparseRows:
    """One (rows, m) float64 array of a streamed obstacle log, on disk as its entries that are not
    ``fill`` (NaN: the clearance's beyond-reach entries, 0: no contact force): three ``.npy``
    files ``<name>.row`` (int64), ``<name>.index`` (int32) and ``<name>.value`` (float64), in row
    order (:class:`usv_mj.record.store.AppendFile`). So the files grow with what was measured
    (the obstacles within reach, the contacts), not with rows x obstacles; rows [lo, hi) are read
    by a binary search in the row file (a few pages) and the entries between."""

    def __init__(self, folder, name: str, m: int, fill: float, mode: str = "write"):
        from usv_mj.record.store import AppendFile

        self.m, self.fill = m, fill
        self.row = AppendFile(Path(folder) / f"{name}.row.npy", "<i8", mode)
        self.index = AppendFile(Path(folder) / f"{name}.index.npy", "<i4", mode)
        self.value = AppendFile(Path(folder) / f"{name}.value.npy", "<f8", mode)
        # a killed run's files may end in a partial entry: the entries all three files hold
        self.row.count = self.index.count = self.value.count = min(self.row.count, self.index.count,
                                                                   self.value.count)

    def append(self, lo: int, block: np.ndarray, keep: np.ndarray) -> None:
        r, i = np.nonzero(keep)   # row-major: in row order
        self.row.append(r + lo)
        self.index.append(i)
        self.value.append(block[r, i])

    def read(self, lo: int, hi: int, out: np.ndarray) -> None:
        """Rows [lo, hi) into ``out`` (hi - lo, m), the entries not stored set to ``fill``."""
        rows = self.row.mapped()
        a, b = int(np.searchsorted(rows, lo)), int(np.searchsorted(rows, hi))
        out[:] = self.fill
        if b > a:
            out[self.row.read(a, b) - lo, self.index.read(a, b)] = self.value.read(a, b)

    def finish(self) -> None:
        for part in (self.row, self.index, self.value):
            part.finish()


class StoredObstacleLog:
    """A streamed obstacle log read back from its folder (``<record folder>/obstacles``), lazily:
    :meth:`block` and the array-likes ``clearance``, ``normal_force``, ``obstacle_xy``
    (:class:`LazyRows`) read only the rows asked for. ``rows``: the rows it holds; ``names``, the
    obstacles'; ``meta``: its ``obstacles.json``."""

    def __init__(self, folder):
        folder = Path(folder)
        meta_path = folder / "obstacles.json"
        if not meta_path.exists():
            raise FileNotFoundError(f"{folder}: no stored obstacle log (obstacles.json missing)")
        self.meta = json.loads(meta_path.read_text())
        self.names = list(self.meta["obstacles"])
        m = len(self.names)
        self.obstacles = self.names
        self.dt = float(self.meta["control_period_s"])
        self._center0 = np.asarray(self.meta["center"], dtype=float).reshape(m, 2)
        self._velocity = np.asarray(self.meta["velocity"], dtype=float).reshape(m, 2)
        self._parts = (SparseRows(folder, "clearance", m, np.nan, mode="read"),
                       SparseRows(folder, "normal_force", m, 0.0, mode="read"))
        rows = self._parts[0].row
        last = int(rows.read(rows.count - 1, rows.count)[0]) + 1 if rows.count else 0
        self.rows = self.capacity = int(self.meta["rows"]) if self.meta.get("status") != "running" else last
        self.clearance, self.normal_force, self.obstacle_xy = (LazyRows(self, i) for i in range(3))

    def block(self, lo: int, hi: int) -> tuple:
        """Rows [lo, hi) as (clearance, normal force, centres) arrays (NaN past the end)."""
        lo, hi = max(0, int(lo)), max(int(lo), int(hi))
        m, r = len(self.names), hi - lo
        c, f = np.full((r, m), np.nan), np.full((r, m), np.nan)
        top = max(0, min(hi, self.rows) - lo)
        self._parts[0].read(lo, lo + top, c[:top])
        self._parts[1].read(lo, lo + top, f[:top])
        if self._velocity.any():
            xy = self._center0[None] + self._velocity[None] * (np.arange(lo, hi) * self.dt)[:, None, None]
        else:
            xy = np.repeat(self._center0[None], r, axis=0)
        xy[top:] = np.nan
        return c, f, xy
