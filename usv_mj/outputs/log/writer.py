"""Writing a run log: :class:`RunLogWriter` owns one ``.mcap`` file; ``writer.sink(run)`` logs one run.

Usage (what the main job does)::

    with RunLogWriter(out / "run.mcap", scenario) as writer:
        record = simulate(scenario, sinks=[writer.sink("main")])
        base = simulate(scenario, controller_kind="pi", sinks=[writer.sink("baseline")])

The simulation loop hands the sink a block of rows every ``block`` steps (``rows(record, lo, hi)``).
The sink copies the block into a slot of a shared-memory ring (one memcpy, no pickling) and sends
the slot number, with the events added since the last call, to a background process
(``multiprocessing`` spawn context) that lays out the messages (protobuf per step, JSON for the
Foxglove frames) and the MCAP chunks, compresses them (zstd), writes them and frees the slot; so the second core does the logging while the loop runs.
Memory stays bounded: the ring has ``queue_blocks`` slots of ``SLOT_ROWS`` rows (the loop waits when
all are full), and the file is written chunk by chunk (``rows_per_chunk`` rows per chunk).

This module is the process and queue side; the message side (what a command becomes in the file)
is :class:`usv_mj.outputs.log.messages.RunLogFile`.

What is in the file (topics: :mod:`usv_mj.outputs.log.topics`):

- metadata ``usv_mj`` (at open): schema version, preset, every parameter (``scenario.to_dict()``),
  package versions (python, numpy, numba, mujoco, mcap, orjson, protobuf, zstandard, usv_mj), the
  project's own version (``usv_mj_version``, usv_mj.core.version), every plug-in the run names
  (``plugins``: each kind that is not built in, with its distribution and version, or its module's
  or data file's path: :func:`plugins_of`), and in a git checkout the commit and whether the tree
  had uncommitted changes (an installed package has none: ``install`` says so);
- attachments: ``models/<name>.xml`` for every model XML of the project, ``scenario/<file>`` when
  ``scenario.source`` is a file, any ``attachments`` passed in, and ``scene/<run>.xml`` (at
  ``start``, a MuJoCo plant's run): the MJCF scene that plant ran (``MuJoCoPlant.scene_xml``);
- metadata ``run_start/<run>`` (at ``start``): topic prefix, the record's metadata, the columns;
- metadata ``run_end/<run>`` (at ``finish``): status, stop reason, rows, the record's final
  metadata and ``usv_mj.record.summary.summarize(record)`` (all JSON text).

An interrupted run (Ctrl-C, an exception, a divergence) still gets every row up to the stop, its
events (the loop records why it stopped) and a ``run_end`` record, because ``simulate`` always calls
``finish``; ``finish`` never raises (a failure of the writer is kept and raised by :meth:`close`,
so it cannot hide the run's own exception). The worker ignores SIGINT, SIGTERM and SIGHUP from its
first instruction on (:func:`usv_mj.support.spawning.start_sheltered`), so a Ctrl-C, a hang-up or
a ``kill -TERM`` sent to the whole process group stops the run, not the file: the parent closes it
with every row the run made. A killed process leaves a file without summary that
:func:`usv_mj.outputs.log.read_run` still reads up to its last complete chunk.
"""


from __future__ import annotations

import atexit
import math
import mimetypes
import os
import platform
import queue
import subprocess
import sys
import time
import traceback
import uuid
import warnings
import weakref
from multiprocessing import shared_memory
from datetime import datetime, timezone
from importlib import metadata as importlib_metadata
from pathlib import Path

import numpy as np

from usv_mj.core.registry import origins
from usv_mj.core.version import __version__
from usv_mj.record.run_record import COL, COLUMNS, RunRecord
from usv_mj.support.assets import model_files
from usv_mj.outputs.log.messages import (RunLogError, RunLogFile, frame_layout, funnel_layout, json_text,  # noqa: F401 (re-exported)
                       obstacle_table, reference_path)
