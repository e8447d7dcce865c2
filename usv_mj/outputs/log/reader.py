"""Reading a run log back: whole runs as :class:`~usv_mj.record.run_record.RunRecord`, or one topic as arrays.

The file is read front to back (``mcap.stream_reader.StreamReader``, which also works on a
non-seekable stream), chunk by chunk. What is checked before a file is called complete: every
chunk's CRC (of its uncompressed records), the data section's CRC (in the DataEnd record: it
covers the header, schemas, channels, metadata and indexes), the summary's CRC (in the footer) and
the closing magic. A file that ends early (a killed process: no summary, maybe half a chunk) is read
up to its last complete chunk and :attr:`RunLog.truncated` says so; a damaged chunk stops the
reading there; a damage outside the chunks sets :attr:`RunLog.damaged`. :attr:`RunLog.notice` is
the one line the commands print about it. Messages outside chunks (an unchunked MCAP) are read
too. Each topic comes back in log-time order (a stable sort when the file holds it otherwise).
Numbers come back bit-exactly (see :mod:`usv_mj.outputs.log.topics` for the NaN / infinity convention).

Memory: a row topic is decoded chunk by chunk into one growing (rows x fields) array
(:class:`_Rows`, grown in place by ``realloc``), not into per-chunk pieces joined at the end, so
reading a run needs about the record's own size twice (the topic arrays and the RunRecord).
"""

from __future__ import annotations

import io
import stat
import json
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.records import Attachment, Channel, Chunk, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from numba import njit

from usv_mj.outputs.log import json_codec, protobuf_rows
from usv_mj.outputs.log.mcap_file import message_record

from usv_mj.record.run_record import COL, CORE_COLUMNS, Event, RunRecord
from usv_mj.outputs.log.extra_topics import environment_arrays, obstacle_arrays
from usv_mj.outputs.log.topics import ROW_SCHEMAS, prefix_for, row_topics

MAGIC = b"\x89MCAP0\r\n"


class RunLogReadError(ValueError):
    """The file is missing, is not an MCAP file, or holds no run; the message names the file."""


@njit(cache=True)
def _walk_records(buf):
    """Positions of the records in an uncompressed chunk: (opcode, start, end, channel, log_time) per record."""
    n = buf.shape[0]
    cap = 1024
    op = np.empty(cap, np.int64)
    start = np.empty(cap, np.int64)
    end = np.empty(cap, np.int64)
    chan = np.empty(cap, np.int64)
    lt = np.empty(cap, np.int64)
    p = 0
    k = 0
    while p + 9 <= n:
        length = 0
        for b in range(8):
            length |= np.int64(buf[p + 1 + b]) << (8 * b)
        if k == cap:
            cap *= 2
            op = np.concatenate((op, np.empty(cap - k, np.int64)))
            start = np.concatenate((start, np.empty(cap - k, np.int64)))
            end = np.concatenate((end, np.empty(cap - k, np.int64)))
            chan = np.concatenate((chan, np.empty(cap - k, np.int64)))
            lt = np.concatenate((lt, np.empty(cap - k, np.int64)))
        op[k] = buf[p]
        start[k] = p + 9
        end[k] = min(p + 9 + length, n)
        if buf[p] == 5 and length >= 22:
            chan[k] = np.int64(buf[p + 9]) | (np.int64(buf[p + 10]) << 8)
            t = 0
            for b in range(8):
                t |= np.int64(buf[p + 15 + b]) << (8 * b)
            lt[k] = t
            start[k] = p + 31
        else:
            chan[k] = -1
            lt[k] = 0
        k += 1
        p += 9 + length
    return op[:k], start[:k], end[:k], chan[:k], lt[:k]


@njit(cache=True)
def _gather(buf, starts, ends, out):
    """Concatenate buf[starts[i]:ends[i]] with ',' between into out; return the length."""
    p = 0
    for i in range(starts.shape[0]):
        if i:
            out[p] = 44
            p += 1
        for b in range(starts[i], ends[i]):
            out[p] = buf[b]
            p += 1
    return p


@njit(cache=True)
def _gather_values(buf, starts, ends, out):
    """Flat JSON objects {"k":v,...} (numbers / null only) -> "[v,...],[v,...]" in out; return length.

    Returns -1 if a message is not such a flat object (a string value or a nested object), so that
    the caller falls back to the general decoder.
    """
    p = 0
    for i in range(starts.shape[0]):
        if i:
            out[p] = 44
            p += 1
        out[p] = 91
        p += 1
        q = starts[i]
        e = ends[i]
        if q >= e or buf[q] != 123:                  # '{'
            return -1
        q += 1
        first = True
        while q < e and buf[q] != 125:               # '}'
            if buf[q] == 44:
                q += 1
            if buf[q] != 34:                         # key must start with '"'
                return -1
            q += 1
            while q < e and buf[q] != 34:
                if buf[q] == 92:                     # backslash: not our simple keys
                    return -1
                q += 1
            q += 2                                   # closing quote and ':'
            if q >= e or buf[q] == 34 or buf[q] == 123 or buf[q] == 91:
                return -1
            if not first:
                out[p] = 44
                p += 1
            first = False
            while q < e and buf[q] != 44 and buf[q] != 125:
                out[p] = buf[q]
                p += 1
                q += 1
        out[p] = 93
        p += 1
    return p


