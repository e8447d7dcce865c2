"""A run's record on disk, one column per file, appended block by block while the run goes on.

Layout of a stored record (a folder, e.g. ``out/record/``):

- ``<column>.npy``: one NumPy ``.npy`` file (format 1.0, little-endian float64, 1-D) per column
  of the record (``t``, ``x``, ..., the controller's diagnostics); a fixed 128-byte header, then
  the rows in order. The header's shape is written when the store is finished (and is re-derived
  from the file's size for a folder left by a run that was killed);
- ``record.json``: the column names, the row count, the status, the stop reason, the events and
  the metadata (written when the run ends; Python's JSON, so +-inf and NaN (an unlimited
  actuator's limit) are ``Infinity`` and ``NaN`` and read back as they were).

Why ``.npy`` columns and not Arrow IPC: a column is one contiguous little-endian array in its own
file, so ``np.load(path, mmap_mode="r")`` (and :meth:`ColumnStore.column`) gives it as one
memory-mapped ndarray without a copy, any tool that reads NumPy reads it, and appending a block is
a plain ``write``; Arrow's record batches would hand a ten-hour column back as thousands of chunks
that must be concatenated (copied) to become one array.

Memory: appended blocks go through the page cache (not the process's resident set); reading a
whole memory-mapped column makes its pages resident, so the reductions over a long run read it in
chunks (:meth:`ColumnStore.chunks`, by ``pread`` into a fresh buffer: nothing stays mapped).
"""

from __future__ import annotations

import json
import os
import shutil
import weakref
from pathlib import Path

import numpy as np

HEADER_BYTES = 128          # the fixed .npy header of every column file (magic, length, dict, padding)
CHUNK_ROWS = 1 << 18        # rows per chunk of the chunked reductions (2 MB of float64)
META_FILE = "record.json"
_MAGIC = b"\x93NUMPY\x01\x00"


def _header(rows: int, descr: str = "<f8") -> bytes:
    text = "{'descr': '%s', 'fortran_order': False, 'shape': (%d,), }" % (descr, rows)
    room = HEADER_BYTES - len(_MAGIC) - 2
    body = text.ljust(room - 1) + "\n"
    if len(body) != room:
        raise ValueError(f"record store: {rows} rows do not fit the .npy header")
    return _MAGIC + len(body).to_bytes(2, "little") + body.encode("latin1")


