"""The message side of a run log: :class:`RunLogFile` turns the sink's commands into MCAP records
(protobuf rows per step, JSON for the Foxglove frames, scenes and events), in the writer's
background process or in-process (:mod:`usv_mj.outputs.log.writer`, the process and queue side, sends
it the commands). The layouts and the topics are those of :mod:`usv_mj.outputs.log.topics` and
:mod:`usv_mj.outputs.log.extra_topics`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from usv_mj.record.run_record import COL, COLUMNS
from usv_mj.outputs.log import json_codec
from usv_mj.outputs.log.mcap_file import ChunkBuffer, McapFileWriter, TemplateLayout, template_layout
from usv_mj.outputs.log.protobuf_rows import BinaryRows, FixedLayout, message_class
from usv_mj.outputs.log.extra_topics import (ENVIRONMENT_SCHEMA, ENVIRONMENT_SCHEMA_NAME, OBSTACLES_SCHEMA, OBSTACLES_SCHEMA_NAME,
                           environment_block, environment_layout, obstacle_layout)
from usv_mj.outputs.log.topics import (EVENT_SCHEMA, FRAME_PERIOD, FRAME_TRANSFORM_SCHEMA, HULL_SIZE, PATH_SAMPLE,
                     SCENE_UPDATE_SCHEMA, SCHEMA_VERSION, SLOW_PERIOD, WORLD_FRAME, frame_for, prefix_for,
                     reference_frame_for, row_topic_schema, row_topics)


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


def json_text(obj) -> str:
    """Metadata JSON text; +-inf (an unlimited actuator's limit) as 1e999 / -1e999, as in the
    Foxglove topics, so that ``json.loads`` gives the record's metadata back (NaN stays null)."""
    text = json_codec.dumps(_mark_inf(obj)).decode()
    if "\\u0000" in text:
        for mark, token in ((_POS_INF, "1e999"), (_NEG_INF, "-1e999")):
            text = text.replace(json_codec.dumps(mark).decode(), token)
    return text



# --- the file side (runs in the worker process, or in-process with background=False) -----------


class RunLogFile:
    """Turns the sink's commands into MCAP records. One instance per file."""

    def __init__(self, path: str, file_metadata: dict, attachments: list, rows_per_chunk: int,
                 compression_level: int, environment=None):
        self.environment = environment   # None: from each run's scenario (calm: no environment topic)
        self.mcap = McapFileWriter(path, profile="", library=f"usv_mj.outputs.log ({SCHEMA_VERSION})",
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
            "run": run, "prefix": p, "schema_version": SCHEMA_VERSION, "columns": json_text(list(columns)),
            "diagnostic_fields": json_text(list(columns[len(COL):])),
            "diagnostic_events": json_text(dict(info.get("diagnostic_events") or {})),
            "control_period_s": repr(dt), "metadata": json_text(info.get("metadata", {})),
            **({"obstacles": json_text(obstacle_table(info["obstacles"], info.get("inflation")))}
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
                from usv_mj.scene.display import scene_entities

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