class _Checked:
    """The file as the StreamReader reads it, with the CRCs its records promise computed on the way:
    ``crc`` of every byte read so far, ``before`` = the CRC before each of the last two reads (the
    opcode and the length of the record being read), ``summary`` = the bytes read after DataEnd."""

    def __init__(self, raw):
        self._raw = raw
        self.crc = 0
        self.before = [0, 0]
        self.summary: bytearray | None = None

    def read(self, n=-1):
        data = self._raw.read(n)
        self.before = [self.before[1], self.crc]
        self.crc = zlib.crc32(data, self.crc)
        if self.summary is not None:
            self.summary += data
        return data

    def close(self):
        self._raw.close()


class _DataReader(StreamReader):
    """mcap's StreamReader without the index records (message, chunk, attachment and metadata
    indexes, statistics, summary offsets), which it parses pair by pair in Python (four fifths of
    reading a run log) and which a front-to-back reader does not need: their bytes are skipped (and
    still counted in the data-section CRC). The DataEnd record's data-section CRC and the footer's
    summary CRC are checked against ``checked`` (:class:`_Checked`); a mismatch is noted in
    ``crc_problems``, not raised, so the records read stay usable.
    If a later mcap has no ``_read_record`` to override, every record is parsed as before."""

    _SKIP = frozenset({0x07, 0x08, 0x0A, 0x0B, 0x0D, 0x0E})

    def __init__(self, checked: _Checked, **kwargs):
        super().__init__(checked, **kwargs)
        self.checked = checked
        self.crc_problems: list[str] = []

    def _read_record(self, opcode, length):
        if opcode in self._SKIP:
            return None
        if opcode == 0x0F:                                   # DataEnd
            crc = self.checked.before[0]                    # of every byte before this record
            rec = super()._read_record(opcode, length)
            if rec.data_section_crc and rec.data_section_crc != crc:
                self.crc_problems.append(
                    "the data section's CRC does not match its DataEnd record: a record outside the chunks "
                    "(header, schema, channel, metadata or index) is damaged; the chunks' own CRCs held")
            self.checked.summary = bytearray()
            return rec
        if opcode == 0x02 and self.checked.summary is not None:   # Footer
            rec = super()._read_record(opcode, length)
            if rec.summary_crc and zlib.crc32(bytes(self.checked.summary[:-4])) != rec.summary_crc:
                self.crc_problems.append("the summary's CRC does not match the footer (the summary section "
                                         "is damaged; the data section was read whole)")
            return rec
        return super()._read_record(opcode, length)


class _Rows:
    """One row topic's messages as they are decoded: log times and a (rows x fields) float64 array,
    grown in place (``ndarray.resize``: a ``realloc``, which for big arrays remaps pages instead of
    copying them) so that reading needs no per-chunk pieces joined at the end."""

    def __init__(self, keys: tuple, width: int, capacity: int = 0):
        """``capacity``: the rows expected (the summary's message count when the file has one)."""
        self.keys = keys
        cap = max(int(capacity), 1024)
        try:
            self.lt = np.empty(cap, np.int64)
            self.values = np.empty((cap, width), np.float64)
        except MemoryError:                 # a hint from a damaged summary: grow as the rows come instead
            self.lt = np.empty(1024, np.int64)
            self.values = np.empty((1024, width), np.float64)
        self.n = 0

    def append(self, lt, values) -> None:
        m = len(lt)
        need = self.n + m
        if need > len(self.lt):
            cap = max(need, 2 * len(self.lt))
            self.lt.resize(cap, refcheck=False)
            self.values.resize((cap, self.values.shape[1]), refcheck=False)
        self.lt[self.n:need] = lt
        self.values[self.n:need] = values
        self.n = need

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return self.lt[:self.n], self.values[:self.n]

    def trim(self) -> None:
        """Give back the capacity not used (a shrinking ``realloc`` unmaps the tail)."""
        if len(self.lt) > self.n:
            self.lt.resize(max(self.n, 1), refcheck=False)
            self.values.resize((max(self.n, 1), self.values.shape[1]), refcheck=False)


def _add_rows(scan, ch: int, lt, keys: tuple, values) -> None:
    """A chunk's decoded rows of channel ``ch``, appended to its last :class:`_Rows` when the fields agree."""
    pieces = scan.pieces.setdefault(ch, [])
    if not pieces or not isinstance(pieces[-1], _Rows) or pieces[-1].keys != tuple(keys) \
            or pieces[-1].values.shape[1] != values.shape[1]:
        pieces.append(_Rows(tuple(keys), values.shape[1], scan.expected.get(ch, 0) if not pieces else 0))
    pieces[-1].append(lt, values)


def _in_time_order(lt: np.ndarray, *arrays):
    """``lt`` and the arrays (rows along the first axis) sorted by log time (stable: messages of one
    log time keep the order of the file); the same objects when already in order."""
    if lt.size > 1 and np.any(lt[1:] < lt[:-1]):
        order = np.argsort(lt, kind="stable")
        return (lt[order],) + tuple(a[order] if isinstance(a, np.ndarray) else [a[i] for i in order.tolist()]
                                    for a in arrays)
    return (lt,) + arrays


