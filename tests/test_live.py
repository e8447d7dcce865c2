"""Live in Foxglove: `usv-mj run --live` over the Foxglove WebSocket protocol, read by a real client.

The client is the `websockets` package speaking the protocol itself (subprotocol foxglove.sdk.v1:
serverInfo and advertise as JSON text, a subscribe op, binary Message Data frames of opcode 1,
subscription id u32, timestamp u64, payload); protobuf payloads are decoded from the advertised
FileDescriptorSet, JSON payloads as JSON, and the values compared with the run's own record (its
run.mcap, read by usv_mj.outputs.log.read_run). Loopback only; every wait is for a condition, bounded.
"""

from __future__ import annotations

import asyncio
import base64
import json
import math
import os
import re
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

pytest.importorskip("foxglove", reason='pip install "usv_mj[live]"')
websockets = pytest.importorskip("websockets")

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TIMEOUT_S = 240.0


def _decoder(channel):
    if channel["encoding"] == "json":
        return lambda data: json.loads(data)
    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for f in fds.file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
    return lambda data: cls.FromString(data)


async def _client(port: int, want: set, ends: frozenset = frozenset({"/usv/events"}), got: dict | None = None) -> dict:
    """Subscribe to every channel as it is advertised (the SDK advertises them one by one); collect the
    decoded messages by topic (into ``got`` if given: what came before a timeout) until the run_end
    event of every events topic of ``ends`` (a fleet: one per vessel). ``want``: topics that must be
    advertised."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"],
                                  max_size=None) as ws:
        assert ws.subprotocol == "foxglove.sdk.v1"
        subs, decoders, ended = {}, {}, set()
        got = {} if got is None else got
        while True:
            frame = await ws.recv()
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg["op"] == "status":      # e.g. "Unknown channel ID": a subscription refused
                    got.setdefault("status", []).append(msg)
                if msg["op"] == "advertise":
                    new = []
                    for c in msg["channels"]:
                        sid = len(subs) + 1
                        subs[sid], decoders[sid] = c, _decoder(c)
                        got.setdefault(c["topic"], [])
                        new.append({"id": sid, "channelId": c["id"]})
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
                continue
            if frame[0] != 1:        # 1: Message Data
                continue
            sub, stamp = struct.unpack_from("<IQ", frame, 1)
            value = decoders[sub](frame[13:])
            topic = subs[sub]["topic"]
            got[topic].append((stamp, value))
            got.setdefault("wall", []).append(time.monotonic())
            if topic in ends and value.get("kind") == "run_end":
                ended.add(topic)
                if ended == set(ends):
                    assert want <= set(got), sorted(got)
                    return got


def _wait_for_url(proc, lines: list) -> int:
    """Read the command's stderr until it waits for a viewer on its live URL (its channels are then
    advertised: a client subscribing while the SDK still advertises them can be told "unknown
    channel", foxglove-sdk 0.30.3); keep reading it in a thread."""
    found = threading.Event()
    port = []

    def pump():
        for line in proc.stderr:
            lines.append(line)
            m = re.search(r"waiting for a viewer on ws://127\.0\.0\.1:(\d+)", line)
            if m and not port:
                port.append(int(m.group(1)))
                found.set()
        found.set()

    threading.Thread(target=pump, daemon=True).start()
    assert found.wait(TIMEOUT_S), "the command never said where it serves"
    assert port, "".join(lines)
    return port[0]


