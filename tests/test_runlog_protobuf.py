"""The per-step topics' protobuf encoding (usv_mj.outputs.log.protobuf_rows) against the protobuf library itself,
and files written by other writers: the mcap project's protobuf writer (standard serialization, which
leaves default fields out) and a JSON-rows log of schema version 2 written with the mcap library's Writer.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.writer import Writer

from usv_mj.outputs.log import load_topic, read_run
from usv_mj.outputs.log.extra_topics import (ENVIRONMENT_SCHEMA, ENVIRONMENT_SCHEMA_NAME, OBSTACLES_SCHEMA,
                                        OBSTACLES_SCHEMA_NAME, environment_layout, obstacle_layout)
from usv_mj.outputs.log.protobuf_rows import BinaryRows, FixedLayout, decode_payloads, message_class
from usv_mj.outputs.log.topics import ROW_TOPICS, row_topic_schema


def _values(n, seed=3):
    return np.random.default_rng(seed).normal(size=n) * 10.0 ** np.arange(n) % 7 + 0.5   # nonzero, varied


@pytest.mark.parametrize("name,title,fields", ROW_TOPICS)
def test_row_layout_is_the_protobuf_librarys_own_serialization(name, title, fields):
    cls = message_class(row_topic_schema(title, fields), title)
    layout = FixedLayout(cls)
    assert layout.paths == fields
    vals = _values(len(fields))
    expected = cls(**dict(zip(fields, vals.tolist()))).SerializeToString(deterministic=True)
    assert layout.encode_one(vals) == expected
    back = cls.FromString(layout.encode_one(vals))
    assert [getattr(back, f) for f in fields] == vals.tolist()


def test_nested_and_repeated_layouts_are_the_librarys_serialization():
    env = environment_layout()
    vals = _values(len(env.paths))
    cls = message_class(ENVIRONMENT_SCHEMA, ENVIRONMENT_SCHEMA_NAME)
    msg = cls(t=vals[0], zeta=vals[1])
    for i, group in enumerate(("tau_wave", "tau_drift", "tau_wind")):
        for j, axis in enumerate("xyn"):
            setattr(getattr(msg, group), axis, vals[2 + 3 * i + j])
    msg.current.x, msg.current.y, msg.wind.speed, msg.wind.direction = vals[11:15]
    assert env.encode_one(vals) == msg.SerializeToString(deterministic=True)

    names = ["buoy", "pier-2", "ø"]
    obs = obstacle_layout(names)
    vals = _values(len(obs.paths))
    cls = message_class(OBSTACLES_SCHEMA, OBSTACLES_SCHEMA_NAME)
    msg = cls(t=vals[0])
    for i, name in enumerate(names):
        item = msg.obstacles.add(name=name, clearance_m=vals[1 + 4 * i], normal_force_N=vals[2 + 4 * i])
        item.center.x, item.center.y = vals[3 + 4 * i], vals[4 + 4 * i]
    assert obs.encode_one(vals) == msg.SerializeToString(deterministic=True)
    assert obs.strings == {f"obstacles.{i}.name": n for i, n in enumerate(names)}


def test_bulk_records_decode_by_the_library_and_back():
    """BinaryRows' MCAP records: header fields at their places, messages the library parses; and
    decode_payloads refuses a message that is not in the layout (so the reader parses it instead)."""
    name, title, fields = ROW_TOPICS[0]
    cls = message_class(row_topic_schema(title, fields), title)
    layout = FixedLayout(cls)
    block = np.random.default_rng(0).normal(size=(5, len(fields)))
    block[1, 2] = 0.0
    rows = BinaryRows([(7, layout, range(len(fields)))])
    lt = np.arange(5, dtype=np.int64) * 1000 + 17
    records, offsets = rows.encode(block, lt, 40)
    buf = records
    starts, ends = [], []
    for i in range(5):
        at = int(offsets[i, 0])
        head = buf[at:at + 31].tobytes()
        assert head[0] == 5 and int.from_bytes(head[9:11], "little") == 7
        assert int.from_bytes(head[11:15], "little") == 40 + i
        assert int.from_bytes(head[15:23], "little") == int.from_bytes(head[23:31], "little") == lt[i]
        length = int.from_bytes(head[1:9], "little")
        msg = cls.FromString(buf[at + 31:at + 9 + length].tobytes())
        assert [getattr(msg, f) for f in fields] == block[i].tolist()
        starts.append(at + 31)
        ends.append(at + 9 + length)
    starts, ends = np.array(starts), np.array(ends)
    assert np.array_equal(decode_payloads(buf, starts, ends, layout), block)
    spoiled = buf.copy()
    spoiled[starts[3]] ^= 0x08                 # field 1's tag becomes field 2's
    assert decode_payloads(spoiled, starts, ends, layout) is None


def test_a_file_from_the_mcap_protobuf_writer_reads(tmp_path):
    """Standard protobuf serialization leaves 0.0 fields out: the reader parses such messages one
    by one with the library (the default 0.0 comes back), not through the fixed layout."""
    from mcap_protobuf.writer import Writer as ProtobufWriter

    name, title, fields = ROW_TOPICS[0]
    cls = message_class(row_topic_schema(title, fields), title)
    path = tmp_path / "other.mcap"
    rows = np.random.default_rng(1).normal(size=(50, len(fields)))
    rows[:, 0] = np.arange(50) * 0.001
    rows[::7, 3] = 0.0
    with open(path, "wb") as f, ProtobufWriter(f) as writer:
        for row in rows:
            writer.write_message(f"/usv/{name}", cls(**dict(zip(fields, row.tolist()))),
                                 log_time=round(row[0] * 1e9))
    got = load_topic(path, "/usv/state")
    for i, f in enumerate(fields):
        assert np.array_equal(got[f], rows[:, i]), f
    rec = read_run(path).record
    assert np.array_equal(rec["psi"], rows[:, 3]) and rec.status == "truncated"


def test_a_version_2_log_with_json_rows_still_reads(tmp_path):
    path = tmp_path / "v2.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("usv_mj.State", "jsonschema", b"{}")
        cid = w.register_channel("/usv/state", "json", sid, {"run": "main", "kind": "rows"})
        xs = [1.5, 1e999, None, -0.25]
        for k, x in enumerate(xs):
            msg = {"t": k * 0.001, "x": x, "y": 2.0, "psi": 0.0, "u": 0.1, "v": 0.0, "r": 0.0}
            w.add_message(cid, log_time=k * 1_000_000, publish_time=k * 1_000_000, sequence=k,
                          data=json.dumps(msg).replace("Infinity", "1e999").encode())
        w.finish()
    rec = read_run(path).record
    assert np.array_equal(rec["x"], [1.5, np.inf, np.nan, -0.25], equal_nan=True)
    assert np.array_equal(rec["t"], np.arange(4) * 0.001)


def test_columns_that_are_not_protobuf_names_round_trip(tmp_path):
    """A controller may name its fields "speed gap" or "2nd-try": the protobuf fields are renamed
    (field_names) and the reader gives the record back under the declared names."""
    from usv_mj.record.run_record import RunRecord
    from usv_mj.outputs.log import RunLogWriter
    from usv_mj.outputs.log.protobuf_rows import field_names
    from usv_mj.scenario.spec import load_scenario

    assert field_names(["t", "speed gap", "2nd-try", "speed_gap", "ψ"]) == ["t", "speed_gap", "_2nd_try",
                                                                            "speed_gap_2", "_"]
    odd = ("speed gap", "2nd-try", "speed_gap")
    rec = RunRecord(5, metadata={"control_period_s": 0.001}, diagnostic_fields=odd)
    rec.data[:] = np.random.default_rng(2).normal(size=rec.data.shape)
    rec.data[:, 0] = np.arange(5) * 0.001
    path = tmp_path / "odd.mcap"
    with RunLogWriter(path, load_scenario(preset="paper"), background=False) as writer:
        sink = writer.sink("main")
        sink.start(rec)
        rec.n_rows = 5
        sink.rows(rec, 0, 5)
        sink.finish(rec)
    got = read_run(path).record
    assert got.diagnostic_fields == odd
    for name in odd:
        assert np.array_equal(got[name], rec[name]), name


def test_a_damaged_message_is_left_out_with_the_reason(tmp_path):
    """A message that the protobuf library cannot parse (its chunk CRC set to 0, so nothing else
    notices) is skipped and named in the log's problem; the reader does not raise."""
    from mcap.writer import CompressionType

    name, title, fields = ROW_TOPICS[0]
    schema = row_topic_schema(title, fields)
    path = tmp_path / "bad.mcap"
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.NONE, enable_crcs=False)
        w.start()
        sid = w.register_schema(title, "protobuf", schema)
        cid = w.register_channel("/usv/state", "protobuf", sid, {"kind": "rows"})
        layout = FixedLayout(message_class(schema, title))
        for k in range(3):
            data = layout.encode_one(np.full(len(fields), 1.0 + k)) if k != 1 else b"\x0a\xff\xff"
            w.add_message(cid, log_time=k, publish_time=k, data=data, sequence=k)
        w.finish()
    log = read_run(path)
    assert "/usv/state" in log.problem and "left out" in log.problem
    assert np.array_equal(log.record["x"], [1.0, 3.0])