@dataclass
class _Scan:
    schemas: dict = field(default_factory=dict)       # id -> Schema
    channels: dict = field(default_factory=dict)      # id -> Channel
    metadata: list = field(default_factory=list)      # (name, dict)
    attachments: dict = field(default_factory=dict)   # name -> bytes
    media_types: dict = field(default_factory=dict)
    pieces: dict = field(default_factory=dict)        # channel id -> list of _Rows or (log_times, None, data)
    counts: dict = field(default_factory=dict)        # channel id -> messages
    header: Header | None = None
    complete: bool = False                            # footer and closing magic reached, every CRC held
    truncated: bool = False                           # the reading stopped before the end (cut or damaged chunk)
    damaged: bool = False                             # bytes are wrong somewhere (a CRC did not hold)
    problem: str = ""
    chunks: int = 0
    end_time: int = 0
    start_time: int | None = None
    size: int = 0
    flat: object = None                               # predicate: channel holds flat numeric objects
    protobuf: dict = field(default_factory=dict)      # channel id -> (message class, FixedLayout or None)
    strings: dict = field(default_factory=dict)       # channel id -> the fixed strings of its messages
    expected: dict = field(default_factory=dict)      # channel id -> messages the summary counts (a capacity hint)


def _expected_counts(source) -> dict:
    """The summary's message count per channel of a file with a summary ({} for a stream, a cut
    file or a damaged summary: then the row arrays grow as they are read). Only a hint for the
    arrays' capacity; nothing read is trusted from it."""
    if not isinstance(source, (str, Path)):
        return {}
    try:
        from mcap.reader import make_reader

        with open(source, "rb") as f:
            size = f.seek(0, 2)
            f.seek(max(0, size - 37))              # footer record (29 bytes) and the closing magic (8)
            tail = f.read(37)
            start = int.from_bytes(tail[9:17], "little") if len(tail) == 37 and tail[0] == 0x02 else 0
            if not 0 < start < size or size - start > 64 << 20:   # no footer, or a damaged one: no hint
                return {}
            f.seek(0)
            summary = make_reader(f).get_summary()
        stats = summary.statistics if summary is not None else None
        return {int(k): int(v) for k, v in (stats.channel_message_counts if stats else {}).items() if 0 <= v < 1 << 34}
    except Exception:  # noqa: BLE001 - a cut or damaged file has no usable summary: no hint
        return {}