def test_run_live_serves_the_record(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", "run", "--live", "--live-port", "0", "--duration", "5",
                             "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--out", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list = []
    try:
        port = _wait_for_url(proc, lines)
        got = asyncio.run(asyncio.wait_for(_client(port, {"/usv/state", "/usv/control", "/usv/tf/hull"}), TIMEOUT_S))
        assert proc.wait(TIMEOUT_S) == 0, "".join(lines)
    finally:
        if proc.poll() is None:
            proc.kill()
    from usv_mj.outputs.log import read_run

    record = read_run(out / "run.mcap").record
    t = record["t"]
    n = len(t)
    assert n == 5001
    # every per-step message, in order, with the record's values bit for bit
    state = got["/usv/state"]
    assert len(state) == n
    for name in ("t", "x", "y", "psi", "u", "v", "r"):
        assert np.array_equal(np.array([getattr(m, name) for _, m in state]), record[name]), name
    assert [s for s, _ in state] == [round(v * 1e9) for v in t]
    control = got["/usv/control"]
    assert len(control) == n
    for name in ("tau_u", "tau_r", "f_u", "f_r"):
        assert np.array_equal(np.array([getattr(m, name) for _, m in control]), record[name]), name
    # the hull frame every 20 ms: map -> base_link at (x, y), yaw psi
    tf = got["/usv/tf/hull"]
    assert len(tf) == 251
    for stamp, m in tf:
        k = int(round(stamp * 1e-9 / 1e-3))
        assert m["parent_frame_id"] == "map" and m["child_frame_id"] == "base_link"
        assert m["translation"]["x"] == pytest.approx(record["x"][k], abs=1e-12)
        assert m["translation"]["y"] == pytest.approx(record["y"][k], abs=1e-12)
        assert m["rotation"]["z"] == pytest.approx(math.sin(record["psi"][k] / 2), abs=1e-12)
        assert m["rotation"]["w"] == pytest.approx(math.cos(record["psi"][k] / 2), abs=1e-12)
    assert got["/usv/errors"], "the funnel errors are served"


FLEET_ENDS = frozenset({"/usv/events", "/target/usv/events"})


def _served(args: list, want: set, ends: frozenset) -> dict:
    """Start ``usv-mj ARGS`` (which serves on --live-port 0), collect what a client gets until the
    run_end of every events topic of ``ends``, and wait for the command's exit 0. Every wait is
    bounded (TIMEOUT_S); a timeout names the topics and the run_end events received so far."""
    proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    lines: list = []
    got: dict = {}
    try:
        port = _wait_for_url(proc, lines)
        try:
            asyncio.run(asyncio.wait_for(_client(port, want, ends, got), TIMEOUT_S))
        except asyncio.TimeoutError:
            seen = {t: len(v) for t, v in got.items() if t not in ("wall", "status")}
            ended = sorted(t for t in ends if any(isinstance(m, dict) and m.get("kind") == "run_end"
                                                  for _, m in got.get(t, [])))
            pytest.fail(f"no run_end on every one of {sorted(ends)} within {TIMEOUT_S:g} s (run_end on {ended}); "
                        f"received {seen}; status {got.get('status')}; stderr: {''.join(lines)}")
        assert proc.wait(TIMEOUT_S) == 0, "".join(lines)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert not got.get("status"), got["status"]      # every subscription taken
    return got


def test_run_live_serves_every_vessel_of_a_fleet(tmp_path):
    """A fleet's run served live (issue 35): every vessel's state and hull frame on its own topics
    (the own ship's under /usv, the target's under /target/usv with frame target/base_link), each
    equal to that vessel's run in the logs written beside it, bit for bit; then the log replayed
    (``usv-mj render run.mcap --live``) serves the other vessel's file with the own ship's, each
    message on its own vessel's topic. Before: the replay served every file's messages on the last
    file's channels (a generator expression's late binding), so /usv/events never had its run_end
    and the client waited until its timeout."""
    out = tmp_path / "fleet"
    scenario = os.path.join(ROOT, "examples", "scenarios", "head_on_no_avoidance.toml")
    want = {"/usv/state", "/usv/tf/hull", "/target/usv/state", "/target/usv/tf/hull"}
    got = _served(["run", "--scenario", scenario, "--live", "--live-port", "0", "--duration", "1", "--plant",
                   "analytic", "--no-video", "-q", "--out", str(out)], want, FLEET_ENDS)
    from usv_mj.outputs.log import read_run

    log = read_run(out / "run.mcap")
    for prefix, run, frame in (("/usv", "main", "base_link"), ("/target/usv", "target", "target/base_link")):
        record = log.runs[run]
        state = got[f"{prefix}/state"]
        assert len(state) == len(record["t"]) == 101, (run, {t: len(v) for t, v in got.items()})  # 1 s at 10 ms
        for name in ("x", "y", "psi"):
            assert np.array_equal(np.array([getattr(m, name) for _, m in state]), record[name]), (run, name)
        assert {m["child_frame_id"] for _, m in got[f"{prefix}/tf/hull"]} == {frame}
    # the two vessels close head-on: the target starts 30 m north of the own ship, both heading for the other
    own, target = got["/usv/state"], got["/target/usv/state"]
    assert target[0][1].y - own[0][1].y == 30.0 and target[-1][1].y - own[-1][1].y < 30.0
    # the log replayed: the same messages on the same topics, the other vessel's file with the own ship's
    again = _served(["render", str(out / "run.mcap"), "--live", "--live-port", "0"], want, FLEET_ENDS)
    for prefix, frame in (("/usv", "base_link"), ("/target/usv", "target/base_link")):
        for name in ("x", "y", "psi"):
            assert ([getattr(m, name) for _, m in again[f"{prefix}/state"]]
                    == [getattr(m, name) for _, m in got[f"{prefix}/state"]]), (prefix, name)
        assert {m["child_frame_id"] for _, m in again[f"{prefix}/tf/hull"]} == {frame}
        assert [m.get("kind") for _, m in again[f"{prefix}/events"]][-1] == "run_end"


def test_missing_sdk_is_one_line(tmp_path):
    """Without foxglove-sdk: one line naming the pip extra, exit 2 (a stub on sys.path hides the package)."""
    stub = tmp_path / "stub"
    stub.mkdir()
    (stub / "foxglove.py").write_text("raise ImportError('hidden for the test')\n")
    env = dict(os.environ, PYTHONPATH=f"{stub}{os.pathsep}{ROOT}")
    res = subprocess.run([sys.executable, "-m", "usv_mj.cli.main", "run", "--live", "--duration", "1", "--no-video",
                          "--out", str(tmp_path / "r")], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=TIMEOUT_S)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == ['usv-mj run: error: live viewing needs the foxglove-sdk package: '
                                               'pip install "usv_mj[live]"']


@pytest.mark.parametrize("speed", [None, 2.0])
def test_render_live_replays_a_log(tmp_path, speed):
    """`usv-mj render RUN.mcap --live`: the log's messages again, the same values; at --speed X
    the 2 s of the log take 2 / X s of wall time."""
    from usv_mj import load_scenario, simulate
    from usv_mj.outputs.log import RunLogWriter

    scenario = load_scenario(overrides={"duration": 2.0, "plant": {"kind": "analytic"}})
    with RunLogWriter(tmp_path / "run.mcap", scenario, background=False) as writer:
        record = simulate(scenario, sinks=[writer.sink("main")])
    proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", "render", str(tmp_path / "run.mcap"), "--live",
                             "--live-port", "0"] + (["--speed", str(speed)] if speed else []), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list = []
    try:
        port = _wait_for_url(proc, lines)
        got = asyncio.run(asyncio.wait_for(_client(port, {"/usv/state", "/usv/control"}), TIMEOUT_S))
        assert proc.wait(TIMEOUT_S) == 0, "".join(lines)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert np.array_equal(np.array([m.x for _, m in got["/usv/state"]]), record["x"])
    assert np.array_equal(np.array([m.f_u for _, m in got["/usv/control"]]), record["f_u"])
    if speed:
        wall = got["wall"][-1] - got["wall"][0]
        assert 0.9 * 2.0 / speed < wall < 2.0 / speed + 5.0, wall