def test_message_class_takes_a_descriptor_set_in_any_file_order():
    from google.protobuf import descriptor_pb2, timestamp_pb2

    dep = descriptor_pb2.FileDescriptorProto()
    timestamp_pb2.DESCRIPTOR.CopyToProto(dep)
    main = descriptor_pb2.FileDescriptorProto(name="stamped.proto", package="demo", syntax="proto3",
                                              dependency=[dep.name])
    msg = main.message_type.add(name="Stamped")
    msg.field.add(name="stamp", number=1, type=descriptor_pb2.FieldDescriptorProto.TYPE_MESSAGE,
                  type_name=".google.protobuf.Timestamp", label=descriptor_pb2.FieldDescriptorProto.LABEL_OPTIONAL)
    schema = descriptor_pb2.FileDescriptorSet(file=[main, dep]).SerializeToString()   # the user first
    cls = message_class(schema, "demo.Stamped")
    assert cls.FromString(cls(stamp={"seconds": 7}).SerializeToString()).stamp.seconds == 7


def test_chunk_index_is_in_time_order_whatever_order_the_rows_came_in():
    from usv_mj.outputs.log.mcap_file import ChunkBuffer

    name, title, fields = ROW_TOPICS[0]
    layout = FixedLayout(message_class(row_topic_schema(title, fields), title))
    rows = BinaryRows([(3, layout, range(len(fields)))])
    lt = np.array([30, 10, 20], np.int64)
    records, offsets = rows.encode(np.zeros((3, len(fields))), lt, 0)
    buf = ChunkBuffer()
    buf.add_rows(records, offsets, lt, rows.channel_ids)
    parts, index = buf.finish()
    times, offs = index[3]
    assert times.tolist() == [10, 20, 30]
    data = np.concatenate([np.frombuffer(p, np.uint8) if isinstance(p, bytes) else p for p in parts])
    got = [int.from_bytes(data[o + 15:o + 23].tobytes(), "little") for o in offs.tolist()]
    assert got == [10, 20, 30]