def _regular_file(path: Path) -> None:
    """RunLogReadError unless ``path`` is (a link to) a regular file: a FIFO named ``*.mcap`` would
    block its open() until a writer comes, and a link loop is no file at all."""
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        if path.is_symlink():
            raise RunLogReadError(f"{path}: is a symbolic link that leads to no file "
                                  f"({exc.strerror or exc}), not an .mcap run log") from None
        raise RunLogReadError(f"{path}: no such file" if isinstance(exc, FileNotFoundError)
                              else f"{path}: cannot be read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise RunLogReadError(f"{path}: is a folder, not an .mcap run log")
    if not stat.S_ISREG(mode):
        kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
                else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a special file")
        raise RunLogReadError(f"{path}: is not a regular file ({kind}), not an .mcap run log")


def _open(source):
    if isinstance(source, (bytes, bytearray, memoryview)):
        raise RunLogReadError(f"a run log is read from a path or a binary stream, not from {type(source).__name__} "
                              "(wrap the bytes in io.BytesIO)")
    if isinstance(source, (str, Path)):
        path = Path(source)
        _regular_file(path)
        f = open(path, "rb")
        head = f.read(8)
        if head != MAGIC:
            f.close()
            raise RunLogReadError(f"{path}: not an MCAP file (it starts with {head!r}, not the MCAP magic)")
        f.seek(0)
        return f, str(path), path.stat().st_size
    if not hasattr(source, "read"):
        raise RunLogReadError(f"a run log is read from a path or a binary stream, not from {type(source).__name__}")
    head = source.read(8)
    if head != MAGIC:
        raise RunLogReadError(f"{source!r}: not an MCAP stream (starts with {head!r})")
    return io.BufferedReader(_Prepend(head, source)), "the stream", 0


class _Prepend(io.RawIOBase):
    """A non-seekable stream with its first bytes already read put back in front."""

    def __init__(self, head: bytes, rest):
        self._head, self._rest = head, rest

    def readable(self):
        return True

    def read(self, n=-1):
        if self._head:
            if n is None or n < 0:
                out, self._head = self._head + self._rest.read(), b""
                return out
            out, self._head = self._head[:n], self._head[n:]
            if len(out) < n:
                out += self._rest.read(n - len(out))
            return out
        return self._rest.read(n)

    def readinto(self, b):
        data = self.read(len(b))
        b[:len(data)] = data
        return len(data)


def _scan(source, want=None, decode=True, flat=None) -> _Scan:
    """Read records front to back. ``want(scan, channel id)``: keep the data of that channel (default all);
    ``flat(channel id)``: that channel holds flat numeric objects (decoded to arrays directly)."""
    stream, name, size = _open(source)
    checked = _Checked(stream)
    scan = _Scan(size=size, flat=flat, expected=_expected_counts(source) if decode else {})
    dctx = zstandard.ZstdDecompressor()
    loose: list = []                     # message records outside chunks, taken as one chunk when they end
    footer = None

    def take_loose():
        if loose:
            _take_chunk(scan, b"".join(loose), want, decode)
            loose.clear()

    try:
        reader = _DataReader(checked, emit_chunks=True, record_size_limit=None)
        it = reader.records
        while True:
            try:
                rec = next(it)
            except StopIteration:
                break
            except Exception as exc:  # noqa: BLE001 - any failure here is a cut or damaged end
                take_loose()
                scan.truncated = True
                if footer is not None:
                    scan.problem = "the file ends inside its closing magic (its last bytes are missing)"
                else:
                    scan.problem = f"the file ends or is damaged after {scan.chunks} complete chunks " \
                                   f"({type(exc).__name__}{': ' + str(exc) if str(exc) else ''})"
                break
            if isinstance(rec, Message):
                loose.append(message_record(rec.channel_id, rec.log_time, rec.data, rec.sequence))
                continue
            take_loose()
            if isinstance(rec, Chunk):
                try:
                    if rec.compression == "zstd":
                        data = dctx.decompress(rec.data, max_output_size=rec.uncompressed_size)
                    elif rec.compression == "":
                        data = rec.data
                    elif rec.compression == "lz4":
                        import lz4.frame

                        data = lz4.frame.decompress(rec.data)
                    else:
                        raise ValueError(f"unknown compression {rec.compression!r}")
                    if len(data) != rec.uncompressed_size:
                        raise ValueError("chunk shorter than its declared size")
                    if rec.uncompressed_crc and zlib.crc32(data) != rec.uncompressed_crc:
                        raise ValueError("chunk CRC mismatch")
                    _check_chunk_records(data)
                except Exception as exc:  # noqa: BLE001
                    scan.truncated = scan.damaged = True
                    scan.problem = f"chunk {scan.chunks + 1} is incomplete or damaged ({exc}); read up to the " \
                                   f"{scan.chunks} complete chunks before it"
                    break
                _take_chunk(scan, data, want, decode)
                scan.chunks += 1
            elif isinstance(rec, Schema):
                scan.schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                scan.channels[rec.id] = rec
            elif isinstance(rec, Metadata):
                scan.metadata.append((rec.name, dict(rec.metadata)))
            elif isinstance(rec, Attachment):
                scan.attachments[rec.name] = rec.data
                scan.media_types[rec.name] = rec.media_type
            elif isinstance(rec, Header):
                scan.header = rec
            elif isinstance(rec, Footer):
                footer = rec
        take_loose()
        if footer is not None and not scan.truncated:
            if stream.read(1):
                scan.damaged = True
                scan.problem = "bytes follow the closing magic (two files joined, or a damaged end)"
            else:
                scan.complete = True
        if reader.crc_problems:
            scan.damaged, scan.complete = True, False
            scan.problem = "; ".join(reader.crc_problems + ([scan.problem] if scan.problem else []))
    finally:
        stream.close()
    for pieces in scan.pieces.values():
        for piece in pieces:
            if isinstance(piece, _Rows):
                piece.trim()
    if not scan.complete and not scan.truncated and not scan.damaged:
        scan.truncated = True
        scan.problem = scan.problem or "the file ends before its summary and footer"
    if scan.header is None:
        raise RunLogReadError(f"{name}: not a readable MCAP file ({scan.problem or 'no header'})")
    return scan


@njit(cache=True)
def _records_tile(buf) -> bool:
    """The records of an uncompressed chunk tile it exactly, and every message record is long
    enough for its header (a chunk whose CRC was not written could otherwise hold a cut record)."""
    n = buf.shape[0]
    p = 0
    while p + 9 <= n:
        length = 0
        for b in range(8):
            length |= np.int64(buf[p + 1 + b]) << (8 * b)
        if length < 0 or (buf[p] == 5 and length < 22):
            return False
        p += 9 + length
    return p == n


def _check_chunk_records(data: bytes) -> None:
    if not _records_tile(np.frombuffer(data, np.uint8)):
        raise ValueError("its records do not fill it exactly (a record is cut or a length is damaged)")


def _take_chunk(scan: _Scan, data: bytes, want, decode: bool):
    buf = np.frombuffer(data, np.uint8)
    op, start, end, chan, lt = _walk_records(buf)
    for i in np.flatnonzero(op != 5):          # schemas / channels inside chunks (other writers do that)
        body = ReadDataStream(io.BytesIO(data[start[i]:end[i]]))
        if op[i] == 0x03:
            s = Schema.read(body)
            scan.schemas[s.id] = s
        elif op[i] == 0x04:
            c = Channel.read(body)
            scan.channels[c.id] = c
    msg = op == 5
    if not msg.any():
        return
    chan, lt, start, end = chan[msg], lt[msg], start[msg], end[msg]
    scan.start_time = int(lt.min()) if scan.start_time is None else min(scan.start_time, int(lt.min()))
    scan.end_time = max(scan.end_time, int(lt.max()))
    for ch in np.unique(chan):
        sel = np.flatnonzero(chan == ch)
        ch = int(ch)
        scan.counts[ch] = scan.counts.get(ch, 0) + len(sel)
        if not decode or (want is not None and not want(scan, ch)):
            continue
        s, e = start[sel], end[sel]
        channel = scan.channels.get(ch)
        if channel is not None and channel.message_encoding == "protobuf":
            _take_protobuf(scan, ch, data, buf, lt[sel], s, e)
            continue
        if scan.flat is not None and scan.flat(scan, ch):
            # a row topic: keys of the first message, then values only, one orjson call per chunk
            out = np.empty(int((e - s).sum()) + 2 * len(sel) + 2, np.uint8)
            out[0] = 91
            n = _gather_values(buf, s, e, out[1:])
            if n >= 0:
                out[n + 1] = 93
                keys = tuple(_decode_array(data[s[0]:e[0]]).keys())
                if tuple(_decode_array(data[s[-1]:e[-1]]).keys()) == keys:
                    values = np.array(_decode_array(out[:n + 2].tobytes()), dtype=np.float64)
                    if values.ndim == 2 and values.shape[1] == len(keys):
                        _add_rows(scan, ch, lt[sel], keys, values)
                        continue
        out = np.empty(int((e - s).sum()) + len(sel) + 2, np.uint8)
        out[0] = 91  # '['
        n = _gather(buf, s, e, out[1:])
        out[n + 1] = 93  # ']'
        scan.pieces.setdefault(ch, []).append((lt[sel], None, out[:n + 2].tobytes()))


def _take_protobuf(scan: _Scan, ch: int, data: bytes, buf: np.ndarray, lt, s, e):
    """A chunk's messages of a protobuf channel: in bulk when they share one fixed layout (what
    usv_mj writes: :func:`usv_mj.outputs.log.protobuf_rows.decode_payloads`), else one by one with the
    protobuf library, flattened to {path: value}."""
    if ch not in scan.protobuf:
        schema = scan.schemas.get(scan.channels[ch].schema_id)
        try:
            cls = protobuf_rows.message_class(schema.data, schema.name)
        except Exception as exc:  # noqa: BLE001 - a schema we cannot use: the topic is skipped, said why
            scan.problem = scan.problem or f"topic {scan.channels[ch].topic}: unreadable protobuf schema ({exc})"
            scan.protobuf[ch] = (None, None)
            return
        scan.protobuf[ch] = (cls, None)
    cls, layout = scan.protobuf[ch]
    if cls is None:
        return
    if layout is None:
        try:
            layout = protobuf_rows.FixedLayout(cls, protobuf_rows.shape_of(cls.FromString(data[s[0]:e[0]])))
        except Exception:  # noqa: BLE001 - no fixed layout (repeated doubles, ...): message by message
            layout = False
        scan.protobuf[ch] = (cls, layout)
        if layout:
            scan.strings[ch] = layout.strings
    values = protobuf_rows.decode_payloads(buf, s, e, layout) if layout else None
    if values is not None:
        _add_rows(scan, ch, lt, layout.paths, values)
    else:
        msgs, times = [], []
        for a, b, t in zip(s.tolist(), e.tolist(), lt.tolist()):
            try:
                msgs.append(protobuf_rows.flatten(cls.FromString(data[a:b])))
                times.append(t)
            except Exception as exc:  # noqa: BLE001 - protobuf's DecodeError: said, and the message skipped
                scan.problem = scan.problem or f"topic {scan.channels[ch].topic}: a message is not a valid " \
                                               f"{cls.DESCRIPTOR.full_name} ({exc}); such messages are left out"
        scan.pieces.setdefault(ch, []).append((np.array(times, np.int64), None, msgs))


def _decode_array(text: bytes):
    return json_codec.loads(text)


def _messages(scan: _Scan, ch: int) -> tuple[np.ndarray, list]:
    """All messages of a channel as dicts, in log-time order (chunks decoded to arrays are turned
    back; protobuf messages are flat {path: value} dicts)."""
    times, msgs = [], []
    strings = scan.strings.get(ch, {})
    for piece in scan.pieces.get(ch, []):
        if isinstance(piece, _Rows):
            lt, values = piece.arrays()
            times.append(lt)
            msgs += [{**strings, **dict(zip(piece.keys, row))} for row in values.tolist()]
            continue
        lt, _, data = piece
        times.append(lt)
        msgs += data if isinstance(data, list) else _decode_array(data)
    log_time = np.concatenate(times) if times else np.zeros(0, np.int64)
    return _in_time_order(log_time, msgs)


def _columns(scan: _Scan, ch: int) -> tuple[np.ndarray, dict]:
    """A channel of flat messages as (log_time, {field: float64 array, or object array for strings}),
    in log-time order. The float columns are views into the channel's one (rows x fields) array."""
    pieces = scan.pieces.get(ch, [])
    if pieces and all(isinstance(p, _Rows) for p in pieces) and len({p.keys for p in pieces}) == 1:
        keys = pieces[0].keys
        if len(pieces) == 1:
            log_time, values = pieces[0].arrays()
        else:
            log_time = np.concatenate([p.arrays()[0] for p in pieces])
            values = np.concatenate([p.arrays()[1] for p in pieces])
        log_time, values = _in_time_order(log_time, values)
        cols = {k: values[:, i] for i, k in enumerate(keys)}
        for k, text in scan.strings.get(ch, {}).items():
            cols[k] = np.full(len(values), text, dtype=object)
        return log_time, cols
    log_time, msgs = _messages(scan, ch)
    cols = _arrays(msgs, log_time)
    del cols["log_time"]
    return log_time, cols


def _topic_columns(scan: _Scan, ch: int, lists: bool = False, with_log_time: bool = False) -> dict:
    """Any channel as {path: array} (float64; object arrays for strings): the row topics and the
    protobuf topics from their decoded arrays, other JSON topics flattened (``lists``: arrays of
    objects too, as an older log's ``P/obstacles``)."""
    channel = scan.channels.get(ch)
    if _is_row_channel(scan, ch) or (channel is not None and channel.message_encoding == "protobuf"):
        log_time, cols = _columns(scan, ch)
        return {"log_time": log_time.astype(np.int64), **cols} if with_log_time else cols
    log_time, msgs = _messages(scan, ch)
    cols = _arrays(msgs, log_time, lists)
    return cols if with_log_time else {k: v for k, v in cols.items() if k != "log_time"}


def _is_row_channel(scan: _Scan, ch: int) -> bool:
    c = scan.channels.get(ch)
    schema = scan.schemas.get(c.schema_id) if c is not None else None
    return (c is not None and c.metadata.get("kind") == "rows") or (schema is not None and schema.name in ROW_SCHEMAS)


def _flatten(msg: dict, prefix: str = "", out=None, lists: bool = False) -> dict:
    """A JSON message as {path: value}: objects with dots ("translation.x"), and with ``lists``
    arrays of objects too ("obstacles.0.name", as the protobuf topics are flattened)."""
    out = {} if out is None else out
    for k, v in msg.items():
        if isinstance(v, dict):
            _flatten(v, f"{prefix}{k}.", out, lists)
        elif lists and isinstance(v, list) and all(isinstance(item, dict) for item in v):
            for i, item in enumerate(v):
                _flatten(item, f"{prefix}{k}.{i}.", out, lists)
        else:
            out[prefix + k] = v
    return out


def _arrays(msgs: list, log_time: np.ndarray, lists: bool = False) -> dict:
    flat = [_flatten(m, lists=lists) for m in msgs]
    names = []
    for m in flat:
        for k in m:
            if k not in names:
                names.append(k)
    out = {"log_time": log_time.astype(np.int64)}
    for k in names:
        vals = [m.get(k) for m in flat]
        if all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)) for v in vals):
            out[k] = np.array(vals, dtype=np.float64)
        else:
            arr = np.empty(len(vals), dtype=object)
            arr[:] = vals
            out[k] = arr
    return out


