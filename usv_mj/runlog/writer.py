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

What is in the file (topics: :mod:`usv_mj.runlog.topics`):

- metadata ``usv_mj`` (at open): schema version, preset, every parameter (``scenario.to_dict()``),
  package versions (python, numpy, numba, mujoco, mcap, orjson, protobuf, zstandard, usv_mj), the
  project's git commit ("unknown" outside a checkout) and whether the tree had uncommitted changes;
- attachments: ``models/<name>.xml`` for every model XML of the project, ``scenario/<file>`` when
  ``scenario.source`` is a file, any ``attachments`` passed in, and ``scene/<run>.xml`` (at
  ``start``, a MuJoCo plant's run): the MJCF scene that plant ran (``MuJoCoPlant.scene_xml``);
- metadata ``run_start/<run>`` (at ``start``): topic prefix, the record's metadata, the columns;
- metadata ``run_end/<run>`` (at ``finish``): status, stop reason, rows, the record's final
  metadata and ``usv_mj.summary.summarize(record)`` (all JSON text).

An interrupted run (Ctrl-C, an exception, a divergence) still gets every row up to the stop, its
events (the loop records why it stopped) and a ``run_end`` record, because ``simulate`` always calls
``finish``; ``finish`` never raises (a failure of the writer is kept and raised by :meth:`close`,
so it cannot hide the run's own exception). The worker ignores SIGINT, so Ctrl-C in the terminal
does not kill the file with the run. A killed process leaves a file without summary that
:func:`usv_mj.runlog.read_run` still reads up to its last complete chunk.
"""

from __future__ import annotations

import atexit
import math
import mimetypes
import os
import platform
import queue
import signal
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

from ..record import COL, COLUMNS, RunRecord
from ..assets import model_files
from . import json_codec
from .mcap_file import ChunkBuffer, McapFileWriter, TemplateLayout, template_layout
from .protobuf_rows import BinaryRows, FixedLayout, message_class
from .extra_topics import (ENVIRONMENT_SCHEMA, ENVIRONMENT_SCHEMA_NAME, OBSTACLES_SCHEMA, OBSTACLES_SCHEMA_NAME,
                           environment_block, environment_layout, obstacle_layout)
from .topics import (EVENT_SCHEMA, FRAME_PERIOD, FRAME_TRANSFORM_SCHEMA, HULL_SIZE, PATH_SAMPLE,
                     SCENE_UPDATE_SCHEMA, SCHEMA_VERSION, SLOW_PERIOD, WORLD_FRAME, frame_for, prefix_for,
                     reference_frame_for, row_topic_schema, row_topics)

PROJECT_ROOT = Path(__file__).resolve().parents[2]
SLOT_ROWS = 2048       # rows per slot of the shared-memory ring at the PPC record's width
SLOT_FLOATS = SLOT_ROWS * len(COLUMNS)   # a slot's size in float64; a run of W columns puts SLOT_FLOATS // W rows in it


class RunLogError(RuntimeError):
    """The run log could not be written or read; the message says which file and why."""


_POS_INF, _NEG_INF = "\x00+inf\x00", "\x00-inf\x00"


def _mark_inf(obj):
    if isinstance(obj, dict):
        return {k: _mark_inf(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_mark_inf(v) for v in obj]
    if isinstance(obj, (float, np.floating)) and math.isinf(obj):
        return _POS_INF if obj > 0 else _NEG_INF
    return obj


def _json(obj) -> str:
    """Metadata JSON text; +-inf (an unlimited actuator's limit) as 1e999 / -1e999, as in the
    Foxglove topics, so that ``json.loads`` gives the record's metadata back (NaN stays null)."""
    text = json_codec.dumps(_mark_inf(obj)).decode()
    if "\\u0000" in text:
        for mark, token in ((_POS_INF, "1e999"), (_NEG_INF, "-1e999")):
            text = text.replace(json_codec.dumps(mark).decode(), token)
    return text


def package_versions() -> dict:
    """Versions of the packages a run depends on ("not installed" when absent)."""
    out = {"python": platform.python_version()}
    for name in ("usv_mj", "numpy", "numba", "mujoco", "dm-control", "mcap", "orjson", "protobuf", "zstandard"):
        try:
            out[name] = importlib_metadata.version(name)
        except importlib_metadata.PackageNotFoundError:
            out[name] = "not installed"
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


class RunLogFile:
    """Turns the sink's commands into MCAP records. One instance per file."""

    def __init__(self, path: str, file_metadata: dict, attachments: list, rows_per_chunk: int,
                 compression_level: int, environment=None):
        self.environment = environment   # None: from each run's scenario (calm: no environment topic)
        self.mcap = McapFileWriter(path, profile="", library=f"usv_mj.runlog ({SCHEMA_VERSION})",
                                   compression_level=compression_level)
        self.rows_per_chunk = max(1, int(rows_per_chunk))
        self.mcap.add_metadata("usv_mj", file_metadata)
        for name, media_type, data in attachments:
            self.mcap.add_attachment(name, media_type, data, log_time=0, create_time=time.time_ns())
        self.schema_ids: dict[tuple, int] = {}
        self.runs: dict[str, dict] = {}

    def _schema(self, name: str, data: bytes, encoding: str = "jsonschema") -> int:
        # keyed by the data too: two controllers' usv_mj.Diagnostics differ (one file may hold both)
        if (name, data) not in self.schema_ids:
            self.schema_ids[(name, data)] = self.mcap.register_schema(name, encoding, data)
        return self.schema_ids[(name, data)]

    def handle(self, cmd: tuple):
        getattr(self, "cmd_" + cmd[0])(*cmd[1:])

    def cmd_start(self, run: str, info: dict):
        if run in self.runs:
            raise RunLogError(f"run {run!r} is logged twice in one file")
        p = prefix_for(run)
        columns = tuple(info.get("columns") or COLUMNS)
        controller = str((info.get("metadata") or {}).get("controller", "?"))
        chans = {}
        rows = []
        topics = row_topics(columns)
        col = {c: i for i, c in enumerate(columns)}
        for name, title, fields in topics:
            desc = (f"the declared diagnostics of controller {controller!r}, one control step"
                    if name == "diagnostics" else "")
            schema = row_topic_schema(title, fields, desc)
            cid = self.mcap.register_channel(f"{p}/{name}", "protobuf", self._schema(title, schema, "protobuf"),
                                             {"run": run, "kind": "rows"})
            rows.append((cid, FixedLayout(message_class(schema, title)), [col[f] for f in fields]))   # same order
        funnel = any(name == "errors" for name, _, _ in topics)
        chans["events"] = self.mcap.register_channel(f"{p}/events", "json", self._schema("usv_mj.Event", EVENT_SCHEMA),
                                                     {"run": run})
        for key, topic, schema, data in (("tf_hull", "tf/hull", "foxglove.FrameTransform", FRAME_TRANSFORM_SCHEMA),
                                         ("tf_ref", "tf/reference", "foxglove.FrameTransform", FRAME_TRANSFORM_SCHEMA),
                                         ("funnel", "scene/funnel", "foxglove.SceneUpdate", SCENE_UPDATE_SCHEMA),
                                         ("path", "scene/path", "foxglove.SceneUpdate", SCENE_UPDATE_SCHEMA),
                                         ("hull", "scene/hull", "foxglove.SceneUpdate", SCENE_UPDATE_SCHEMA)):
            if key == "funnel" and not funnel:
                continue
            chans[key] = self.mcap.register_channel(f"{p}/{topic}", "json", self._schema(schema, data), {"run": run})
        extra = self._extra_topics(run, p, info, rows, len(columns))
        extra.update(tf_hull=frame_layout(chans["tf_hull"], frame_for(run)),
                     tf_ref=frame_layout(chans["tf_ref"], reference_frame_for(run)),
                     funnel=funnel_layout(chans["funnel"]) if funnel else None)
        dt = float(info["control_period_s"])
        self.runs[run] = {**extra,
            "layout": BinaryRows(rows), "chans": chans, "dt": dt, "width": len(columns), "col": col,
            "decim": max(1, int(round(FRAME_PERIOD / dt))), "slow": max(1, int(round(SLOW_PERIOD / dt))),
            "frame": frame_for(run), "path": list(info.get("path") or ()), "rows": 0,
            "last_ns": 0, "ended": False,
        }
        self.mcap.add_metadata(f"run_start/{run}", {
            "run": run, "prefix": p, "schema_version": SCHEMA_VERSION, "columns": _json(list(columns)),
            "diagnostic_fields": _json(list(columns[len(COL):])),
            "diagnostic_events": _json(dict(info.get("diagnostic_events") or {})),
            "control_period_s": repr(dt), "metadata": _json(info.get("metadata", {})),
            **({"obstacles": _json(obstacle_table(info["obstacles"], info.get("inflation")))}
               if info.get("obstacles") else {}),
        })

    def _extra_topics(self, run: str, p: str, info: dict, per_step: list, width: int) -> dict:
        """Channels of P/obstacles, P/scene/obstacles and P/environment (extra_topics); the per-step
        ones are appended to ``per_step`` (channel, layout, columns), their values in the columns
        after the record's ``width``: the obstacles' (extra_topics.obstacle_block), then the sea's."""
        out = {"obstacles": tuple(info.get("obstacles") or ()), "inflation": info.get("inflation"),
               "obs_values": 0, "env": None, "obs_scene": None}
        if out["obstacles"]:
            out["obs_scene"] = self.mcap.register_channel(f"{p}/scene/obstacles", "json",
                                                          self._schema("foxglove.SceneUpdate", SCENE_UPDATE_SCHEMA),
                                                          {"run": run})
            out["any_moving"] = any(o.moving for o in out["obstacles"])
            if info.get("obstacle_log"):
                cid = self.mcap.register_channel(f"{p}/obstacles", "protobuf",
                                                 self._schema(OBSTACLES_SCHEMA_NAME, OBSTACLES_SCHEMA, "protobuf"),
                                                 {"run": run})
                layout = obstacle_layout([o.name for o in out["obstacles"]])
                per_step.append((cid, layout, range(width, width + len(layout.paths))))
                out["obs_values"] = len(layout.paths)
        env = self.environment if self.environment is not None else info.get("environment")
        if env is not None and not env.calm:
            out["env"] = env
            cid = self.mcap.register_channel(f"{p}/environment", "protobuf",
                                             self._schema(ENVIRONMENT_SCHEMA_NAME, ENVIRONMENT_SCHEMA, "protobuf"),
                                             {"run": run})
            layout = environment_layout()
            at = width + out["obs_values"]
            per_step.append((cid, layout, range(at, at + len(layout.paths))))
        return out

    def cmd_rows(self, run: str, lo: int, block: np.ndarray, events: list, obstacles: np.ndarray | None = None):
        st = self.runs[run]
        n = block.shape[0]
        step = self.rows_per_chunk
        t = block[:, COL["t"]]
        # log time = round(t * 1e9) ns; never before what this run already wrote (a row whose t is
        # not finite gets the time before it), so that the file is in log-time order
        raw = np.rint(np.nan_to_num(t, nan=0.0, posinf=0.0, neginf=0.0) * 1e9).clip(0).astype(np.int64)
        block_time = np.maximum.accumulate(np.maximum(raw, st["last_ns"]))
        events = sorted(events, key=lambda e: (e["t"], e["seq"]))
        for a in range(0, n, step):
            sub = block[a:a + step]
            buf = ChunkBuffer()
            log_time = block_time[a:a + step]
            values = sub
            if st["layout"].n_cols > st["width"]:     # the obstacles' and the sea's values after the record's
                values = np.full((sub.shape[0], st["layout"].n_cols), np.nan)
                values[:, :st["width"]] = sub
                if st["obs_values"] and obstacles is not None:   # (the sink hands them whenever it logs them)
                    values[:, st["width"]:st["width"] + st["obs_values"]] = obstacles[a:a + step]
                if st["env"] is not None:
                    values[:, st["width"] + st["obs_values"]:] = environment_block(st["env"], sub)
            records, offsets = st["layout"].encode(values, log_time, lo + a)
            buf.add_rows(records, offsets, log_time, st["layout"].channel_ids)
            self._foxglove(st, buf, sub, lo + a, log_time)
            # each event in the chunk of its time (the rest in the last one)
            if a + step >= n:
                here, events = events, []
            else:
                cut = int(block_time[a + step])
                here = [e for e in events if _ns(e["t"]) < cut]
                events = events[len(here):]
            self._events(st, buf, here, int(log_time[0]))
            self.mcap.write_chunk(buf)
            st["last_ns"] = max(st["last_ns"], int(buf.end_time if buf.end_time is not None else log_time[-1]))
        st["rows"] = lo + n

    def cmd_attach(self, name: str, media_type: str, data: bytes):
        self.mcap.add_attachment(name, media_type, data, log_time=0, create_time=time.time_ns())

    def cmd_finish(self, run: str, end: dict, events: list):
        st = self.runs[run]
        buf = ChunkBuffer()
        self._events(st, buf, events, st["last_ns"])
        t_end = max([st["last_ns"]] + [_ns(e["t"]) for e in events])
        buf.add_message(st["chans"]["events"], t_end, json_codec.dumps({
            "t": t_end / 1e9, "seq": -1, "kind": "run_end", "synthetic": True, "status": end["status"],
            "stop_reason": end["stop_reason"],
            "message": f"run {run} ended: {end['status']}" + (f" ({end['stop_reason']})" if end["stop_reason"] else ""),
            "values": {"rows": end["rows"]}}))
        self.mcap.write_chunk(buf)
        self.mcap.add_metadata(f"run_end/{run}", {
            "run": run, "status": end["status"], "stop_reason": end["stop_reason"], "rows": str(end["rows"]),
            "metadata": end["metadata"], "summary": end["summary"],
        })
        st["ended"] = True

    def cmd_close(self):
        self.mcap.finish()

    def _events(self, st, buf, events, floor: int = 0):
        """Event messages at log time round(t * 1e9), or at ``floor`` (the chunk's first row, or the
        run's last written time) for an event reported after later rows were written: the file stays
        in log-time order; the event's own ``t`` is in its message."""
        ch = st["chans"]["events"]
        floor = max(int(floor), st["last_ns"])
        for e in sorted(events, key=lambda e: (e["t"], e["seq"])):
            buf.add_message(ch, max(_ns(e["t"]), floor), json_codec.dumps(e), e["seq"])

    def _foxglove(self, st, buf, sub, k0, log_time):
        """Foxglove messages of the rows ``sub`` (record rows k0...): the hull and reference frames and
        the funnel every FRAME_PERIOD (laid out in bulk from templates), the path, hull shape and
        obstacles as single messages. Rows whose values are not finite get no message."""
        decim, slow, ch, c = st["decim"], st["slow"], st["chans"], st["col"]
        k = np.arange(k0, k0 + sub.shape[0])
        pick = np.flatnonzero(k % decim == 0)
        if pick.size:
            rows, ks, ns = sub[pick], k[pick], log_time[pick]
            x, y, psi = rows[:, c["x"]], rows[:, c["y"]], rows[:, c["psi"]]
            xd, yd, psid = rows[:, c["x_d"]], rows[:, c["y_d"]], rows[:, c["psi_d"]]
            zero = np.zeros_like(x)
            hull_ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(psi)
            ref_ok = np.isfinite(xd) & np.isfinite(yd) & np.isfinite(psid)
            with np.errstate(invalid="ignore"):
                todo = [(st["tf_hull"], hull_ok, (zero, zero, x, y, np.sin(psi / 2), np.cos(psi / 2))),
                        (st["tf_ref"], ref_ok, (zero, zero, xd, yd, np.sin(psid / 2), np.cos(psid / 2)))]
                if st["funnel"] is not None:
                    r1, r2 = rows[:, c["rho1"]], rows[:, c["rho2"]]
                    funnel_ok = ref_ok & np.isfinite(r1) & np.isfinite(r2)
                    todo.append((st["funnel"], funnel_ok, (zero, zero, xd - r1, yd - r2, xd + r1, yd - r2,
                                                           xd + r1, yd + r2, xd - r1, yd + r2)))
                for layout, ok, cols in todo:
                    if ok.any():
                        block = np.stack(cols, axis=1)[ok]
                        records, offsets = layout.encode(block, ns[ok], ks[ok])
                        buf.add_rows(records, offsets, ns[ok], layout.channel_ids)
        for i in pick:
            if not (k[i] % slow == 0 or (st["obs_scene"] is not None and st["any_moving"])):
                continue
            row = sub[i]
            ns = int(log_time[i])
            stamp = {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}
            if st["obs_scene"] is not None:
                from ..obstacles.display import scene_entities

                obstacles = st["obstacles"] if k[i] % slow == 0 else [o for o in st["obstacles"] if o.moving]
                infl = st["inflation"]
                if infl is not None and k[i] % slow != 0:
                    infl = [v for v, o in zip(infl, st["obstacles"]) if o.moving]
                buf.add_message(st["obs_scene"], ns, json_codec.dumps(
                    {"deletions": [], "entities": scene_entities(obstacles, float(row[c["t"]]), stamp, infl)}),
                    int(k[i]))
            if k[i] % slow == 0:
                if st["path"]:
                    buf.add_message(ch["path"], ns, _scene(stamp, WORLD_FRAME, "reference_path", lines=[
                        _line(0, st["path"], (0.2, 0.6, 1.0, 1.0), 0.05)]), int(k[i]))
                half = HULL_SIZE[2] / 2
                buf.add_message(ch["hull"], ns, _scene(stamp, st["frame"], "hull", frame_locked=True, cubes=[{
                    "pose": {"position": {"x": 0.0, "y": 0.0, "z": half},
                             "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                    "size": {"x": HULL_SIZE[0], "y": HULL_SIZE[1], "z": HULL_SIZE[2]},
                    "color": {"r": 0.9, "g": 0.9, "b": 0.95, "a": 1.0}}]), int(k[i]))


_STAMP_HOLES = {"sec": "$sec", "nsec": "$nsec"}


def frame_layout(channel_id: int, child: str) -> TemplateLayout:
    """``foxglove.FrameTransform`` world -> ``child`` in the plane; block columns: (sec, nsec: ignored),
    x, y [m], the quaternion's z = sin(psi/2) and w = cos(psi/2)."""
    return template_layout(channel_id, _frame(_STAMP_HOLES, child, "$x", "$y", "$qz", "$qw"),
                           ("$sec", "$nsec", "$x", "$y", "$qz", "$qw"))


def funnel_layout(channel_id: int) -> TemplateLayout:
    """``foxglove.SceneUpdate`` of the funnel rectangle (LINE_LOOP, world frame); block columns:
    (sec, nsec: ignored), then x, y of its 4 corners [m]."""
    holes = [(f"$x{i}", f"$y{i}") for i in range(4)]
    return template_layout(channel_id, _scene(_STAMP_HOLES, WORLD_FRAME, "funnel", lines=[
        _line(1, holes, (1.0, 0.55, 0.0, 1.0), 0.05)], encode=False),
        ("$sec", "$nsec") + tuple(h for pair in holes for h in pair))


def obstacle_table(obstacles, inflation=None) -> list:
    """The obstacles' fixed shapes for the run_start metadata (JSON-ready)."""
    out = []
    for i, o in enumerate(obstacles):
        infl = None
        if inflation is not None and i < len(inflation) and math.isfinite(float(inflation[i])):
            infl = float(inflation[i])
        out.append({"name": o.name, "kind": o.kind, "center": list(o.center), "radius": o.radius,
                    "size": list(o.size), "yaw": o.yaw, "velocity": list(o.velocity), "moving": o.moving,
                    "inflation_m": infl})
    return out


def reference_path(reference, duration: float) -> list:
    """The run's reference (``record.statics.reference``, a pure function of t) sampled every
    PATH_SAMPLE s over ``duration``: (x_d, y_d) points for the 3D view ([] if it cannot be sampled)."""
    if reference is None or not (duration is not None and math.isfinite(float(duration)) and duration >= 0):
        return []
    pts = []
    for t in np.arange(0.0, float(duration) + 1e-9, PATH_SAMPLE):
        try:
            p = reference.evaluate(float(t))
        except Exception:   # noqa: BLE001 - the path is decoration; never fail a run for it
            break
        x, y = float(p[0]), float(p[1])
        if math.isfinite(x) and math.isfinite(y):
            pts.append((x, y))
    return pts


def _ns(t) -> int:
    t = float(t)
    return int(round(t * 1e9)) if math.isfinite(t) and t > 0 else 0


def _frame(stamp, child, x, y, qz, qw) -> dict:
    return {"timestamp": stamp, "parent_frame_id": WORLD_FRAME, "child_frame_id": child,
            "translation": {"x": x, "y": y, "z": 0.0}, "rotation": {"x": 0.0, "y": 0.0, "z": qz, "w": qw}}


def _line(kind, pts, rgba, thickness):
    return {"type": kind, "pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
                                   "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
            "thickness": thickness, "scale_invariant": False,
            "points": [{"x": px, "y": py, "z": 0.0} for px, py in pts],
            "color": dict(zip("rgba", rgba)), "colors": [], "indices": []}


def _scene(stamp, frame_id, entity_id, frame_locked=False, lines=(), cubes=(), encode=True):
    entity = {"timestamp": stamp, "frame_id": frame_id, "id": entity_id, "lifetime": {"sec": 0, "nsec": 0},
              "frame_locked": frame_locked, "metadata": [], "arrows": [], "cubes": list(cubes), "spheres": [],
              "cylinders": [], "lines": list(lines), "triangles": [], "texts": [], "models": []}
    message = {"deletions": [], "entities": [entity]}
    return json_codec.dumps(message) if encode else message


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
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C stops the run, not the file
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
    :class:`~usv_mj.scenario.Scenario` being run (the file's metadata and the scenario file);
    ``attachments``: extra files to carry, name -> bytes or text. ``background=False`` writes in the
    calling process (same file, slower loop). ``rows_per_chunk`` bounds a chunk (~0.7 kB per row
    before compression); ``compression_level``: zstd's level for the chunks (default -3, a fast
    level: on these binary rows it takes half the CPU of level 1 for a file 5 % larger);
    ``queue_blocks`` bounds the blocks waiting for the background writer.
    ``environment``: an :class:`usv_mj.sea.Environment` to log on ``P/environment`` instead of
    each run's own (``record.statics.environment``, the sea its plant saw: the writer builds none;
    a calm sea or a record without statics writes no environment topic). The drawn reference path
    is ``record.statics.reference`` sampled every 0.5 s. An obstacle run gets ``P/obstacles`` from
    its :class:`~usv_mj.obstacles.sink.ObstacleLog` (``record.statics.obstacle_log``, or one attached
    with :meth:`RunLogSink.attach_obstacle_log`) and ``P/scene/obstacles`` whenever it has obstacles.
    ``companion_of``: the writer of the main run's file when this one holds another run of the
    same job (the main job's ``baseline.mcap`` beside ``run.mcap``): one file per run keeps each
    file in log-time order, and :func:`usv_mj.runlog.read_run` of the main file finds this one.
    ``live``: a :class:`usv_mj.runlog.live.LiveServer` that serves every chunk's messages to
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
        self.stats: dict = {}     # after close: the writer's CPU time (background), chunks, messages
        commit, dirty = git_commit()
        to_dict = scenario.to_dict() if hasattr(scenario, "to_dict") else {}
        file_metadata = {
            "schema_version": SCHEMA_VERSION, "preset": str(getattr(scenario, "preset", "")),
            "source": str(getattr(scenario, "source", "")), "scenario": _json(to_dict),
            "versions": _json(package_versions()), "git_commit": commit, "git_dirty": _json(dirty),
            "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "topics": "see usv_mj.runlog.topics: /usv/... (run main), /baseline/usv/... (run baseline)",
            "log_id": self.log_id,
        }
        if companion_of is not None:
            # read_run(companion_of's file) finds this file beside it and adds its runs
            file_metadata["companion_of"] = _json({"file": companion_of.path.name, "log_id": companion_of.log_id})
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
        if live is not None:   # a usv_mj.runlog.live.LiveServer: written here, its chunks served as they are
            background = False
        slots = max(1, int(queue_blocks))
        shape = (slots, SLOT_FLOATS)     # each run views a slot as (SLOT_FLOATS // its width, its width)
        if background:
            try:
                self._ring_shm = shared_memory.SharedMemory(create=True, size=int(np.prod(shape)) * 8)
            except OSError as exc:      # e.g. a container with a tiny /dev/shm: same file, slower loop
                warnings.warn(f"run log {self.path}: no shared memory for the background writer "
                              f"({np.prod(shape) * 8 / 1e6:.0f} MB: {exc}); writing in this process",
                              RuntimeWarning, stacklevel=2)
                background = False
        self._background = background
        if background:
            from usv_mj.spawning import spawn_context

            ctx = spawn_context()  # the writer never imports the user's __main__ (usv_mj.spawning)
            self._ring = np.ndarray(shape, dtype=np.float64, buffer=self._ring_shm.buf)
            self._next_slot = 0
            self._free_slots = ctx.Semaphore(slots)
            self._queue = ctx.Queue()   # commands only (blocks go through the ring): bounded by the slots
            self._reply, child_reply = ctx.Pipe(duplex=False)
            self._proc = ctx.Process(target=_worker_main, args=(*args, self._queue, child_reply, os.getpid(),
                                                                self._ring_shm.name, shape, self._free_slots),
                                     name="usv_mj-runlog", daemon=True)
            self._proc.start()
            child_reply.close()
            # a writer never closed (no with-block) is closed at interpreter exit, before
            # multiprocessing ends its children (atexit runs the later registration first)
            atexit.register(_close_at_exit, weakref.ref(self))
        else:
            self._file = RunLogFile(*args)
            self._file.mcap.tee = live

    # commands
    def _send(self, cmd: tuple):
        if self._closed:
            raise RunLogError(f"run log {self.path} is closed")
        if not self._background:
            self._file.handle(cmd)
            return
        while True:
            try:
                self._queue.put(cmd, timeout=0.5)
                return
            except queue.Full:
                if not self._proc.is_alive():
                    raise RunLogError(f"the background writer of {self.path} stopped (exit code "
                                      f"{self._proc.exitcode})") from None

    def _send_rows(self, run: str, lo: int, block: np.ndarray, events: list, obstacles):
        """Send rows lo.. of ``block`` (the record's own array: copied here) through the ring."""
        if not self._background:
            self._send(("rows", run, lo, np.array(block, dtype=np.float64, copy=True), events, obstacles))
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
                        status = ("error", "the background writer exited without a reply", {})
                elif not self._proc.is_alive():
                    status = ("error", f"the background writer exited with code {self._proc.exitcode}", {})
            self._proc.join(timeout=30)
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


def _close_at_exit(ref):
    writer = ref()
    if writer is not None and not writer._closed:
        try:
            writer.close()
        except Exception as exc:  # noqa: BLE001 - at exit, say it and go on
            print(f"usv_mj.runlog: closing {writer.path} at exit failed: {exc}", file=sys.stderr)


def log_every(rate_hz, control_period: float, where: str = "--log-rate") -> int:
    """The n of ``RunLogWriter.sink(log_every=n)`` that logs at ``rate_hz`` [Hz] a run of control
    period ``control_period`` [s]: round(1 / (rate_hz dt)), at least 1 (None: every step). The rate
    must divide the control rate (1 kHz: 500, 100, 10, 1 Hz, ...); ScenarioError otherwise."""
    from ..errors import ScenarioError

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
    """The :class:`~usv_mj.simulation.RunSink` of one run in a :class:`RunLogWriter`."""

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
                from .extra_topics import obstacle_block

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
                from ..summary import summarize

                with np.errstate(all="ignore"):
                    summary = summarize(record)
            except Exception as exc:  # noqa: BLE001
                summary = {"error": f"summarize failed: {type(exc).__name__}: {exc}"}
        events = self._new_events(record) if record is not None else []
        self.writer._send(("finish", self.run, {
            "status": status, "stop_reason": stop_reason, "rows": self._logged,
            "metadata": _json(self._metadata(record) if record is not None else {}), "summary": _json(summary)}, events))
