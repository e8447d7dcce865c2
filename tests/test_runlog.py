"""Run logs (issue 5): round trip, the mcap library's own validation, cut files, interrupted runs.

The references here are independent of the code under test: the in-memory RunRecord (values compared
bit for bit), the mcap library's readers (SeekingReader / NonSeekingReader / StreamReader with CRC
checks, its summary statistics and chunk indexes), the mcap project's protobuf decoder
(``mcap-protobuf-support``, which builds the message classes from the schema in the file), closed
forms (quaternion of a yaw), and the JSON schemas checked with the jsonschema package.
"""

from __future__ import annotations

import io
import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk

from usv_mj.record.run_record import COL, COLUMNS, Event, RunRecord
from usv_mj.outputs.log import RunLogReadError, RunLogWriter, load_topic, read_run
from usv_mj.cli.inspect import add_arguments as add_inspect_arguments, run as inspect_command
from usv_mj.outputs.log.topics import ROW_TOPICS, row_topics
from usv_mj.scenario.spec import load_scenario
from usv_mj.loop.simulate import make_controller, simulate
from usv_mj.record.summary import summarize

ROOT = Path(__file__).resolve().parents[1]
DURATION = 8.0
PER_STEP_SCHEMAS = {"usv_mj.State", "usv_mj.Reference", "usv_mj.Control", "usv_mj.Errors", "usv_mj.Diagnostics"}


def _decoded(path, topics=None):
    """(channel, message, decoded protobuf message) of the per-step topics, by the mcap project's
    own protobuf decoder: nothing of usv_mj.outputs.log's reader is involved."""
    from mcap_protobuf.decoder import DecoderFactory

    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        if topics is None:
            topics = [c.topic for c in reader.get_summary().channels.values() if c.message_encoding == "protobuf"]
        return [(c, m, d) for _, c, m, d in reader.iter_decoded_messages(topics=topics)]


def _descriptor(summary, topic):
    """The message descriptor (DescriptorProto) and {field name: doc comment} of a protobuf topic."""
    from google.protobuf import descriptor_pb2

    channel = next(c for c in summary.channels.values() if c.topic == topic)
    schema = summary.schemas[channel.schema_id]
    assert schema.encoding == "protobuf"
    fd = descriptor_pb2.FileDescriptorSet.FromString(schema.data).file[0]
    msg = fd.message_type[0]
    assert f"{fd.package}.{msg.name}" == schema.name
    docs = {tuple(loc.path): loc.leading_comments.strip() for loc in fd.source_code_info.location}
    return msg, {f.name: docs.get((4, 0, 2, i), "") for i, f in enumerate(msg.field)}, docs.get((4, 0), "")


def _norm(obj):
    """JSON-normal form (tuples -> lists) for comparing metadata dicts, via the standard library."""
    return json.loads(json.dumps(obj, default=str))


def assert_same_rows(a: RunRecord, b: RunRecord, n: int | None = None):
    n = len(b) if n is None else n
    assert len(a) == n
    assert a.column_names == b.column_names and a.diagnostic_fields == b.diagnostic_fields
    assert a.diagnostic_events == b.diagnostic_events
    for c in b.column_names:
        x, y = a[c], b[c][:n]
        assert np.array_equal(x.view(np.uint64), y.view(np.uint64)), c     # NaN payloads too (protobuf)


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(preset="paper", overrides={"duration": DURATION, "plant": {"kind": "analytic"}})


@pytest.fixture(scope="module")
def logged(tmp_path_factory, scenario):
    """A file with the main run and the PI baseline, written by the background writer."""
    path = tmp_path_factory.mktemp("runlog") / "run.mcap"
    with RunLogWriter(path, scenario, attachments={"notes/readme.txt": "hello", "blob.bin": b"\x00\x01"},
                      rows_per_chunk=700) as writer:
        main = simulate(scenario, sinks=[writer.sink("main")], block=1500)
        base = simulate(scenario, controller_kind="pi", sinks=[writer.sink("baseline")], block=1500)
    return path, main, base


# --- round trip ---------------------------------------------------------------------------------


def test_round_trip_is_bit_exact_for_both_runs(logged):
    path, main, base = logged
    log = read_run(path)
    assert log.complete and not log.truncated
    assert_same_rows(log.record, main)
    assert_same_rows(log.baseline, base)
    for got, want in ((log.record, main), (log.baseline, base)):
        assert got.status == want.status == "completed"
        assert got.stop_reason == want.stop_reason
        assert [(e.t, e.kind, e.message, _norm(e.values)) for e in got.events] == \
               [(e.t, e.kind, e.message, _norm(e.values)) for e in want.events]
        assert got.metadata == _norm(want.metadata)
    assert log.summaries["main"] == _norm(summarize(main))
    assert log.summaries["baseline"] == _norm(summarize(base))


def _odd_floats(n: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2**64 - 1, size=n, dtype=np.uint64, endpoint=True)
    vals = bits.view(np.float64).copy()
    specials = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308,
                         1.7976931348623157e308, -1.7976931348623157e308, 0.1, 1e-7, 1e22, 123456789012345678.0])
    vals[: len(specials)] = specials
    return vals