@dataclass
class RunLog:
    """A run log read back. ``record`` is the main run, ``baseline`` the PI baseline (or None)."""

    path: str
    runs: dict                  # run name -> RunRecord
    metadata: dict              # file metadata (JSON values decoded) + "runs": {name: {"start":..., "end":...}}
    attachments: dict           # name -> bytes
    topic_counts: dict          # topic -> message count
    truncated: bool
    complete: bool              # the file has its summary and footer
    problem: str
    summaries: dict             # run name -> summary dict written at the run's end ({} if none)
    obstacles_by_run: dict = field(default_factory=dict)    # run -> extra_topics.obstacle_arrays(...)
    environment_by_run: dict = field(default_factory=dict)  # run -> extra_topics.environment_arrays(...)
    files: dict = field(default_factory=dict)               # run -> the file it was read from
    damaged: bool = False       # a CRC did not hold (a chunk, the data section or the summary)
    notices: dict = field(default_factory=dict)             # file -> what is wrong with it and what was recovered

    @property
    def notice(self) -> str:
        """One line for the user when this log or a companion read with it is cut or damaged, with
        what was recovered ("" when every file read is complete): what ``plot`` and ``render`` print
        and write into their report and figure titles."""
        return "; ".join(f"{Path(f).name}: {text}" for f, text in self.notices.items())

    @property
    def obstacles(self) -> dict | None:
        """The main run's ``P/obstacles`` as arrays: {"t" (n,), "names", "clearance_m" (n, m),
        "normal_force_N" (n, m), "center" (n, m, 2)}; None when the run has no obstacle topic."""
        return self.obstacles_by_run.get("main", next(iter(self.obstacles_by_run.values()), None))

    @property
    def environment(self) -> dict | None:
        """The main run's ``P/environment`` as arrays: {"t", "zeta", "tau_wave", "tau_drift", "tau_wind"
        (n, 3), "current" (n, 2), "wind_speed", "wind_direction"}; None in a calm sea."""
        return self.environment_by_run.get("main", next(iter(self.environment_by_run.values()), None))

    @property
    def record(self) -> RunRecord:
        if "main" in self.runs:
            return self.runs["main"]
        if not self.runs:
            raise RunLogReadError(f"{self.path}: holds no run")
        return next(iter(self.runs.values()))

    @property
    def baseline(self) -> RunRecord | None:
        return self.runs.get("baseline")

    def topics(self) -> dict:
        """Topic name -> number of messages read."""
        return dict(self.topic_counts)