from usv_mj.outputs.log.topics import SCHEMA_VERSION, prefix_for
from usv_mj.support.assets import PACKAGE_DIR
from usv_mj.support.spawning import (group_signals_blocked, shelter_from_group_signals, spawn_context,
                                    start_resource_tracker, start_sheltered)

PROJECT_ROOT = PACKAGE_DIR.parent
SLOT_ROWS = 2048       # rows per slot of the shared-memory ring at the PPC record's width
SLOT_FLOATS = SLOT_ROWS * len(COLUMNS)   # a slot's size in float64; a run of W columns puts SLOT_FLOATS // W rows in it


def package_versions() -> dict:
    """Versions of the packages a run depends on ("not installed" when absent)."""
    out = {"python": platform.python_version()}
    for name in ("usv_mj", "numpy", "numba", "mujoco", "dm-control", "mcap", "orjson", "protobuf", "zstandard"):
        try:
            out[name] = importlib_metadata.version(name)
        except importlib_metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def plugins_of(scenario) -> dict:
    """Every kind the scenario names that is not built in, with where it comes from: the installed
    distribution and its version, or the module's file, or the data file
    (:func:`usv_mj.core.registry.origins`); {} for a scenario of built-ins only."""
    if not hasattr(scenario, "controller"):
        return {}
    raw = getattr(scenario, "raw", {}) or {}
    baseline = getattr(scenario, "baseline", None)
    kinds = {"controller": scenario.controller.kind,
             "trajectory": getattr(getattr(scenario, "trajectory", None), "kind", None),
             "plant": getattr(getattr(scenario, "plant", None), "kind", None),
             "vessel": getattr(getattr(scenario, "vessel", None), "kind", None),
             "disturbance": (raw.get("disturbance") or {}).get("kind") if isinstance(raw.get("disturbance"), dict)
             else None,
             "manoeuvre": getattr(getattr(scenario, "manoeuvre", None), "kind", None)}
    out = origins(kinds)
    if baseline is not None and getattr(baseline, "enabled", False):
        out.update({f"baseline {k.split(' ', 1)[1]}": v for k, v in origins({"controller": baseline.kind}).items()})
    return out


def git_commit(root: Path = PROJECT_ROOT) -> tuple[str, bool | None]:
    """(commit hash, tree has uncommitted changes) of the project checkout, ("unknown", None) outside one."""
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=10).stdout.strip()
        if not commit:
            return "unknown", None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip() != ""
        return commit, dirty
    except (OSError, subprocess.SubprocessError):
        return "unknown", None




# --- the file side (runs in the worker process, or in-process with background=False) -----------



def _keep_freed_pages():
    """Let glibc's malloc keep the chunk-sized buffers it frees (mmap threshold 64 MB, trim at 256
    MB) instead of giving them back and page-faulting them in again for the next chunk: that was a
    third of the writer's CPU (sys time, 140 k page faults a 300 s run). Elsewhere: nothing."""
    try:
        import ctypes

        libc = ctypes.CDLL(None)
        libc.mallopt(-3, 64 << 20)      # M_MMAP_THRESHOLD
        libc.mallopt(-1, 256 << 20)     # M_TRIM_THRESHOLD
    except Exception:  # noqa: BLE001 - not glibc (musl, another OS): malloc as it is
        pass