def _plain(obj):
    """``obj`` as JSON data (numpy scalars as Python numbers; other objects as their text)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return str(obj)


class ColumnStore:
    """The column files of one record in ``directory``: :meth:`append` blocks, then :meth:`finish`.

    ``temporary``: the folder is removed when the store is garbage-collected (a long run that
    :func:`usv_mj.simulate` streamed on its own, with no folder given)."""

    def __init__(self, directory, column_names, *, temporary: bool = False, mode: str = "write"):
        self.directory = Path(directory)
        self.column_names = tuple(column_names)
        self.rows = 0
        self.finished = mode != "write"
        self._writable = mode == "write"
        self._maps: dict = {}
        if mode == "write":
            self.directory.mkdir(parents=True, exist_ok=True)
            stale = self.directory / META_FILE
            if stale.exists():
                stale.unlink()
            self._files = {}
            self._counts = dict.fromkeys(self.column_names, 0)   # rows in each file (see append)
            for name in self.column_names:
                f = open(self.directory / f"{name}.npy", "w+b")
                f.write(_header(0))
                self._files[name] = f
            self._write_meta({"status": "running"})   # the columns' order, for a run that is killed
        else:
            self._files = {name: open(self.directory / f"{name}.npy", "rb") for name in self.column_names}
        if temporary:
            weakref.finalize(self, _remove, list(self._files.values()), str(self.directory))

    @classmethod
    def open(cls, directory):
        """A finished (or killed) store, read only; returns (store, the parsed record.json)."""
        directory = Path(directory)
        meta_path = directory / META_FILE
        meta = json.loads(meta_path.read_text()) if meta_path.exists() else None
        if meta is None or not (directory / "t.npy").exists():
            raise FileNotFoundError(f"{directory}: no stored record ({META_FILE} or t.npy missing)")
        names = meta["columns"]
        store = cls(directory, names, mode="read")
        sizes = [(os.fstat(f.fileno()).st_size - HEADER_BYTES) // 8 for f in store._files.values()]
        store.rows = int(min(sizes))
        if meta.get("status") != "running":   # finished: its row count (a killed run: the whole rows there)
            store.rows = min(store.rows, int(meta["rows"]))
        return store, meta

    def append(self, block: np.ndarray) -> None:
        """Rows (n, columns), the rows after :attr:`rows`, at the end of every column file. An
        append that an interrupt (Ctrl-C) cut is finished by the next: a column that already has
        some of the rows gets only the ones it lacks."""
        if self.finished:
            raise RuntimeError(f"record store {self.directory} is finished")
        if block.shape[0] == 0:
            return
        target = self.rows + block.shape[0]
        for i, name in enumerate(self.column_names):
            have = self._counts[name]
            if have < target:
                self._files[name].write(np.ascontiguousarray(block[have - self.rows:, i], dtype="<f8").data)
                self._counts[name] = target
        self.rows = target
        self._maps.clear()

    def flush(self) -> None:
        if not self.finished:
            for f in self._files.values():
                f.flush()

    def finish(self, info: dict) -> None:
        """Write every column's header (its row count) and ``record.json`` (``info`` plus columns
        and rows). May be called again (a later change of the status or events)."""
        if self._writable:
            for f in self._files.values():
                f.flush()
                os.pwrite(f.fileno(), _header(self.rows), 0)
        self.finished = True
        self._write_meta(info)

    def _write_meta(self, info: dict) -> None:
        meta = {"format": "usv_mj record 1", "columns": list(self.column_names), "rows": self.rows,
                **_plain(info)}
        tmp = self.directory / (META_FILE + ".tmp")
        tmp.write_text(json.dumps(meta, indent=1))
        os.replace(tmp, self.directory / META_FILE)

    def column(self, name: str) -> np.ndarray:
        """The stored column, memory-mapped read only (its pages become resident as they are read)."""
        found = self._maps.get(name)
        if found is not None:
            return found
        self.flush()
        if self.rows == 0:
            arr = np.empty(0)
        else:
            arr = np.memmap(self._files[name], dtype="<f8", mode="r", offset=HEADER_BYTES, shape=(self.rows,))
        self._maps[name] = arr
        return arr

    def read(self, name: str, lo: int, hi: int) -> np.ndarray:
        """Rows [lo, hi) of a column, read into a new array (no mapping kept)."""
        lo, hi = max(0, lo), min(hi, self.rows)
        if hi <= lo:
            return np.empty(0)
        self.flush()
        raw = os.pread(self._files[name].fileno(), (hi - lo) * 8, HEADER_BYTES + lo * 8)
        return np.frombuffer(raw, dtype="<f8")

    def chunks(self, name: str, rows: int = CHUNK_ROWS):
        """The column in consecutive chunks of ``rows`` rows (read by pread: bounded memory)."""
        for lo in range(0, self.rows, rows):
            yield self.read(name, lo, lo + rows)


class AppendFile:
    """One 1-D ``.npy`` file of ``dtype`` (little-endian) appended in blocks, the header written by
    :meth:`finish` (a file left unfinished has its length in its size): the column files' format
    for other element types (the obstacle log's sparse entries, :mod:`usv_mj.obstacles.sink`).
    Read back with :meth:`read` (pread: nothing stays mapped) or :meth:`mapped` (memory-mapped;
    pages become resident as they are touched: a binary search touches a few)."""

    def __init__(self, path, dtype, mode: str = "write"):
        self.path = Path(path)
        self.dtype = np.dtype(dtype).newbyteorder("<")
        self.count = 0
        if mode == "write":
            self._file = open(self.path, "w+b")
            self._file.write(_header(0, self.dtype.str))
        else:   # read: as many whole elements as the file holds (a killed run's too)
            self._file = open(self.path, "rb")
            self.count = max(0, (os.fstat(self._file.fileno()).st_size - HEADER_BYTES) // self.dtype.itemsize)

    def append(self, values) -> None:
        values = np.ascontiguousarray(values, dtype=self.dtype).reshape(-1)
        if values.size:
            self._file.write(values.data)
            self.count += values.size

    def flush(self) -> None:
        if self._file.writable():
            self._file.flush()

    def finish(self) -> None:
        self._file.flush()
        os.pwrite(self._file.fileno(), _header(self.count, self.dtype.str), 0)

    def read(self, lo: int, hi: int) -> np.ndarray:
        lo, hi = max(0, lo), min(hi, self.count)
        if hi <= lo:
            return np.empty(0, self.dtype)
        self.flush()
        size = self.dtype.itemsize
        return np.frombuffer(os.pread(self._file.fileno(), (hi - lo) * size, HEADER_BYTES + lo * size), self.dtype)

    def mapped(self) -> np.ndarray:
        self.flush()
        if self.count == 0:
            return np.empty(0, self.dtype)
        return np.memmap(self._file, dtype=self.dtype, mode="r", offset=HEADER_BYTES, shape=(self.count,))

    def close(self) -> None:
        try:
            self._file.close()
        except OSError:
            pass


def _remove(files, directory: str) -> None:
    for f in files:
        try:
            f.close()
        except OSError:
            pass
    shutil.rmtree(directory, ignore_errors=True)