def _declared_fields(start: dict) -> dict:
    """Row topic name -> its fields, from a run's ``run_start`` columns ({} without them)."""
    names = start.get("columns")
    try:
        return {name: fields for name, _, fields in row_topics(tuple(names))} if isinstance(names, list) else {}
    except ValueError:
        return {}


def _maybe_json(value: str):
    try:
        return json.loads(value)
    except (ValueError, TypeError):
        return value


def _run_names(scan: _Scan) -> list:
    names = [m["run"] for name, m in scan.metadata if name.startswith("run_start/") and "run" in m]
    if not names:  # no start records (cut very early or another writer): guess from the topics
        for c in scan.channels.values():
            if c.topic.endswith("/state"):
                p = c.topic[: -len("/state")]
                names.append("main" if p == "/usv" else p.strip("/").split("/")[0])
    return list(dict.fromkeys(names))


def peek_file_metadata(path) -> dict:
    """The ``usv_mj`` metadata record of a run log (written first, before any chunk), {} if none."""
    try:
        stream, _, _ = _open(path)
    except (RunLogReadError, OSError):
        return {}
    try:
        for rec in StreamReader(stream, emit_chunks=True, record_size_limit=None).records:
            if isinstance(rec, Metadata) and rec.name == "usv_mj":
                return dict(rec.metadata)
            if isinstance(rec, (Chunk, Attachment, Footer)):
                break
    except Exception:  # noqa: BLE001 - a damaged neighbour is simply not a companion
        pass
    finally:
        stream.close()
    return {}