def _worker_main(path, file_metadata, attachments, rows_per_chunk, compression_level, environment, commands, reply,
                 parent_pid, ring_name, ring_shape, free_slots):
    """The background writer: consume commands until "close" (or until the parent process is gone).

    A "rows" command names its block as ("slot", i, n): rows 0..n of slot i of the shared ring,
    handed back (``free_slots.release()``) once the command is done with it."""
    shelter_from_group_signals()   # a signal to the process group stops the run, not the file
    _keep_freed_pages()
    error = None
    log = None
    ring_shm = shared_memory.SharedMemory(name=ring_name)
    ring = np.ndarray(ring_shape, dtype=np.float64, buffer=ring_shm.buf)
    try:
        log = RunLogFile(path, file_metadata, attachments, rows_per_chunk, compression_level, environment)
    except OSError as exc:
        error = f"cannot write {path}: {exc.strerror or exc}"
    except BaseException:
        error = traceback.format_exc()
    while True:
        try:
            cmd = commands.get(timeout=1.0)
        except queue.Empty:
            if os.getppid() != parent_pid:          # parent gone without "close": finish what we have
                cmd = ("close",)
            else:
                continue
        slot = cmd[3][1] if cmd[0] == "rows" else None
        if error is None:
            try:
                if slot is not None:
                    _, _, m, width = cmd[3]
                    cmd = cmd[:3] + (ring[slot, :m * width].reshape(m, width),) + cmd[4:]
                log.handle(cmd)
            except OSError as exc:      # disk full, read-only: one line naming the file
                error = f"cannot write {path}: {exc.strerror or exc}; the log holds what was written before"
            except BaseException:
                error = traceback.format_exc()
        if slot is not None:
            cmd = None                  # no view of the slot outlives its release
            free_slots.release()
            continue
        if cmd[0] == "close":
            del ring
            try:
                ring_shm.close()
            except BufferError:         # a view still alive: the mapping goes with the process
                pass
            if log is not None and not log.mcap.finished:
                try:
                    log.mcap.finish()       # leave a valid file with everything written before the error
                except BaseException:
                    log.mcap.abandon()
            stats = {"cpu_s": time.process_time(), "chunks": log.mcap.stats.chunk_count if log else 0,
                     "messages": log.mcap.stats.message_count if log else 0}
            try:
                reply.send(("error", error, stats) if error else ("ok", None, stats))
            except (OSError, EOFError):
                pass
            # the file is closed and the parent has its answer: skip the interpreter's teardown
            # (about 0.25 s of unloading numba and numpy that the parent's close() would wait for)
            reply.close()
            for stream in (sys.stdout, sys.stderr):
                if stream is not None:
                    stream.flush()
            os._exit(0)


# --- the simulation side ------------------------------------------------------------------------


