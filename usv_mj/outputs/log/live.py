"""Live in Foxglove: the run log's messages served over the Foxglove WebSocket protocol as they are written.

``usv-mj run --live`` (and ``usv-mj render RUN.mcap --live``, a replay) serve the same topics,
schemas and messages as the MCAP log (:mod:`usv_mj.outputs.log.topics`): nothing is encoded twice. The
run log's writer (:class:`usv_mj.outputs.log.writer.RunLogWriter` with ``live=``) hands every chunk it
writes to :meth:`LiveServer.chunk` before compressing it; the server walks the chunk's MCAP message
records (op 0x05: channel u16, sequence u32, log time u64, publish time u64, data) and logs each
one's bytes on a ``foxglove.Channel`` made from the file's own channel and schema records
(the ``foxglove-sdk`` package, ``pip install "usv_mj[live]"``).

Pacing: ``speed`` = None logs as fast as the run makes rows (each viewer has a deep buffer,
:data:`BACKLOG`; when a viewer falls further behind, its oldest messages are dropped, the log file
is always written in full); ``speed`` = X holds log time / X to the wall clock (1: real time).
The server waits for a viewer to subscribe (up to ``wait_s`` [s], a finite number >= 0; None: until
one does) once the first run's channels are in the file, every vessel's for a fleet (one file per
vessel, :meth:`LiveServer.attach`; :meth:`LiveServer.ready`, before the run's first step), so that a
viewer opened after the command sees the run from its start, every vessel on its own topics; Ctrl-C
or SIGTERM stops the wait (and the run). ``usv-mj render RUN.mcap --live`` replays the file with its
companions (a fleet's other vessels, the baseline) merged in log-time order. Loopback (127.0.0.1)
only by default.

Subprotocols: a viewer names the protocol in its WebSocket handshake. foxglove-sdk's server accepts
``foxglove.sdk.v1`` only, and answers any other offer with HTTP 400 (its handshake,
``rust/foxglove/src/websocket/handshake.rs``, a constant the Python API cannot change): what the
Foxglove app offers since the SDK (and foxglove_bridge 3) came. Foxglove Studio up to 1.87, Lichtblick
before its ``foxglove.sdk.v1`` support and other ``@foxglove/ws-protocol`` clients offer
``foxglove.websocket.v1`` only: the same protocol under its first name (the ws-protocol
specification; Foxglove's own word is that the two are identical for now). So the port the user
names is a small loopback relay (:class:`_SubprotocolRelay`) in front of the SDK's server: a
handshake offering ``foxglove.websocket.v1`` without ``foxglove.sdk.v1`` is passed on as
``foxglove.sdk.v1`` and answered with the name the viewer offered; every byte after the handshake is
passed on as it is. :data:`SUBPROTOCOLS` are the names accepted; any other offer still gets HTTP 400.
"""

from __future__ import annotations

import heapq
import itertools
import struct
import sys
import threading
import time
from contextlib import ExitStack
from pathlib import Path

from usv_mj.core.errors import ScenarioError
from usv_mj.outputs.log.reader import companion_files

DEFAULT_PORT = 8765
BACKLOG = 1 << 17        # messages buffered per viewer before the oldest are dropped
SETTLE_S = 0.3           # after the first subscription, wait until none came for this long (max 2 s)
_MESSAGE = 0x05
_HEAD = struct.Struct("<BQHIQQ")   # opcode, record length, channel, sequence, log time, publish time
INSTALL_HINT = 'live viewing needs the foxglove-sdk package: pip install "usv_mj[live]"'
SDK_SUBPROTOCOL = "foxglove.sdk.v1"              # the only name foxglove-sdk's server accepts
OLD_SUBPROTOCOL = "foxglove.websocket.v1"        # the ws-protocol specification's name of the same protocol
SUBPROTOCOLS = (SDK_SUBPROTOCOL, OLD_SUBPROTOCOL)
HANDSHAKE_LIMIT = 64 * 1024                      # bytes of an HTTP upgrade request or response head
HANDSHAKE_S = 10.0                               # s to receive a handshake before the connection is dropped


def layout_path() -> str:
    """The Foxglove layout shipped with the package (3D scene, errors against the funnel, forces)."""
    from importlib import resources

    return str(resources.files("usv_mj.outputs.log") / "foxglove_layout.json")