def test_env_live_serves_each_episode(tmp_path):
    """`usv-mj env track --live`: the episode's rows as the run log's topics, the frames consistent with them."""
    proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", "env", "track", "--policy", "ppc", "--duration", "3",
                             "--video", "none", "--live", "--live-port", "0"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    lines: list = []
    try:
        port = _wait_for_url(proc, lines)
        got = asyncio.run(asyncio.wait_for(_client(port, {"/usv/state", "/usv/control", "/usv/tf/hull"}), TIMEOUT_S))
        assert proc.wait(TIMEOUT_S) == 0, "".join(lines)
    finally:
        if proc.poll() is None:
            proc.kill()
    t = np.array([m.t for _, m in got["/usv/state"]])
    assert t[0] == 0.0 and t[-1] == pytest.approx(3.0, abs=1e-9)
    assert np.allclose(np.diff(t), t[1] - t[0])
    assert [s for s, _ in got["/usv/state"]] == [round(v * 1e9) for v in t]
    x = {s: m.x for s, m in got["/usv/state"]}
    for stamp, m in got["/usv/tf/hull"]:
        assert m["translation"]["x"] == x[stamp]
    assert len(got["/usv/control"]) == len(t)


# --- the subprotocol names a viewer may offer (issue 34) ----------------------------------------------