class RunLogWriter:
    """One ``.mcap`` run log. A context manager; :meth:`sink` gives the RunSink of one run.

    ``path``: the file to write (its folder must exist); ``scenario``: the
    :class:`~usv_mj.scenario.spec.Scenario` being run (the file's metadata and the scenario file);
    ``attachments``: extra files to carry, name -> bytes or text. ``background=False`` writes in the
    calling process (same file, slower loop). ``rows_per_chunk`` bounds a chunk (~0.7 kB per row
    before compression); ``compression_level``: zstd's level for the chunks (default -3, a fast
    level: on these binary rows it takes half the CPU of level 1 for a file 5 % larger);
    ``queue_blocks`` bounds the blocks waiting for the background writer.
    ``environment``: an :class:`usv_mj.physics.sea.Environment` to log on ``P/environment`` instead of
    each run's own (``record.statics.environment``, the sea its plant saw: the writer builds none;
    a calm sea or a record without statics writes no environment topic). The drawn reference path
    is ``record.statics.reference`` sampled every 0.5 s. An obstacle run gets ``P/obstacles`` from
    its :class:`~usv_mj.obstacles.sink.ObstacleLog` (``record.statics.obstacle_log``, or one attached
    with :meth:`RunLogSink.attach_obstacle_log`) and ``P/scene/obstacles`` whenever it has obstacles.
    ``companion_of``: the writer of the main run's file when this one holds another run of the
    same job (the main job's ``baseline.mcap`` beside ``run.mcap``): one file per run keeps each
    file in log-time order, and :func:`usv_mj.outputs.log.read_run` of the main file finds this one.
    ``live``: a :class:`usv_mj.outputs.log.live.LiveServer` that serves every chunk's messages to
    Foxglove as the chunk is written (the file is then written in this process).
    """

    def __init__(self, path, scenario, attachments: dict | None = None, *, background: bool = True,
                 rows_per_chunk: int = 2000, compression_level: int = -3, queue_blocks: int = 32,
                 environment=None, companion_of: "RunLogWriter | None" = None, live=None):
        self.path = Path(path)
        self.log_id = uuid.uuid4().hex
        if not self.path.parent.is_dir():
            raise RunLogError(f"cannot write run log {self.path}: folder {self.path.parent} does not exist")
        self.scenario = scenario
        self._errors: list[str] = []
        self._sinks: list[RunLogSink] = []
        self._closed = False
        self.failed = False       # after close: writing failed (the file ends at its last complete chunk)
        self.stats: dict = {}     # after close: the writer's CPU time (background), chunks, messages
        commit, dirty = git_commit()
        to_dict = scenario.to_dict() if hasattr(scenario, "to_dict") else {}
        file_metadata = {
            "schema_version": SCHEMA_VERSION, "preset": str(getattr(scenario, "preset", "")),
            "source": str(getattr(scenario, "source", "")), "scenario": json_text(to_dict),
            "versions": json_text(package_versions()), "usv_mj_version": __version__,
            "plugins": json_text(plugins_of(scenario)),
            **({"git_commit": commit, "git_dirty": json_text(dirty)} if commit != "unknown" else
               {"install": "an installed package, not a git checkout (usv_mj_version names it)"}),
            "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "topics": "see usv_mj.outputs.log.topics: /usv/... (run main), /baseline/usv/... (run baseline)",
            "log_id": self.log_id,
        }
        if companion_of is not None:
            # read_run(companion_of's file) finds this file beside it and adds its runs
            file_metadata["companion_of"] = json_text({"file": companion_of.path.name, "log_id": companion_of.log_id})
        att = []
        for f in model_files():
            att.append((f"models/{f.name}", "application/xml", f.read_bytes()))
        source = str(getattr(scenario, "source", "") or "")
        if source and Path(source).is_file():
            att.append((f"scenario/{Path(source).name}", "application/toml", Path(source).read_bytes()))
        for name, data in (attachments or {}).items():
            if isinstance(data, str):
                data = data.encode()
            if not isinstance(data, (bytes, bytearray)):
                raise TypeError(f"attachment {name!r} must be bytes or str, got {type(data).__name__}")
            att.append((str(name), mimetypes.guess_type(str(name))[0] or "application/octet-stream", bytes(data)))
        args = (str(self.path), file_metadata, att, rows_per_chunk, compression_level, environment)
        if live is not None:   # a usv_mj.outputs.log.live.LiveServer: written here, its chunks served as they are
            background = False
        slots = max(1, int(queue_blocks))
        shape = (slots, SLOT_FLOATS)     # each run views a slot as (SLOT_FLOATS // its width, its width)
        if background:
            start_resource_tracker()    # before the ring registers with it: it outlives a hang-up
            try:
                self._ring_shm = shared_memory.SharedMemory(create=True, size=int(np.prod(shape)) * 8)
            except OSError as exc:      # e.g. a container with a tiny /dev/shm: same file, slower loop
                warnings.warn(f"run log {self.path}: no shared memory for the background writer "
                              f"({np.prod(shape) * 8 / 1e6:.0f} MB: {exc}); writing in this process",
                              RuntimeWarning, stacklevel=2)
                background = False
        self._background = background
        if background:
            ctx = spawn_context()  # the writer never imports the user's __main__ (usv_mj.support.spawning)
            self._ring = np.ndarray(shape, dtype=np.float64, buffer=self._ring_shm.buf)
            self._next_slot = 0
            self._free_slots = ctx.Semaphore(slots)
            self._queue = ctx.Queue()   # commands only (blocks go through the ring): bounded by the slots
            self._reply, child_reply = ctx.Pipe(duplex=False)
            self._proc = ctx.Process(target=_worker_main, args=(*args, self._queue, child_reply, os.getpid(),
                                                                self._ring_shm.name, shape, self._free_slots),
                                     name="usv_mj-runlog", daemon=True)
            start_sheltered(self._proc)     # no signal to the process group reaches it (module docstring)
            child_reply.close()
            # a writer never closed (no with-block) is closed at interpreter exit, before
            # multiprocessing ends its children (atexit runs the later registration first)
            atexit.register(_close_at_exit, weakref.ref(self))
        else:
            self._file = RunLogFile(*args)
            self._live = live
            self._unserved: list = []      # chunks written to the file, not yet served live
            if live is not None:           # served after each command is in the file (_serve_live)
                self._file.mcap.tee = self
                live.attach(self._file.mcap)   # a fleet's files: every one's channels before the first wait

    # commands
    def _send(self, cmd: tuple, serve: bool = True):
        """Hand ``cmd`` to the writer. In this process (``background=False``, ``--live``) the file's
        part is done whole with the group's signals blocked (a Ctrl-C never cuts a chunk out of
        the file), then, with ``serve``, the chunks are served live (where a Ctrl-C may land:
        the file already holds them)."""
        if self._closed:
            raise RunLogError(f"run log {self.path} is closed")
        if not self._background:
            with group_signals_blocked():
                self._file.handle(cmd)
            if serve:
                self._serve_live()
            return
        while True:
            try:
                self._queue.put(cmd, timeout=0.5)
                return
            except queue.Full:
                if not self._proc.is_alive():
                    raise RunLogError(f"the background writer of {self.path} stopped (exit code "
                                      f"{self._proc.exitcode})") from None

    def chunk(self, mcap, parts) -> None:
        """The file's tee (``--live``): a chunk just written, kept to be served by :meth:`_serve_live`."""
        self._unserved.append((mcap, parts))

    def _serve_live(self) -> None:
        """Serve the chunks the file holds and the viewers do not have yet (``--live``): the first
        one after the first run's channels are in the file (in every file of a fleet) waits for a viewer
        (:meth:`usv_mj.outputs.log.live.LiveServer.ready`). A signal here stops the run, not the
        file; the chunks not served yet are served with the next command."""
        if self._background or self._live is None:
            return
        self._live.ready(self._file.mcap)
        while self._unserved:
            mcap, parts = self._unserved[0]
            self._unserved.pop(0)
            self._live.chunk(mcap, parts)

    def _send_rows(self, run: str, lo: int, block: np.ndarray, events: list, obstacles):
        """Send rows lo.. of ``block`` (the record's own array: copied here) through the ring; in
        this process, into the file (the caller serves them live: :meth:`_serve_live`)."""
        if not self._background:
            self._send(("rows", run, lo, np.array(block, dtype=np.float64, copy=True), events, obstacles),
                       serve=False)
            return
        n, width = block.shape
        per_slot = SLOT_FLOATS // width
        if per_slot < 1:
            raise RunLogError(f"run {run!r}: a row of {width} columns does not fit a ring slot of {SLOT_FLOATS}")
        for a in range(0, n, per_slot):
            m = min(per_slot, n - a)
            while not self._free_slots.acquire(timeout=0.5):
                if not self._proc.is_alive():
                    raise RunLogError(f"the background writer of {self.path} stopped (exit code "
                                      f"{self._proc.exitcode})")
            slot = self._next_slot
            self._next_slot = (slot + 1) % self._ring.shape[0]
            self._ring[slot, :m * width].reshape(m, width)[:] = block[a:a + m]
            last = a + per_slot >= n
            self._send(("rows", run, lo + a, ("slot", slot, m, width), events if last else [],
                        None if obstacles is None else obstacles[a:a + m]))

    def sink(self, run: str = "main", log_every: int = 1) -> "RunLogSink":
        """The RunSink (start/rows/finish) that logs one simulated run under the run's topic prefix;
        ``log_every`` n: only every n-th control step (rows k = 0, n, 2n, ...: the log reads back as
        a run of control period n dt; the events and the summary are the full run's)."""
        prefix_for(run)  # validates the name
        if any(s.run == run for s in self._sinks):
            raise RunLogError(f"run {run!r} already has a sink in {self.path}")
        if not (isinstance(log_every, int) and log_every >= 1):
            raise ValueError(f"run log sink: log_every must be an integer >= 1, got {log_every!r}")
        s = RunLogSink(self, run, log_every)
        self._sinks.append(s)
        return s

    def close(self):
        """Finish every run still open, write the summary and footer; raise if writing failed."""
        if self._closed:
            return
        for s in self._sinks:
            if s.started and not s.finished and not s.broken:
                try:
                    s._end(None, "the sink was not finished (the run did not call finish())")
                except RunLogError as exc:
                    self._errors.append(str(exc))
        self._closed = True
        error = None
        if self._background:
            try:
                self._queue.put(("close",), timeout=5.0)
            except queue.Full:
                pass
            status = None
            while status is None:
                if self._reply.poll(0.5):
                    try:
                        status = self._reply.recv()
                    except EOFError:
                        status = ("error", None, {})
                elif not self._proc.is_alive():
                    status = ("error", None, {})
            self._proc.join(timeout=30)
            if status[0] == "error" and status[1] is None:      # it died: say how, and what the file holds
                code = self._proc.exitcode
                how = f"killed by {signal_name(-code)}" if code is not None and code < 0 else f"exit code {code}"
                status = ("error", f"{self.path}: the background log writer died ({how}) before the run ended; "
                                   "the log holds the rows up to its last complete chunk", {})
            # the worker is gone: anything still buffered for it can never be read, so do not wait
            # for the queue's feeder thread to deliver it (that would hang when the worker died)
            self._queue.cancel_join_thread()
            self._queue.close()
            self._ring = None
            self._ring_shm.close()
            self._ring_shm.unlink()
            self.stats = dict(status[2])
            if status[0] == "error":
                error = status[1]
        else:
            try:
                self._file.mcap.finish()
                self.stats = {"chunks": self._file.mcap.stats.chunk_count, "messages": self._file.mcap.stats.message_count}
            except Exception:
                error = traceback.format_exc()
        problems = self._errors + ([error] if error else [])
        self.failed = bool(problems)
        if problems:
            if len(problems) == 1 and "\n" not in problems[0].strip():
                raise RunLogError(problems[0])      # one line (a fault such as a full disk)
            raise RunLogError(f"writing run log {self.path} failed:\n" + "\n".join(problems))

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            self.close()
        except RunLogError:
            if exc_type is None:
                raise
            warnings.warn(f"run log {self.path}: writer failed too", RuntimeWarning, stacklevel=2)
        return False