class LiveUnavailable(ScenarioError):
    """foxglove-sdk is not installed (the CLI says so in one line, exit 2)."""


def import_foxglove():
    try:
        import foxglove
    except ImportError:
        raise LiveUnavailable(INSTALL_HINT) from None
    return foxglove


class _Listener:
    """Counts the viewers' subscriptions (the SDK calls these from its own thread)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.subs: set = set()
        self.changed = threading.Condition(self.lock)
        self.last_change = 0.0
        self.ever = False

    def on_subscribe(self, client, channel):
        with self.lock:
            self.subs.add((client.id, channel.id))
            self.ever = True
            self.last_change = time.monotonic()
            self.changed.notify_all()

    def on_unsubscribe(self, client, channel):
        with self.lock:
            self.subs.discard((client.id, channel.id))
            self.last_change = time.monotonic()
            self.changed.notify_all()


def _head(sock, limit: int = HANDSHAKE_LIMIT) -> tuple[bytes, bytes]:
    """Read an HTTP head (to its blank line) from ``sock``: (head with its blank line, bytes after it)."""
    buf = b""
    while b"\r\n\r\n" not in buf:
        if len(buf) > limit:
            raise OSError("handshake too long")
        data = sock.recv(4096)
        if not data:
            raise OSError("closed during the handshake")
        buf += data
    end = buf.index(b"\r\n\r\n") + 4
    return buf[:end], buf[end:]


def _protocol_lines(head: bytes) -> tuple[list, list]:
    """(the head's lines, the tokens of its Sec-WebSocket-Protocol headers)."""
    lines = head[:-4].split(b"\r\n")
    tokens = []
    for line in lines[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"sec-websocket-protocol":
            tokens += [t.strip().decode("latin-1") for t in value.split(b",") if t.strip()]
    return lines, tokens


def _with_protocol(lines: list, protocol: str) -> bytes:
    """The head of ``lines`` with one Sec-WebSocket-Protocol header, ``protocol``."""
    kept = [l for l in lines if l.partition(b":")[0].strip().lower() != b"sec-websocket-protocol"]
    return b"\r\n".join(kept + [b"Sec-WebSocket-Protocol: " + protocol.encode()]) + b"\r\n\r\n"


class _SubprotocolRelay:
    """The TCP port viewers connect to, passing every connection on to the SDK's server on
    ``inner_port`` (127.0.0.1), with the handshake of a ``foxglove.websocket.v1`` viewer renamed
    (module docstring). A thread accepts; two threads a connection copy bytes until either side closes."""

    def __init__(self, host: str, port: int, inner_port: int):
        import socket

        self.inner_port = inner_port
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.listener = socket.create_server((host, port), family=family)
        self.port = self.listener.getsockname()[1]
        self._open: set = set()
        self._lock = threading.Lock()
        self._closed = False
        threading.Thread(target=self._accept, name="usv_mj-live-relay", daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:   # closed
                return
            threading.Thread(target=self._serve, args=(client,), daemon=True).start()

    def _track(self, *socks) -> bool:
        with self._lock:
            if self._closed:
                return False
            self._open.update(socks)
            return True

    def _serve(self, client) -> None:
        import socket

        upstream = None
        try:
            if not self._track(client):
                client.close()
                return
            client.settimeout(HANDSHAKE_S)
            head, rest = _head(client)
            lines, offered = _protocol_lines(head)
            alias = OLD_SUBPROTOCOL if OLD_SUBPROTOCOL in offered and SDK_SUBPROTOCOL not in offered else None
            if alias:
                head = _with_protocol(lines, SDK_SUBPROTOCOL)
            upstream = socket.create_connection(("127.0.0.1", self.inner_port), timeout=HANDSHAKE_S)
            if not self._track(upstream):
                return
            upstream.sendall(head + rest)
            head, rest = _head(upstream)
            if alias:
                lines, chosen = _protocol_lines(head)
                if chosen == [SDK_SUBPROTOCOL]:
                    head = _with_protocol(lines, alias)
            client.sendall(head + rest)
            client.settimeout(None)
            upstream.settimeout(None)
            back = threading.Thread(target=self._pipe, args=(upstream, client), daemon=True)
            back.start()
            self._pipe(client, upstream)
            back.join()
        except OSError:
            pass
        finally:
            for sock in (client, upstream):
                if sock is not None:
                    with self._lock:
                        self._open.discard(sock)
                    sock.close()

    @staticmethod
    def _pipe(src, dst) -> None:
        import socket

        try:
            while True:
                data = src.recv(65536)
                if not data:
                    break
                dst.sendall(data)
        except OSError:
            pass
        for sock in (dst, src):   # one side ended: end the other, so its pipe ends too
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def close(self) -> None:
        import socket

        with self._lock:
            self._closed = True
            socks = list(self._open)
        try:   # wakes the thread blocked in accept(): close() alone leaves it blocked for the process's life
            self.listener.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.listener.close()
        for sock in socks:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass


class LiveServer:
    """A Foxglove WebSocket server fed with MCAP chunks (module docstring).

    ``host`` / ``port`` [TCP; 0: any free port, see :attr:`port`], ``speed`` (None: unpaced; X > 0:
    log time / X), ``wait_s`` [s] (None: wait for a viewer as long as it takes; 0: do not wait).
    """

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1", speed: float | None = None,
                 wait_s: float | None = None, say=None):
        if speed is not None and not (speed > 0 and speed < float("inf")):
            raise ScenarioError(f"--speed {speed!r}: must be a finite number > 0 (1 = real time)")
        if wait_s is not None and not (isinstance(wait_s, (int, float)) and 0 <= wait_s < float("inf")):
            raise ScenarioError(f"--live-wait {wait_s!r}: must be a finite number of seconds >= 0 (leave it out "
                                "to wait until a viewer comes)")
        if not (isinstance(port, int) and 0 <= port < 65536):
            raise ScenarioError(f"--live-port {port!r}: must be a TCP port, 0 to 65535")
        foxglove = import_foxglove()
        self._fg = foxglove
        self.speed, self.wait_s = speed, wait_s
        self._say = say or (lambda text: print(text, file=sys.stderr, flush=True))
        self.context = foxglove.Context()
        self.listener = _Listener()
        try:   # the SDK's server on a free loopback port, behind the relay on the user's (module docstring)
            self.server = foxglove.start_server(name="usv_mj", host="127.0.0.1", port=0, context=self.context,
                                                server_listener=self.listener, message_backlog_size=BACKLOG)
        except Exception as exc:  # noqa: BLE001 - the SDK raises its own error types
            raise ScenarioError(f"--live-port {port}: cannot start the Foxglove server ({exc})") from None
        try:
            self.relay = _SubprotocolRelay(host, port, int(self.server.port))
        except OSError as exc:
            self.server.stop()
            raise ScenarioError(f"--live-port {port}: cannot serve on {host}:{port} ({exc})") from None
        self.host, self.port = host, int(self.relay.port)
        self._channels: dict = {}      # (id of the file writer, MCAP channel id) -> foxglove.Channel
        self._writers: list = []       # the file writers that feed this server (attach): a fleet's several
        self._waited = False
        self._clock: dict = {}         # per file: (wall [s], log time [ns]) of its first message paced
        self.sent = 0

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    # --- fed by the run log's writer ---------------------------------------------------------------

    def _channel(self, writer, cid: int):
        key = (id(writer), cid)
        ch = self._channels.get(key)
        if ch is None:
            rec = writer.channels[cid]
            schema = writer.schemas.get(rec.schema_id)
            fg_schema = None if schema is None else self._fg.Schema(name=schema.name, encoding=schema.encoding,
                                                                    data=schema.data)
            ch = self._fg.Channel(rec.topic, schema=fg_schema, message_encoding=rec.message_encoding,
                                  context=self.context, metadata={str(k): str(v) for k, v in rec.metadata.items()})
            self._channels[key] = ch
        return ch

    def attach(self, writer) -> None:
        """Serve the chunks of the MCAP file ``writer`` (a
        :class:`usv_mj.outputs.log.mcap_file.McapFileWriter`) too: a fleet's run writes one file per
        vessel. Every attached file's channels are advertised by :meth:`ready`, so a viewer that came
        for one vessel is offered all of them before the first message."""
        if all(w is not writer for w in self._writers):
            self._writers.append(writer)

    def ready(self, writer, serving: bool = False) -> None:
        """Advertise the channels of every attached MCAP file (``writer``'s among them) and wait for a
        viewer (:meth:`wait_for_viewer`; a KeyboardInterrupt, Ctrl-C or SIGTERM, ends the wait) once
        every attached file has its channels (a fleet: each vessel's run has started), or, with
        ``serving``, before the first message is served whatever the others hold. Channels made while
        a viewer is connected (the baseline's after the main run) are advertised and the viewer is
        given time to subscribe to them (:meth:`_settle`): foxglove-sdk 0.30.3 may answer a viewer
        that subscribes at once to a channel it has just advertised "Unknown channel ID", so the
        channels are best all made before the viewer comes."""
        self.attach(writer)
        known = len(self._channels)
        for w in self._writers:          # every channel is advertised before its first message
            for cid in list(w.channels):
                self._channel(w, cid)
        if not self._waited:
            if self._channels and (serving or all(w.channels for w in self._writers)):
                self._waited = True
                self.wait_for_viewer()
        elif len(self._channels) > known:
            self._settle()

    def chunk(self, writer, parts) -> None:
        """Log every message of one uncompressed chunk (``parts``: its bytes / uint8 arrays in order)
        of the MCAP file ``writer`` (a :class:`usv_mj.outputs.log.mcap_file.McapFileWriter`)."""
        self.ready(writer, serving=True)
        data = memoryview(b"".join(bytes(p) for p in parts))
        pos, end, head = 0, len(data), _HEAD.size
        while pos < end:
            op, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
            if op == _MESSAGE:
                _, _, cid, _, log_time, _ = _HEAD.unpack_from(data, pos)
                self._pace(id(writer), log_time)
                self._channel(writer, cid).log(bytes(data[pos + head:pos + 9 + length]), log_time=log_time)
                self.sent += 1
            pos += 9 + length

    def replay(self, path) -> int:
        """Serve the messages of the MCAP file ``path`` and of its companions (the baseline's log, a
        fleet's other vessels: :func:`usv_mj.outputs.log.reader.companion_files`) merged in log-time
        order, as :meth:`chunk` serves a run's (``usv-mj render RUN.mcap --live``); returns the
        number of messages served. Every file's channels are advertised before the wait for a viewer.
        A file without a readable summary (a cut or damaged log) is served front to back up to where
        it ends or is damaged, and the server says so (as ``render`` draws what such a log holds)."""
        with ExitStack() as stack:
            streams = [self._replay_file(k, file, stack.enter_context(open(file, "rb")))
                       for k, file in enumerate([Path(path), *companion_files(path)])]
            merged = heapq.merge(*streams, key=lambda e: (e[0], e[1]))
            first = next(merged, None)   # every file read up to its first message: all channels advertised
            self._waited = True
            self.wait_for_viewer()
            for log_time, _, channel, data in itertools.chain([first] if first is not None else [], merged):
                self._pace("replay", log_time)
                channel.log(data, log_time=log_time)
                self.sent += 1
        return self.sent

    def _replay_channel(self, k: int, rec, schema):
        """The foxglove.Channel of channel record ``rec`` of the ``k``-th file replayed, advertised now."""
        fg_schema = None if schema is None else self._fg.Schema(name=schema.name, encoding=schema.encoding,
                                                                data=schema.data)
        ch = self._fg.Channel(rec.topic, schema=fg_schema, message_encoding=rec.message_encoding,
                              context=self.context, metadata=dict(rec.metadata))
        self._channels[(f"replay{k}", rec.id)] = ch
        return ch

    def _replay_file(self, k: int, path, f):
        """The messages of the ``k``-th file of :meth:`replay`, ``path`` open as ``f``, in log-time
        order: (log time [ns], k, foxglove.Channel, data). Its channels are advertised before its
        first message is yielded."""
        from mcap.reader import make_reader

        try:
            summary = make_reader(f).get_summary()
        except Exception:  # noqa: BLE001 - the mcap library's errors of a cut or damaged file
            summary = None
        f.seek(0)
        if summary is None:
            yield from self._replay_stream(k, path, f)
            return
        reader = make_reader(f)
        chans = {cid: self._replay_channel(k, rec, summary.schemas.get(rec.schema_id))
                 for cid, rec in summary.channels.items()}
        served = 0
        try:
            for _, channel, message in reader.iter_messages(log_time_order=True):
                yield message.log_time, k, chans[channel.id], message.data
                served += 1
        except Exception as exc:  # noqa: BLE001 - a damaged chunk inside a file with a summary
            self._say(f"live: {path} is damaged after {served} messages ({type(exc).__name__}: "
                      f"{' '.join(str(exc).split())[:120]}); served what comes before")

    def _replay_stream(self, k: int, path, f):
        """:meth:`_replay_file` of a file without a readable summary: its records front to back (the
        run log's writer writes each file in log-time order) until the file ends or is damaged. A
        channel that first appears after the viewer subscribed is advertised with time to subscribe."""
        from mcap.records import Channel, Message, Schema
        from mcap.stream_reader import StreamReader

        schemas, chans = {}, {}
        served = 0
        problem = "it has no summary (an unfinished file)"
        try:
            for rec in StreamReader(f, record_size_limit=1 << 32).records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    chans[rec.id] = self._replay_channel(k, rec, schemas.get(rec.schema_id))
                    if self._waited:
                        self._settle()
                elif isinstance(rec, Message) and rec.channel_id in chans:
                    yield rec.log_time, k, chans[rec.channel_id], rec.data
                    served += 1
        except Exception as exc:  # noqa: BLE001 - where the cut or the damage is
            problem = f"it ends or is damaged there ({type(exc).__name__})"
        self._say(f"live: {path} is cut short: served the {served} messages it holds; {problem}")
        return self.sent

    def _pace(self, key, log_time: int) -> None:
        """Sleep until ``log_time`` [ns] is due at ``speed`` (each file's clock starts at its first
        message: the baseline's file starts at t = 0 again)."""
        if self.speed is None:
            return
        now = time.monotonic()
        clock = self._clock.setdefault(key, (now, log_time))
        ahead = (log_time - clock[1]) * 1e-9 / self.speed - (now - clock[0])
        if ahead > 2e-3:
            time.sleep(ahead)

    # --- viewers -----------------------------------------------------------------------------------

    def wait_for_viewer(self) -> bool:
        """Block until a viewer subscribes to a channel and its subscriptions have settled, or until
        ``wait_s``; True if one did."""
        lis = self.listener
        if self.wait_s is not None and self.wait_s <= 0:
            return bool(lis.subs)
        self._say(f"live: waiting for a viewer on {self.url} (Foxglove: Open connection, Foxglove WebSocket"
                  + (f"; going on without one after {self.wait_s:g} s)" if self.wait_s is not None else
                     "; Ctrl-C stops)"))
        deadline = None if self.wait_s is None else time.monotonic() + self.wait_s
        with lis.lock:
            while not lis.subs:
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    self._say("live: no viewer came; the run goes on (the log is written in full)")
                    return False
                lis.changed.wait(0.2 if left is None else min(0.2, left))
            first = time.monotonic()
            while time.monotonic() - lis.last_change < SETTLE_S and time.monotonic() - first < 2.0:
                lis.changed.wait(SETTLE_S)
        self._say(f"live: a viewer is subscribed to {len(lis.subs)} channels")
        return True

    def _settle(self) -> None:
        """After channels were advertised to a subscribed viewer: wait until its subscriptions changed
        and then held still for SETTLE_S (at most 2 s; a viewer that wants none of them costs the 2 s)."""
        lis = self.listener
        with lis.lock:
            if not lis.subs:
                return
            start, before = time.monotonic(), lis.last_change
            while time.monotonic() - start < 2.0:
                if lis.last_change > before and time.monotonic() - lis.last_change >= SETTLE_S:
                    return
                lis.changed.wait(SETTLE_S)

    def finish(self, linger_s: float | None = None) -> None:
        """After the run: serve until every viewer has gone (or ``linger_s`` [s]), then stop."""
        lis = self.listener
        if lis.subs:
            self._say(f"live: the run is over ({self.sent} messages served); serving until the viewer "
                      f"disconnects (Ctrl-C stops)")
            deadline = None if linger_s is None else time.monotonic() + linger_s
            try:
                with lis.lock:
                    while lis.subs and (deadline is None or time.monotonic() < deadline):
                        lis.changed.wait(0.2)
            except KeyboardInterrupt:   # Ctrl-C ends the serving, not the run (it is over and written)
                self._say("live: stopped serving (Ctrl-C)")
        self.close()

    def close(self) -> None:
        for ch in self._channels.values():
            ch.close()
        self._channels.clear()
        self.relay.close()
        self.server.stop()