def companion_files(path) -> list[Path]:
    """The run logs beside ``path`` written as its companions (``RunLogWriter(companion_of=...)``:
    the main job's ``baseline.mcap`` beside ``run.mcap``), matched by the main file's log id."""
    path = Path(path)
    log_id = peek_file_metadata(path).get("log_id")
    if not log_id:
        return []
    out = []
    try:
        here = path.stat()
    except OSError:
        return []
    for other in sorted(path.parent.glob("*.mcap")):
        try:   # only regular files (a FIFO would block, a link loop is no file), not this one itself
            st = other.stat()
        except OSError:
            continue
        if not stat.S_ISREG(st.st_mode) or (st.st_dev, st.st_ino) == (here.st_dev, here.st_ino):
            continue
        link = _maybe_json(peek_file_metadata(other).get("companion_of", ""))
        if isinstance(link, dict) and link.get("log_id") == log_id:
            out.append(other)
    return out


def read_run(path, companions: bool = True) -> RunLog:
    """Read every run of a run log (a path, or a binary stream that need not be seekable).

    Each run becomes a :class:`RunRecord` (``RunRecord.from_arrays``) with the columns and the
    diagnostic fields it was written with, its events (ordered by time, as ``simulate`` leaves
    them), ``status``, ``stop_reason`` and the record's metadata as written at the end of the run.
    A run whose end record is missing (the file was cut) gets ``status = "truncated"`` and a
    ``stop_reason`` saying where the log ends. With ``companions`` (and a path), the runs of the
    companion files beside it (the main job's ``baseline.mcap``) are added; ``RunLog.files`` says
    which file each run came from. ``RunLog.notice`` is one line naming each file read (this one
    and its companions) that is cut or damaged and the rows recovered from it ("" when all are whole).
    """
    if not (isinstance(path, (str, Path)) or hasattr(path, "read")):
        from usv_mj.core.errors import expected

        raise expected("read_run", "path", "a run log's path (str or pathlib.Path) or a binary stream "
                       "(bytes: io.BytesIO(data))", path)
    log = _read_one(path)
    if companions and isinstance(path, (str, Path)):
        for other in companion_files(path):
            try:
                more = _read_one(other)
            except RunLogReadError as exc:
                log.notices[str(other)] = f"could not be read, so its runs are missing ({exc})"
                continue
            log.notices.update(more.notices)
            for run, rec in more.runs.items():
                if run in log.runs:
                    continue
                log.runs[run] = rec
                log.files[run] = more.path
                log.summaries[run] = more.summaries.get(run, {})
                log.metadata.setdefault("runs", {})[run] = more.metadata.get("runs", {}).get(run, {})
                for mine, theirs in ((log.obstacles_by_run, more.obstacles_by_run),
                                     (log.environment_by_run, more.environment_by_run)):
                    if run in theirs:
                        mine[run] = theirs[run]
            for topic, count in more.topic_counts.items():
                log.topic_counts.setdefault(topic, count)
    return log


_RUN_TOPICS = ("events", "obstacles", "environment")     # beside the row topics, what a RunRecord is made of


def _run_channel(scan: _Scan, ch: int) -> bool:
    """What ``read_run`` decodes: the row topics and the topics above (the Foxglove scene topics,
    frames, funnel, path and hull, are skipped: they hold nothing a RunRecord has)."""
    c = scan.channels.get(ch)
    return c is None or _is_row_channel(scan, ch) or c.topic.rsplit("/", 1)[-1] in _RUN_TOPICS