def _handmade_record(n: int, seed: int = 1) -> RunRecord:
    """A record whose every cell is an arbitrary float64 bit pattern (NaN, +-inf, -0, subnormals...)."""
    rec = RunRecord(n, metadata={"preset": "handmade", "control_period_s": 0.001, "plant": "none"})
    rec.data[:] = _odd_floats(n * len(COLUMNS), seed).reshape(n, len(COLUMNS))
    rec.data[:, COL["t"]] = np.arange(n) * 0.001
    return rec


@pytest.mark.parametrize("background", [False, True])
def test_every_float_bit_pattern_round_trips(tmp_path, scenario, background):
    rec = _handmade_record(2500)
    path = tmp_path / "odd.mcap"
    with RunLogWriter(path, scenario, background=background, rows_per_chunk=300) as writer:
        sink = writer.sink("main")
        sink.start(rec)
        for lo in range(0, 2500, 1000):
            rec.n_rows = min(2500, lo + 1000)
            rec.events.append(Event(lo * 0.001, "probe", f"block {lo}", {"x": float(rec.data[lo, 1]) if
                                                                         np.isfinite(rec.data[lo, 1]) else 1.5,
                                                                         "list": [1, 2.5, -0.0]}))
            sink.rows(rec, lo, rec.n_rows)
        rec.status, rec.stop_reason = "completed", ""
        sink.finish(rec)
    got = read_run(path).record
    assert_same_rows(got, rec)
    assert np.isinf(rec.data).any() and np.isnan(rec.data).any()   # the test did exercise the specials
    assert [(e.t, e.kind, e.message, e.values) for e in got.events] == \
           [(e.t, e.kind, e.message, _norm(e.values)) for e in rec.events]


def test_infinities_nan_payloads_and_negative_zero_keep_their_bits_in_protobuf(tmp_path, scenario):
    rec = _handmade_record(4)
    odd_nan = np.uint64(0x7FF4_0000_DEAD_BEEF).view(np.float64)        # a signalling NaN with a payload
    rec.data[:, COL["x"]] = [np.inf, -np.inf, odd_nan, -0.0]
    path = tmp_path / "inf.mcap"
    with RunLogWriter(path, scenario, background=False) as writer:
        sink = writer.sink("main")
        sink.start(rec)
        rec.n_rows = 4
        sink.rows(rec, 0, 4)
        sink.finish(rec)
    xs = np.array([d.x for _, _, d in _decoded(path, ["/usv/state"])])
    assert np.array_equal(xs.view(np.uint64), rec.data[:4, COL["x"]].view(np.uint64))
    got = read_run(path).record["x"]
    assert np.array_equal(got.view(np.uint64), rec.data[:4, COL["x"]].view(np.uint64))


# --- the mcap library's own checks ------------------------------------------------------------------