def signal_name(number: int) -> str:
    """SIGKILL for 9 (``signal <n>`` for a number the platform does not name)."""
    import signal

    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _close_at_exit(ref):
    writer = ref()
    if writer is not None and not writer._closed:
        try:
            writer.close()
        except Exception as exc:  # noqa: BLE001 - at exit, say it and go on
            print(f"usv_mj.outputs.log: closing {writer.path} at exit failed: {exc}", file=sys.stderr)


def log_every(rate_hz, control_period: float, where: str = "--log-rate") -> int:
    """The n of ``RunLogWriter.sink(log_every=n)`` that logs at ``rate_hz`` [Hz] a run of control
    period ``control_period`` [s]: round(1 / (rate_hz dt)), at least 1 (None: every step). The rate
    must divide the control rate (1 kHz: 500, 100, 10, 1 Hz, ...); ScenarioError otherwise."""
    from usv_mj.core.errors import ScenarioError

    if rate_hz is None:
        return 1
    rate = float(rate_hz)
    full = 1.0 / control_period
    if not (math.isfinite(rate) and 0 < rate <= full * (1 + 1e-9)):
        raise ScenarioError(f"{where} {rate_hz!r}: the log rate must be in (0, {full:g}] Hz (the control rate)")
    n = max(1, int(round(full / rate)))
    if abs(n * rate - full) > 1e-6 * full:
        raise ScenarioError(f"{where} {rate_hz!r}: the log rate must divide the control rate {full:g} Hz "
                            f"(every n-th step: {full / max(1, n):g} or {full / (n + 1):g} Hz)")
    return n