def _read_one(path) -> RunLog:
    scan = _scan(path, want=_run_channel, flat=_is_row_channel)
    file_meta, runs_meta = {}, {}
    for name, m in scan.metadata:
        if name == "usv_mj":
            file_meta = {k: _maybe_json(v) if k in ("scenario", "versions", "git_dirty", "companion_of", "plugins") else v
                         for k, v in m.items()}
        elif "/" in name:
            kind, run = name.split("/", 1)
            runs_meta.setdefault(run, {})[kind.replace("run_", "")] = {
                k: _maybe_json(v) if k in ("metadata", "summary", "columns", "diagnostic_fields", "diagnostic_events",
                                           "obstacles") else v for k, v in m.items()}
    by_topic = {c.topic: cid for cid, c in scan.channels.items()}
    runs, summaries = {}, {}
    obstacles_by_run, environment_by_run = {}, {}
    for run in _run_names(scan):
        try:
            p = prefix_for(run)
        except ValueError:
            continue
        if f"{p}/state" not in by_topic:
            continue
        # every row topic of the run (state, reference, control, errors, diagnostics; version 1's
        # adaptation and internal), fields by name: the record's columns come from the run's metadata
        columns, n = {}, None
        t_ref = None
        declared = _declared_fields((runs_meta.get(run) or {}).get("start") or {})
        for cid, c in sorted(scan.channels.items()):
            if not (c.topic.startswith(p + "/") and "/" not in c.topic[len(p) + 1:] and _is_row_channel(scan, cid)):
                continue
            _, cols = _columns(scan, cid)
            fields = declared.get(c.topic[len(p) + 1:])
            if fields and list(cols) != list(fields) and list(cols) == protobuf_rows.field_names(fields):
                cols = dict(zip(fields, cols.values()))     # columns whose names are not protobuf names
            m = len(cols.get("t", ()))
            n = m if n is None else min(n, m)
            for f, values in cols.items():
                if f == "t":
                    if t_ref is None or c.topic == f"{p}/state":
                        t_ref = values
                    continue
                columns.setdefault(f, values)
        n = n or 0
        start = (runs_meta.get(run) or {}).get("start") or {}
        names = start.get("columns")
        if not isinstance(names, list) or not names:
            names = list(CORE_COLUMNS) + [f for f in columns if f not in COL]
        diagnostic_fields = tuple(f for f in names if f not in COL)
        t_col = (t_ref if t_ref is not None else np.zeros(0))[:n]
        # a column the file does not have (an older log's f_u, sat_u, ...): NaN, as the record starts
        columns = {"t": t_col, **{k: (columns[k][:n] if k in columns else np.full(n, np.nan))
                                  for k in list(CORE_COLUMNS[1:]) + list(diagnostic_fields)}}
        diagnostic_events = start.get("diagnostic_events")
        diagnostic_events = diagnostic_events if isinstance(diagnostic_events, dict) else None
        events = []
        cid = by_topic.get(f"{p}/events")
        if cid is not None:
            _, msgs = _messages(scan, cid)
            msgs = sorted((m for m in msgs if not m.get("synthetic")), key=lambda m: (m["t"], m["seq"]))
            events = [Event(m["t"], m["kind"], m["message"], m.get("values") or {}) for m in msgs]
        meta = runs_meta.get(run, {})
        end = meta.get("end")
        if end is not None:
            status, stop_reason = end.get("status", "unknown"), end.get("stop_reason", "")
            record_meta = end.get("metadata") or {}
            summaries[run] = end.get("summary") or {}
        else:
            status = "truncated"
            t_last = float(columns["t"][-1]) if n else 0.0
            stop_reason = f"the log ends at t = {t_last:.3f} s without the run's end record ({scan.problem or 'no end record'})"
            record_meta = (meta.get("start") or {}).get("metadata") or {}
            summaries[run] = {}
        rec = RunRecord.from_arrays(columns, events=events, metadata=record_meta, status=status, stop_reason=stop_reason,
                                    diagnostic_fields=diagnostic_fields, diagnostic_events=diagnostic_events)
        runs[run] = rec
        cid = by_topic.get(f"{p}/obstacles")
        if cid is not None:
            cols = _topic_columns(scan, cid, lists=True)
            if len(cols.get("t", ())):      # none before the first complete chunk
                obstacles_by_run[run] = obstacle_arrays(cols)
        cid = by_topic.get(f"{p}/environment")
        if cid is not None:
            cols = _topic_columns(scan, cid)
            if len(cols.get("t", ())):
                environment_by_run[run] = environment_arrays(cols)
    file_meta["runs"] = runs_meta
    counts = {scan.channels[cid].topic: c for cid, c in scan.counts.items() if cid in scan.channels}
    for cid, c in scan.channels.items():
        counts.setdefault(c.topic, 0)
    if not runs:
        raise RunLogReadError(f"{path}: no usv_mj run in this MCAP file ({scan.problem or 'no /usv/state topic'})")
    notices = {}
    if not scan.complete:
        what = "cut short" if scan.truncated and not scan.damaged else "damaged"
        got = ", ".join(f"{run} {len(rec)} rows up to t = {float(rec['t'][-1]):.3f} s" if len(rec) else f"{run} no rows"
                        for run, rec in runs.items())
        notices[str(path)] = f"{what} ({scan.problem}); recovered: {got}"
    return RunLog(path=str(path), runs=runs, metadata=file_meta, attachments=dict(scan.attachments),
                  topic_counts=counts, truncated=scan.truncated, complete=scan.complete, problem=scan.problem,
                  summaries=summaries, obstacles_by_run=obstacles_by_run, environment_by_run=environment_by_run,
                  files={run: str(path) for run in runs}, damaged=scan.damaged, notices=notices)


def load_topic(path, topic: str) -> dict:
    """Arrays by field of one topic: ``{"log_time": int64 ns, field: float64 or object array}``.

    Nested objects are flattened with dots ("translation.x"; a protobuf topic's repeated
    sub-messages as "obstacles.0.name"); numbers become float64 (null -> NaN), anything else an
    object array. Reads a cut file up to its last complete chunk.
    """
    holder = {}

    def want(scan, ch):
        return ch == holder.get("cid")

    stream_meta = _scan(path, decode=False)
    for cid, c in stream_meta.channels.items():
        if c.topic == topic:
            holder["cid"] = cid
    if "cid" not in holder:
        known = ", ".join(sorted(c.topic for c in stream_meta.channels.values()))
        raise RunLogReadError(f"{path}: no topic {topic!r}; topics are {known}")
    scan = _scan(path, want=want, flat=_is_row_channel)
    if scan.protobuf.get(holder["cid"], (True,))[0] is None:
        raise RunLogReadError(f"{path}: {scan.problem}")
    return _topic_columns(scan, holder["cid"], with_log_time=True)


def scan_summary(path) -> dict:
    """What ``usv-mj inspect`` prints: topics with counts and schemas, time range, metadata, attachments."""
    scan = _scan(path, decode=False)
    topics = {}
    for cid, c in sorted(scan.channels.items()):
        schema = scan.schemas.get(c.schema_id)
        topics[c.topic] = {"count": scan.counts.get(cid, 0), "schema": schema.name if schema else "",
                           "encoding": c.message_encoding}
    return {"topics": topics, "metadata": scan.metadata, "attachments": {k: len(v) for k, v in scan.attachments.items()},
            "start_ns": scan.start_time or 0, "end_ns": scan.end_time, "complete": scan.complete,
            "truncated": scan.truncated, "damaged": scan.damaged, "problem": scan.problem, "chunks": scan.chunks, "size": scan.size,
            "library": scan.header.library if scan.header else ""}