def test_file_passes_the_mcap_library_validation(logged):
    path, main, base = logged
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert len(summary.chunk_indexes) == summary.statistics.chunk_count > 2
        topics = {c.topic: cid for cid, c in summary.channels.items()}
        counts = summary.statistics.channel_message_counts
        for name, _, _ in row_topics(main.column_names):
            assert counts[topics[f"/usv/{name}"]] == len(main)
        for name, _, _ in row_topics(base.column_names):
            assert counts[topics[f"/baseline/usv/{name}"]] == len(base)
        n = 0
        last_state_time = -1
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            n += 1
            if channel.topic == "/usv/state":
                assert message.log_time >= last_state_time
                last_state_time = message.log_time
        assert n == summary.statistics.message_count
        assert last_state_time == round(main["t"][-1] * 1e9)
        assert {s.name for s in summary.schemas.values()} >= {"foxglove.FrameTransform", "foxglove.SceneUpdate"}
        for c in summary.channels.values():     # per step: protobuf; events and Foxglove's: JSON
            per_step = summary.schemas[c.schema_id].name in PER_STEP_SCHEMAS
            assert (c.message_encoding, summary.schemas[c.schema_id].encoding) == \
                (("protobuf", "protobuf") if per_step else ("json", "jsonschema")), c.topic
    # the sequential reader, with every chunk CRC and the data-section CRC checked
    with open(path, "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
    assert sum(isinstance(r, Message) for r in records) == n
    # and the non-seeking reader on a pipe-like stream
    with open(path, "rb") as f:
        stream = io.BufferedReader(_NonSeekable(f.read()))
    assert sum(1 for _ in make_reader(stream, validate_crcs=True).iter_messages()) == n


def test_messages_follow_their_schemas(logged):
    """JSON messages validate against their JSON schemas; protobuf messages decode, by the mcap
    project's decoder, to the record's values at their row (field by field, bit for bit)."""
    jsonschema = pytest.importorskip("jsonschema")
    path, main, base = logged
    seen = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        n_topics = len(reader.get_summary().channels)
        assert n_topics == 2 * 11      # 5 row topics, events, 5 Foxglove topics per run
        for schema, channel, message in reader.iter_messages():
            if channel.topic not in seen and channel.message_encoding == "json":
                seen[channel.topic] = (json.loads(schema.data), json.loads(message.data))
    assert len(seen) == 2 * 6
    for topic, (schema, msg) in seen.items():
        jsonschema.validate(msg, schema)
    checked = set()
    for channel, message, decoded in _decoded(path):
        rec = main if channel.topic.startswith("/usv/") else base
        k = message.sequence
        assert message.log_time == round(rec["t"][k] * 1e9)
        fields = [f.name for f in decoded.DESCRIPTOR.fields]
        assert tuple(fields) == next(f for name, _, f in row_topics(rec.column_names)
                                     if channel.topic.endswith("/" + name))
        for name in fields:
            assert np.float64(getattr(decoded, name)).view(np.uint64) == rec[name][k].view(np.uint64), \
                (channel.topic, k, name)
        checked.add(channel.topic)
    assert len(checked) == 2 * 5


class _NonSeekable(io.RawIOBase):
    def __init__(self, data: bytes):
        self._b = io.BytesIO(data)

    def readable(self):
        return True

    def seekable(self):
        return False

    def readinto(self, b):
        chunk = self._b.read(len(b))
        b[: len(chunk)] = chunk
        return len(chunk)


# --- a file cut short ---------------------------------------------------------------------------------


def _complete_chunk_rows(data: bytes, cut: int) -> int:
    """/usv/state messages in the chunks that end before ``cut`` (counted with the mcap library)."""
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    state = next(cid for cid, c in summary.channels.items() if c.topic == "/usv/state")
    rows = 0
    for ci in summary.chunk_indexes:
        if ci.chunk_start_offset + ci.chunk_length <= cut:
            raw = data[ci.chunk_start_offset: ci.chunk_start_offset + ci.chunk_length]
            chunk = next(iter(StreamReader(io.BytesIO(raw), skip_magic=True, emit_chunks=True).records))
            assert isinstance(chunk, Chunk)
            rows += sum(isinstance(r, Message) and r.channel_id == state for r in breakup_chunk(chunk, True))
    return rows


def test_cut_file_is_read_up_to_its_last_complete_chunk(logged, tmp_path):
    path, main, _ = logged
    data = path.read_bytes()
    summary = make_reader(io.BytesIO(data)).get_summary()
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    main_chunks = [c for c in chunks if c.message_start_time <= round(main["t"][-1] * 1e9)]
    c2 = main_chunks[2]
    cuts = [c2.chunk_start_offset + c2.chunk_length // 2,            # in the middle of a chunk
            c2.chunk_start_offset + c2.chunk_length,                 # right after a chunk, before its indexes
            c2.chunk_start_offset + c2.chunk_length + 5,             # inside its message indexes
            c2.chunk_start_offset + 3,                               # inside a chunk's record header
            chunks[-1].chunk_start_offset + chunks[-1].chunk_length // 3,
            len(data) - 40]                                          # inside the summary / footer
    for cut in cuts:
        cut_path = tmp_path / f"cut_{cut}.mcap"
        cut_path.write_bytes(data[:cut])
        log = read_run(cut_path)
        assert log.truncated or not log.complete
        expected_at_least = _complete_chunk_rows(data, cut)
        n = len(log.record)
        assert expected_at_least <= n <= len(main)
        assert n > 0
        assert_same_rows(log.record, main, n)
        if n < len(main):
            assert log.record.status == "truncated" and "ends at" in log.record.stop_reason
        # the same through a non-seekable stream
        log2 = read_run(io.BufferedReader(_NonSeekable(data[:cut])))
        assert len(log2.record) == n


def test_file_read_while_still_being_written(tmp_path, scenario):
    """Events stream as they happen: after each rows() call the file on disk already holds them."""
    rec = _handmade_record(3000, seed=3)
    path = tmp_path / "live.mcap"
    with RunLogWriter(path, scenario, background=False, rows_per_chunk=10_000) as writer:
        sink = writer.sink("main")
        sink.start(rec)
        for k, lo in enumerate(range(0, 3000, 1000)):
            rec.n_rows = lo + 1000
            rec.events.append(Event(lo * 0.001 + 0.5, "funnel_violation", f"number {k}", {"axis": 1}))
            sink.rows(rec, lo, lo + 1000)
            partial = read_run(path)
            assert partial.truncated and not partial.complete        # no summary yet
            assert len(partial.record) == lo + 1000
            assert [e.message for e in partial.record.events] == [f"number {i}" for i in range(k + 1)]
            assert partial.record.status == "truncated"
        sink.finish(rec)


# --- interrupted runs ---------------------------------------------------------------------------------


class _Stops:
    """A controller that raises ``exc`` at its n-th call (else it is the scenario's PPC controller)."""

    def __init__(self, scenario, n, exc):
        self.inner = make_controller(scenario)
        self.name = self.inner.name
        self.diagnostic_fields = self.inner.diagnostic_fields
        self.diagnostic_events = getattr(self.inner, "diagnostic_events", None)
        self.n, self.exc, self.calls = n, exc, 0

    def reset(self):
        self.inner.reset()
        self.calls = 0

    def __call__(self, t, x, ref):
        self.calls += 1
        if self.calls > self.n:
            raise self.exc
        return self.inner(t, x, ref)


class _Keep:
    def start(self, record):
        self.record = record

    def rows(self, record, lo, hi):
        pass

    def finish(self, record):
        self.record = record


def test_exception_in_the_loop_leaves_a_readable_file(tmp_path, scenario):
    path = tmp_path / "failed.mcap"
    keep = _Keep()
    with pytest.raises(ZeroDivisionError):
        with RunLogWriter(path, scenario) as writer:
            simulate(scenario, controller=_Stops(scenario, 2345, ZeroDivisionError("boom in the law")),
                     sinks=[writer.sink("main"), keep], block=1000)
    log = read_run(path)
    assert log.complete
    assert len(log.record) == 2345
    assert_same_rows(log.record, keep.record)
    assert log.record.status == "failed"
    (ev,) = log.record.events_of("failed")
    assert "boom in the law" in ev.message and ev.t == pytest.approx(2345 * scenario.control_period)


def test_ctrl_c_leaves_a_readable_file(tmp_path, scenario):
    path = tmp_path / "interrupted.mcap"
    with RunLogWriter(path, scenario) as writer:
        rec = simulate(scenario, controller=_Stops(scenario, 1234, KeyboardInterrupt()), sinks=[writer.sink("main")])
    assert rec.status == "interrupted"
    log = read_run(path)
    assert_same_rows(log.record, rec)
    assert len(log.record) == 1234
    assert log.record.status == "interrupted" and "Ctrl-C" in log.record.stop_reason
    assert [e.kind for e in log.record.events_of("interrupted")] == ["interrupted"]
    assert log.summaries["main"]["status"] == "interrupted"


def test_divergence_is_logged_with_its_reason(tmp_path):
    sc = load_scenario(preset="paper", overrides={"duration": 5.0, "limits": {"max_speed": 0.05},
                                                    "plant": {"kind": "analytic"}})
    path = tmp_path / "diverged.mcap"
    with RunLogWriter(path, sc) as writer:
        rec = simulate(sc, sinks=[writer.sink("main")])
    assert rec.status == "diverged"
    log = read_run(path)
    assert_same_rows(log.record, rec)
    assert log.record.status == "diverged" and log.record.stop_reason == rec.stop_reason
    (ev,) = log.record.events_of("divergence")
    assert ev.values == _norm(rec.events_of("divergence")[0].values)
    end = load_topic(path, "/usv/events")
    assert list(end["kind"][-1:]) == ["run_end"] and end["status"][-1] == "diverged"


# --- metadata, attachments, topics -------------------------------------------------------------------


def test_metadata_and_attachments(tmp_path):
    toml = tmp_path / "my_scenario.toml"
    toml.write_text('preset = "paper"\nduration = 2.0\n[plant]\nkind = "analytic"\n')
    sc = load_scenario(toml)
    path = tmp_path / "meta.mcap"
    with RunLogWriter(path, sc, attachments={"extra.txt": "text"}) as writer:
        simulate(sc, sinks=[writer.sink("main")])
    log = read_run(path)
    meta = log.metadata
    assert meta["preset"] == "paper"
    assert meta["scenario"] == _norm(sc.to_dict())
    assert {"mujoco", "numpy", "numba", "mcap", "python"} <= set(meta["versions"])
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    assert meta["git_commit"] == head   # a checkout (an installed package has none: test_log_names_the_plugins...)
    from usv_mj.core.version import __version__

    assert meta["usv_mj_version"] == __version__ and meta["plugins"] == {}   # built-ins only
    assert log.attachments["extra.txt"] == b"text"
    assert log.attachments["scenario/my_scenario.toml"] == toml.read_bytes()
    models = sorted((ROOT / "models").glob("*.xml"))
    for m in models:
        assert log.attachments[f"models/{m.name}"] == m.read_bytes()
    assert meta["runs"]["main"]["end"]["status"] == "completed"


def test_foxglove_topics_match_the_state(logged):
    path, main, _ = logged
    tf = load_topic(path, "/usv/tf/hull")
    k = np.arange(0, len(main), 20)                       # every 20 ms at dt = 1 ms
    assert np.array_equal(tf["translation.x"], main["x"][k])
    assert np.array_equal(tf["translation.y"], main["y"][k])
    psi = main["psi"][k]
    assert np.allclose(tf["rotation.z"], np.sin(psi / 2), rtol=0, atol=1e-15)
    assert np.allclose(tf["rotation.w"], np.cos(psi / 2), rtol=0, atol=1e-15)
    assert set(tf["child_frame_id"]) == {"base_link"} and set(tf["parent_frame_id"]) == {"map"}      # REP-105
    ref = load_topic(path, "/usv/tf/reference")
    assert set(ref["child_frame_id"]) == {"reference"} and set(ref["parent_frame_id"]) == {"map"}
    assert np.array_equal(tf["timestamp.sec"] * 1e9 + tf["timestamp.nsec"], tf["log_time"].astype(float))
    funnel = load_topic(path, "/usv/scene/funnel")
    first = funnel["entities"][len(k) // 2][0]
    i = k[len(k) // 2]
    xs = sorted({p["x"] for p in first["lines"][0]["points"]})
    ys = sorted({p["y"] for p in first["lines"][0]["points"]})
    assert xs == [main["x_d"][i] - main["rho1"][i], main["x_d"][i] + main["rho1"][i]]
    assert ys == [main["y_d"][i] - main["rho2"][i], main["y_d"][i] + main["rho2"][i]]
    path_msgs = load_topic(path, "/usv/scene/path")
    pts = path_msgs["entities"][0][0]["lines"][0]["points"]
    assert len(pts) == int(DURATION / 0.5) + 1
    assert (pts[0]["x"], pts[0]["y"]) == (main["x_d"][0], main["y_d"][0])
    assert (pts[-1]["x"], pts[-1]["y"]) == (main["x_d"][-1], main["y_d"][-1])
    state = load_topic(path, "/baseline/usv/state")
    assert set(state) == {"log_time", "t", "x", "y", "psi", "u", "v", "r"}
    assert np.array_equal(state["log_time"], np.round(state["t"] * 1e9).astype(np.int64))


def test_topics_and_counts(logged):
    path, main, base = logged
    log = read_run(path)
    topics = log.topics()
    assert [name for name, _, _ in ROW_TOPICS] == ["state", "reference", "control", "errors", "diagnostics"]
    for name, _, _ in ROW_TOPICS:
        assert topics[f"/usv/{name}"] == len(main)
        assert topics[f"/baseline/usv/{name}"] == len(base)
    assert "/usv/adaptation" not in topics and "/usv/internal" not in topics
    assert topics["/usv/tf/hull"] == len(range(0, len(main), 20))
    with pytest.raises(RunLogReadError, match="no topic"):
        load_topic(path, "/nope")


# --- inspect ----------------------------------------------------------------------------------------


def _inspect(path, capsys, *extra):
    import argparse

    parser = argparse.ArgumentParser()
    add_inspect_arguments(parser)
    code = inspect_command(parser.parse_args([str(path), *extra]))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_inspect_command(logged, tmp_path, capsys):
    path, main, _ = logged
    code, out, _ = _inspect(path, capsys)
    assert code == 0
    assert "complete" in out and "/usv/state" in out and str(len(main)) in out
    assert "run main" in out and "status completed" in out and "run baseline" in out
    code, out, _ = _inspect(path, capsys, "--json")
    assert code == 0 and json.loads(out)["topics"]["/usv/state"]["count"] == len(main)
    code, _, err = _inspect(tmp_path / "missing.mcap", capsys)
    assert code == 2 and "no such file" in err
    bad = tmp_path / "bad.mcap"
    bad.write_text("not an mcap file")
    code, _, err = _inspect(bad, capsys)
    assert code == 2 and "not an MCAP file" in err
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    code, out, _ = _inspect(cut, capsys)
    assert code == 0 and "CUT SHORT" in out


def test_read_errors_are_friendly(tmp_path):
    with pytest.raises(RunLogReadError, match="no such file"):
        read_run(tmp_path / "nothing.mcap")
    (tmp_path / "x.mcap").write_bytes(b"hello world, not mcap")
    with pytest.raises(RunLogReadError, match="not an MCAP file"):
        read_run(tmp_path / "x.mcap")


def test_killed_writer_leaves_a_readable_prefix_and_close_reports_it(tmp_path, scenario):
    """The process that writes the file is killed (SIGKILL) mid-run: the run goes on, close() raises,
    and the file is read up to its last complete chunk."""
    import os
    import signal
    import time

    from usv_mj.outputs.log import RunLogError

    rec = _handmade_record(6000, seed=5)
    path = tmp_path / "killed.mcap"
    writer = RunLogWriter(path, scenario, rows_per_chunk=500, queue_blocks=2)
    sink = writer.sink("main")
    sink.start(rec)
    rec.n_rows = 2000
    sink.rows(rec, 0, 2000)
    deadline = time.time() + 120
    while time.time() < deadline:          # wait for the worker to have written some chunks
        try:
            if len(read_run(path).record) >= 1000:
                break
        except RunLogReadError:
            pass
        time.sleep(0.2)
    os.kill(writer._proc.pid, signal.SIGKILL)
    writer._proc.join(30)
    with pytest.warns(RuntimeWarning, match="without its log"):
        for lo in range(2000, 6000, 500):
            rec.n_rows = lo + 500
            sink.rows(rec, lo, lo + 500)
    sink.finish(rec)                        # never raises
    with pytest.raises(RunLogError, match="not logged"):
        writer.close()
    log = read_run(path)
    assert log.truncated and 1000 <= len(log.record) <= 2000
    assert_same_rows(log.record, rec, len(log.record))
    assert log.record.status == "truncated"


def test_writer_never_closed_is_closed_at_interpreter_exit(tmp_path):
    """No with-block, no close(): the process still exits, and the file is complete."""
    import sys

    path = tmp_path / "noclose.mcap"
    script = (
        "from usv_mj.scenario.spec import load_scenario\n"
        "from usv_mj.loop.simulate import simulate\n"
        "from usv_mj.outputs.log import RunLogWriter\n"
        "if __name__ == '__main__':\n"
        "    sc = load_scenario(preset='paper', overrides={'duration': 1.0, 'plant': {'kind': 'analytic'}})\n"
        f"    w = RunLogWriter({str(path)!r}, sc)\n"
        "    simulate(sc, sinks=[w.sink('main')])\n")
    (tmp_path / "noclose.py").write_text(script)
    import os

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, str(tmp_path / "noclose.py")], cwd=ROOT, timeout=300,
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    log = read_run(path)
    assert log.complete and len(log.record) == 1001 and log.record.status == "completed"

def test_template_time_stamps_are_the_log_time_in_integer_seconds_and_nanoseconds():
    """The bulk layout writes a Foxglove time {sec, nsec} from each message's log time: every digit
    count, the second boundary and the largest u64-safe stamps, parsed back by the json module."""
    from usv_mj.outputs.log.mcap_file import MESSAGE_HEADER, template_layout

    layout = template_layout(3, {"stamp": {"sec": "$sec", "nsec": "$nsec"}, "v": "$v"}, ("$sec", "$nsec", "$v"))
    ns = np.array([0, 1, 9, 10, 999_999_999, 1_000_000_000, 1_999_999_999, 12_345_678_901, 2**62 + 12345],
                  np.int64)
    block = np.zeros((len(ns), 3))
    block[:, 2] = np.arange(len(ns)) * 0.1
    records, offsets = layout.encode(block, ns, np.arange(100, 100 + len(ns)))
    for i, t in enumerate(ns):
        start = int(offsets[i, 0])
        length = int.from_bytes(records[start + 1:start + 9].tobytes(), "little")
        seq = int.from_bytes(records[start + 11:start + 15].tobytes(), "little")
        msg = json.loads(records[start + MESSAGE_HEADER:start + 9 + length].tobytes())
        assert msg == {"stamp": {"sec": int(t) // 10**9, "nsec": int(t) % 10**9}, "v": i * 0.1}
        assert seq == 100 + i
    with pytest.raises(ValueError, match="exactly once"):
        template_layout(1, {"a": "$x", "b": "$x"}, ("$x",))


def test_no_shared_memory_falls_back_to_writing_in_process(tmp_path, scenario, monkeypatch):
    """Where /dev/shm cannot hold the ring, the writer says so and writes the same file itself."""
    from multiprocessing import shared_memory

    def refuse(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(shared_memory, "SharedMemory", refuse)
    rec = _handmade_record(3000, seed=9)
    rec.n_rows = 3000
    with pytest.warns(RuntimeWarning, match="no shared memory"):
        writer = RunLogWriter(tmp_path / "fallback.mcap", scenario)
    assert writer._background is False
    with writer:
        sink = writer.sink("main")
        sink.start(rec)
        sink.rows(rec, 0, 3000)
        sink.finish(rec)
    assert_same_rows(read_run(tmp_path / "fallback.mcap").record, rec, 3000)


# --- declared columns ---------------------------------------------------------------------------------


class _TwoFields:
    """A user's controller: a proportional law that declares two made-up diagnostics and no funnel."""

    name = "two_fields"
    diagnostic_fields = ("heading_gap", "speed_gap")

    def __init__(self):
        self._diag = np.zeros(2)

    def reset(self):
        self._diag[:] = 0.0

    def __call__(self, t, x, ref):
        self._diag[0] = math.atan2(math.sin(ref[2] - x[2]), math.cos(ref[2] - x[2]))
        self._diag[1] = ref[6] - x[3]
        return 20.0 * self._diag[1], 2.0 * self._diag[0], self._diag


def test_a_controller_with_its_own_fields_round_trips_on_its_own_topic(tmp_path, scenario):
    sc = scenario.with_overrides({"duration": 3.0})
    path = tmp_path / "own.mcap"
    with RunLogWriter(path, sc, rows_per_chunk=400) as writer:
        rec = simulate(sc, controller=_TwoFields(), sinks=[writer.sink("main")], block=700)
    assert rec.column_names[-2:] == ("heading_gap", "speed_gap") and not rec.has_funnel
    log = read_run(path)
    got = log.record
    assert_same_rows(got, rec)
    assert got.diagnostic_fields == ("heading_gap", "speed_gap") and not got.has_funnel
    assert got.metadata["diagnostic_fields"] == ["heading_gap", "speed_gap"]
    topics = log.topics()
    assert {t for t in topics if t.startswith("/usv/")} == {
        "/usv/state", "/usv/reference", "/usv/control", "/usv/diagnostics", "/usv/events", "/usv/tf/hull",
        "/usv/tf/reference", "/usv/scene/path", "/usv/scene/hull"}          # no errors, no funnel: none declared
    diag = load_topic(path, "/usv/diagnostics")
    assert set(diag) == {"log_time", "t", "heading_gap", "speed_gap"}
    assert np.array_equal(diag["speed_gap"], rec["speed_gap"])
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    msg, _, doc = _descriptor(summary, "/usv/diagnostics")
    assert [f.name for f in msg.field] == ["t", "heading_gap", "speed_gap"]
    assert "two_fields" in doc


def test_pi_baseline_record_keeps_its_own_fields(logged):
    path, _, base = logged
    got = read_run(path).baseline
    assert got.diagnostic_fields == base.diagnostic_fields
    assert got.diagnostic_fields[-4:] == ("u_e", "r_e", "integral_u", "integral_r") and got.has_funnel
    diag = load_topic(path, "/baseline/usv/diagnostics")
    assert set(diag) == {"log_time", "t", "e1s", "e2s", "e3s", "psi_a", "u_e", "r_e", "integral_u", "integral_r"}
    assert np.array_equal(diag["integral_u"], base["integral_u"])


# --- file order = log-time order ------------------------------------------------------------------------


def _log_times_in_file_order(path) -> np.ndarray:
    with open(path, "rb") as f:
        return np.array([m.log_time for _, _, m in make_reader(f).iter_messages(log_time_order=False)], np.int64)


def test_main_job_logs_one_file_per_run_each_in_log_time_order(tmp_path, scenario):
    from usv_mj.jobs.run import run_job

    job = run_job(scenario.with_overrides({"duration": 6.0}), tmp_path / "job", video=False, progress=False,
                  step_check=False)
    main_path, base_path = tmp_path / "job" / "run.mcap", tmp_path / "job" / "baseline.mcap"
    assert job.baseline is not None and base_path.is_file()
    for path, rec in ((main_path, job.record), (base_path, job.baseline)):
        lt = _log_times_in_file_order(path)           # the mcap library, chunk by chunk in file order
        assert lt.size > 5 * len(rec) and np.all(np.diff(lt) >= 0), path.name
        assert lt[0] == 0 and lt[-1] == round(rec["t"][-1] * 1e9)
        with open(path, "rb") as f:                    # and record by record with the stream reader
            stream = [r.log_time for r in StreamReader(f, validate_crcs=True).records if isinstance(r, Message)]
        assert stream == lt.tolist()
    with open(main_path, "rb") as f:
        assert {c.topic.split("/")[1] for c in make_reader(f).get_summary().channels.values()} == {"usv"}
    log = read_run(main_path)                          # the baseline is found beside the main run's log
    assert_same_rows(log.record, job.record)
    assert_same_rows(log.baseline, job.baseline)
    assert log.files == {"main": str(main_path), "baseline": str(base_path)}
    assert log.summaries["baseline"] == _norm(summarize(job.baseline))
    assert read_run(main_path, companions=False).baseline is None
    # a log beside it that is not its companion (another job's) is not taken for its baseline
    other = tmp_path / "other"
    other.mkdir()
    with RunLogWriter(other / "run.mcap", scenario) as writer:
        simulate(scenario.with_overrides({"duration": 0.5}), controller_kind="pi", sinks=[writer.sink("baseline")])
    base_path.unlink()
    (other / "run.mcap").rename(base_path)
    assert read_run(main_path).baseline is None


def test_events_are_logged_in_the_chunk_of_their_time(tmp_path, scenario):
    """Events of a block go to the chunk of their time, and one reported late is logged no earlier
    than the rows already written: the file never goes back in log time."""
    rec = _handmade_record(3000, seed=11)
    path = tmp_path / "events.mcap"
    with RunLogWriter(path, scenario, background=False, rows_per_chunk=400) as writer:
        sink = writer.sink("main")
        sink.start(rec)
        rec.events += [Event(0.1, "early", "in the first chunk"), Event(1.7, "late", "in the fifth chunk")]
        rec.n_rows = 2000
        sink.rows(rec, 0, 2000)
        rec.events.append(Event(0.5, "reported_late", "after rows to 2 s were written"))
        rec.n_rows = 3000
        sink.rows(rec, 2000, 3000)
        sink.finish(rec)
    lt = _log_times_in_file_order(path)
    assert np.all(np.diff(lt) >= 0)
    ev = load_topic(path, "/usv/events")
    assert list(ev["kind"]) == ["early", "late", "reported_late", "run_end"]
    assert list(ev["log_time"][:3]) == [100_000_000, 1_700_000_000, 2_000_000_000]
    assert list(ev["t"][:3]) == [0.1, 1.7, 0.5]       # the event's own time is kept in the message
    assert [e.t for e in read_run(path).record.events] == [0.1, 0.5, 1.7]


# --- Foxglove and ROS conventions -------------------------------------------------------------------


SCHEMA_DIR = ROOT / "usv_mj" / "outputs" / "log" / "schemas"


def test_foxglove_schemas_are_embedded_as_published(logged):
    """The channels' schemas are the published files byte for byte (their hashes as recorded in
    schemas/NOTICE.md, from @foxglove/schemas), with the descriptions and enums of the fields used."""
    import hashlib
    import re

    notice = (SCHEMA_DIR / "NOTICE.md").read_text()
    published = {}
    for name, digest in re.findall(r"\| (foxglove\.\w+)\.json \| ([0-9a-f]{64}) \|", notice):
        data = (SCHEMA_DIR / f"{name}.json").read_bytes()
        assert hashlib.sha256(data).hexdigest() == digest, name
        published[name] = data
    assert set(published) == {"foxglove.FrameTransform", "foxglove.SceneUpdate"}
    path, _, _ = logged
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    used = {}
    for c in summary.channels.values():
        s = summary.schemas[c.schema_id]
        if s.name.startswith("foxglove."):
            assert s.data == published[s.name], c.topic
            used[s.name] = json.loads(s.data)
    assert set(used) == set(published)
    tf = used["foxglove.FrameTransform"]["properties"]
    assert all(tf[k].get("description") for k in ("timestamp", "parent_frame_id", "child_frame_id", "translation",
                                                  "rotation"))
    scene = used["foxglove.SceneUpdate"]["properties"]
    deletion = scene["deletions"]["items"]["properties"]["type"]
    assert deletion["title"] == "foxglove.SceneEntityDeletionType"
    assert [(o["title"], o["const"]) for o in deletion["oneOf"]] == [("MATCHING_ID", 0), ("ALL", 1)]
    entity = scene["entities"]["items"]["properties"]
    line_type = entity["lines"]["items"]["properties"]["type"]
    assert [(o["title"], o["const"]) for o in line_type["oneOf"]] == [("LINE_STRIP", 0), ("LINE_LOOP", 1),
                                                                       ("LINE_LIST", 2)]
    assert all(o.get("description") for o in line_type["oneOf"])
    assert entity["cubes"]["items"]["properties"]["size"]["description"]


def test_state_schema_says_the_axes_conventions(logged):
    path, _, _ = logged
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    _, state, _ = _descriptor(summary, "/usv/state")       # the fields' comments in the descriptor
    assert "east" in state["x"] and "ENU" in state["x"]
    assert "north" in state["y"]
    assert "counter-clockwise from east" in state["psi"]
    assert "forward" in state["u"] and "port" in state["v"]
    assert "north position" not in state["x"] and "east position" not in state["y"]


def test_the_log_names_its_plugins_and_an_installed_package_no_unknown_commit(tmp_path, monkeypatch, capsys):
    """Issue 37, item 5: the log's metadata names every plug-in kind the run used (here a module:Name
    controller on PYTHONPATH, no distribution: its file; a vessel data file) and the project's
    version; outside a git checkout it says so instead of "git commit: unknown"."""
    import usv_mj.outputs.log.writer as writer_module
    from usv_mj.cli.main import main

    monkeypatch.syspath_prepend(str(ROOT / "examples" / "plugins" / "usv_mj_example_plugin"))
    monkeypatch.setattr(writer_module, "git_commit", lambda root=None: ("unknown", None))   # as a wheel install
    sc = load_scenario(overrides={"duration": 0.5, "plant": {"kind": "analytic"}, "baseline": {"enabled": False},
                                  "controller": {"kind": "usv_mj_example_plugin.pd:ExamplePD"},
                                  "vessel": {"kind": str(ROOT / "examples" / "vessels" / "wamv.toml")}})
    path = tmp_path / "plug.mcap"
    with RunLogWriter(path, sc) as writer:
        simulate(sc, sinks=[writer.sink("main")])
    meta = read_run(path).metadata
    assert "git_commit" not in meta and "not a git checkout" in meta["install"]
    pd = meta["plugins"]["controller usv_mj_example_plugin.pd:ExamplePD"]
    assert pd["module"] == "usv_mj_example_plugin.pd" and pd["file"].endswith("pd.py") and pd["distribution"] is None
    assert meta["plugins"][f"vessel {ROOT / 'examples' / 'vessels' / 'wamv.toml'}"]["source"].startswith("data file")
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "git commit" not in out and "(an installed package, not a git checkout)" in out
    assert "plug-in controller usv_mj_example_plugin.pd:ExamplePD:" in out


def test_an_installed_plugins_distribution_and_version_are_named():
    """An entry point's kind names the installed distribution that provides its module and its version
    (usv_mj.core.registry.origin), read from the distribution's metadata."""
    import importlib.metadata as md

    from usv_mj.core.registry import Entry, origin

    class Fake:
        pass

    Fake.__module__ = "numpy.fake"   # a module of an installed distribution
    o = origin(Entry("x", Fake, {}, "entry point usv_mj.controllers (dist numpy)"))
    assert o["distribution"] == "numpy" and o["version"] == md.version("numpy")