class RunLogSink:
    """The :class:`~usv_mj.loop.simulate.RunSink` of one run in a :class:`RunLogWriter`."""

    def __init__(self, writer: RunLogWriter, run: str, log_every: int = 1):
        self.writer = writer
        self.run = run
        self.log_every = log_every
        self._logged = 0          # rows written to the log (every log_every-th record row)
        self.started = False
        self.finished = False
        self._written: set[int] = set()
        self._seq = 0
        self._record: RunRecord | None = None
        self._rows = 0
        self.broken = False       # the writer failed; rows are no longer sent
        self.obstacle_log = None  # an ObstacleLog whose per-step arrays go to P/obstacles

    def attach_obstacle_log(self, log) -> None:
        """Log ``log``'s clearance, normal force and centres on ``P/obstacles`` (call before ``start``;
        the ObstacleLog must be a sink placed before this one, so its rows are filled first)."""
        if self.started:
            raise RunLogError(f"run {self.run!r}: attach the obstacle log before the run starts")
        self.obstacle_log = log

    def _new_events(self, record) -> list:
        out = []
        for e in record.events:
            if id(e) not in self._written:
                self._written.add(id(e))
                out.append({"t": float(e.t), "seq": self._seq, "kind": str(e.kind), "message": str(e.message),
                            "values": dict(e.values)})
                self._seq += 1
        return out

    def start(self, record: RunRecord) -> None:
        if self.started:
            raise RunLogError(f"run {self.run!r} was started twice")
        self.started = True
        self._record = record
        dt = record.metadata.get("control_period_s", getattr(self.writer.scenario, "control_period", 0.001))
        dt = dt * self.log_every
        metadata = self._metadata(record)
        # what the run's outputs need comes from the build (record.statics): nothing is rebuilt here
        statics = getattr(record, "statics", None)
        if self.obstacle_log is None and statics is not None:
            self.obstacle_log = getattr(statics, "obstacle_log", None)
        log = self.obstacle_log
        if log is not None:
            obstacles = tuple(log.obstacles)
        elif statics is not None:
            obstacles = tuple(getattr(statics, "obstacles", ()) or ())
        else:
            obstacles = tuple(getattr(self.writer.scenario, "obstacles", ()) or ())
        inflation = None if log is None or log.inflation is None else [float(v) for v in log.inflation]
        duration = record.metadata.get("duration_s", getattr(self.writer.scenario, "duration", None))
        path = reference_path(getattr(statics, "reference", None), duration) if statics is not None else []
        self.writer._send(("start", self.run, {
            "control_period_s": float(dt), "metadata": metadata, "columns": tuple(record.column_names),
            "diagnostic_events": dict(getattr(record, "diagnostic_events", {}) or {}),
            "environment": getattr(statics, "environment", None), "path": path, "obstacles": obstacles,
            "inflation": inflation, "obstacle_log": log is not None}))

    def _metadata(self, record) -> dict:
        """The record's metadata as the log states it: with ``log_every`` n > 1 the log holds rows
        k = 0, n, 2n, ...: a run of control period n dt (``simulated_control_period_s``: dt)."""
        if self.log_every == 1 or "control_period_s" not in record.metadata:
            return record.metadata
        dt = record.metadata["control_period_s"]
        return {**record.metadata, "control_period_s": dt * self.log_every, "log_every": self.log_every,
                "simulated_control_period_s": dt}

    def scene(self, xml: str) -> None:
        """Attach ``scene/<run>.xml``: the MJCF scene the plant ran (MuJoCoPlant.scene_xml)."""
        self.writer._send(("attach", f"scene/{self.run}.xml", "application/xml", xml.encode()))

    def rows(self, record: RunRecord, lo: int, hi: int) -> None:
        # the rows counted (the end record's "rows") are the rows handed to the file: the group's
        # signals wait while both happen, so a Ctrl-C or SIGTERM never separates them (issue 38)
        with group_signals_blocked():
            self._take(record, lo, hi)
        self.writer._serve_live()

    def _take(self, record: RunRecord, lo: int, hi: int) -> None:
        if lo < self._rows:  # rows it already has: the loop resends a block that an interrupt cut
            lo = min(self._rows, hi)  # after this sink took it (simulation._Flusher)
        if hi <= lo:
            return
        if lo != self._rows:
            raise RunLogError(f"run {self.run!r}: rows {lo}..{hi} do not follow row {self._rows}")
        block = record.block(lo, hi)
        n = self.log_every
        pick = slice(None)
        if n > 1:   # the rows k = 0 (mod n) of [lo, hi); events wait for a block with a logged row
            pick = slice((-lo) % n, None, n)
            block = block[pick]
            if block.shape[0] == 0:
                self._rows = hi
                return
        events = self._new_events(record)
        self._rows = hi
        first, self._logged = self._logged, self._logged + block.shape[0]
        if self.broken:
            return
        try:
            obs = None
            if self.obstacle_log is not None:
                from usv_mj.outputs.log.extra_topics import obstacle_block

                log = self.obstacle_log
                m = len(log.obstacles)
                clear, force = np.full((hi - lo, m), np.nan), np.full((hi - lo, m), np.nan)
                xy = np.full((hi - lo, m, 2), np.nan)
                have = max(0, min(hi, len(log.clearance)) - lo)   # rows past the log's horizon: NaN
                clear[:have], force[:have], xy[:have] = (log.clearance[lo:lo + have], log.normal_force[lo:lo + have],
                                                         log.obstacle_xy[lo:lo + have])
                obs = obstacle_block(block[:, COL["t"]], clear[pick], force[pick], xy[pick])
            self.writer._send_rows(self.run, first, block, events, obs)
        except RunLogError as exc:
            # the log is lost from here on, the run is not: keep simulating, fail at close()
            self.broken = True
            self.writer._errors.append(f"run {self.run!r}: rows from {lo} on were not logged: {exc}")
            warnings.warn(f"run log {self.writer.path}: {exc}; the run goes on without its log",
                          RuntimeWarning, stacklevel=2)

    def finish(self, record: RunRecord) -> None:
        """Write the rows not yet sent, the remaining events and the end record. Never raises."""
        try:
            if record.n_rows > self._rows:
                self.rows(record, self._rows, record.n_rows)
            if self.broken:
                self.finished = True
                return
            self._end(record, None)
        except BaseException as exc:  # noqa: BLE001 - a finish must not hide the run's own exception
            self.writer._errors.append(f"run {self.run!r}: finish failed: {type(exc).__name__}: {exc}")
            self.finished = True

    def _end(self, record, note):
        self.finished = True
        record = record if record is not None else self._record
        status = record.status if record is not None else "unknown"
        stop_reason = record.stop_reason if record is not None else ""
        if note:
            stop_reason = f"{stop_reason}; {note}" if stop_reason else note
            if status in ("running", "unknown"):
                status = "interrupted"
        summary = {}
        if record is not None and record.n_rows > 0:
            try:
                from usv_mj.record.summary import summarize

                with np.errstate(all="ignore"):
                    summary = summarize(record)
            except Exception as exc:  # noqa: BLE001
                summary = {"error": f"summarize failed: {type(exc).__name__}: {exc}"}
        events = self._new_events(record) if record is not None else []
        self.writer._send(("finish", self.run, {
            "status": status, "stop_reason": stop_reason, "rows": self._logged,
            "metadata": json_text(self._metadata(record) if record is not None else {}), "summary": json_text(summary)}, events))