def _probe(offer):
    """Connect offering ``offer`` (subprotocols), subscribe to /probe, and return (the subprotocol the
    server chose, the serverInfo, the payload of the first message): one JSON message is logged on
    /probe once the server has seen the subscription."""
    import foxglove

    from usv_mj.outputs.log.live import LiveServer

    server = LiveServer(port=0, wait_s=TIMEOUT_S, say=lambda text: None)
    schema = foxglove.Schema(name="Probe", encoding="jsonschema", data=b'{"type": "object"}')
    channel = foxglove.Channel("/probe", schema=schema, message_encoding="json", context=server.context)

    def publish():                       # once subscribed (a bounded wait on the server's own condition)
        if server.wait_for_viewer():
            channel.log(b'{"k": 42}', log_time=7)

    async def client():
        async with websockets.connect(server.url, subprotocols=offer) as ws:
            info = json.loads(await ws.recv())
            while True:
                frame = await ws.recv()
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    if msg["op"] == "advertise":
                        ids = [c["id"] for c in msg["channels"] if c["topic"] == "/probe"]
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 9, "channelId": ids[0]}]}))
                    continue
                assert frame[0] == 1 and struct.unpack_from("<IQ", frame, 1) == (9, 7)
                return ws.subprotocol, info, json.loads(frame[13:])

    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    try:
        return asyncio.run(asyncio.wait_for(client(), TIMEOUT_S))
    finally:   # (a refused client leaves publish() waiting: a daemon thread, bounded by wait_s)
        server.close()


@pytest.mark.parametrize("offer, chosen", [
    (["foxglove.sdk.v1"], "foxglove.sdk.v1"),                            # the Foxglove app (foxglove-sdk's name)
    (["foxglove.websocket.v1"], "foxglove.websocket.v1"),                # Studio <= 1.87, ws-protocol clients
    (["foxglove.websocket.v1", "foxglove.sdk.v1"], "foxglove.sdk.v1"),   # a client offering both
])
def test_a_viewer_offering_either_subprotocol_is_served(offer, chosen):
    """The live server answers with a subprotocol the viewer offered, and the protocol works under it:
    serverInfo, advertise, subscribe, and a Message Data frame (opcode 1, subscription id, log time, payload).
    Before, foxglove-sdk's server answered a foxglove.websocket.v1 offer with HTTP 400."""
    subprotocol, info, payload = _probe(offer)
    assert subprotocol == chosen
    assert info["op"] == "serverInfo" and info["name"] == "usv_mj"
    assert payload == {"k": 42}


@pytest.mark.parametrize("offer", [["foxglove.websocket.v2"], None])
def test_a_viewer_offering_no_foxglove_subprotocol_gets_400(offer):
    from usv_mj.outputs.log.live import LiveServer

    server = LiveServer(port=0, wait_s=0, say=lambda text: None)

    async def connect():
        async with websockets.connect(server.url, subprotocols=offer):
            pass

    try:
        with pytest.raises(websockets.exceptions.InvalidStatus) as err:
            asyncio.run(asyncio.wait_for(connect(), TIMEOUT_S))
        assert err.value.response.status_code == 400
    finally:
        server.close()
