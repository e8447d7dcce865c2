"""A streaming MCAP writer for long runs: chunks built in bulk, the rest through the mcap library.

Why not ``mcap.writer.Writer`` for everything: its ``add_message`` costs about 6.5 us per message in
Python, and a 300 s run at 1 ms has 300,001 rows x 5 topics = 1.5 million messages (10 s, more than
the simulation itself). Here the message records of a whole chunk are laid out in bulk from a block
of rows: the per-step protobuf topics by :class:`usv_mj.outputs.log.protobuf_rows.BinaryRows` (a
template copy and one strided copy per field), the JSON Foxglove topics by :class:`TemplateLayout` (the
numbers formatted by orjson in one call); the chunk is compressed with zstd; every other record
(header, schemas, channels, chunk, message and chunk indexes, metadata,
attachments, statistics, summary offsets, footer) is serialized by ``mcap.records``. The result is
checked by the mcap library's own readers in tests/test_runlog.py (summary, indexes, CRCs).

MCAP record layouts used here (mcap.dev spec, "Message" op 0x05, "Message Index" op 0x07):
Message = opcode u8, record length u64, channel_id u16, sequence u32, log_time u64, publish_time u64,
data; Message Index = opcode u8, length u64, channel_id u16, records byte length u32, then (log_time
u64, offset u64) pairs, offset = position of the message record in the uncompressed chunk.

Every chunk is written whole and the file is flushed to the OS after it, so a killed process leaves
a file readable up to its last complete chunk (see :mod:`usv_mj.outputs.log.reader`). Inside a chunk the
messages are in log-time order (:meth:`ChunkBuffer.finish`), so with chunks written in time order a
front-to-back reader sees log time never go back.
"""

from __future__ import annotations

import dataclasses
import os
import struct
import zlib

import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Attachment, AttachmentIndex, Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Metadata,
                          MetadataIndex, Schema, Statistics, SummaryOffset)

from usv_mj.outputs.log import json_codec

MAGIC = b"\x89MCAP0\r\n"
MESSAGE_HEADER = 31         # opcode 1 + length 8 + channel 2 + sequence 4 + log_time 8 + publish_time 8


class TemplateLayout:
    """One JSON topic whose messages are a fixed template with float64 holes (the Foxglove frames and
    funnel, every 20 ms: the per-step topics are protobuf, :mod:`usv_mj.outputs.log.protobuf_rows`).

    ``pieces[q]`` is the JSON text written before value q (the first starts the message, e.g.
    b'{"t":'), ``closing`` the text after the last value (e.g. b'}}]}'). The block handed to
    :meth:`encode` has exactly ``len(pieces)`` columns, value q in column q. Numbers: the shortest
    round-trip decimal (orjson, one call per block), null = NaN, +-1e999 = +-inf.
    """

    def __init__(self, channel_id: int, pieces: list[bytes], closing: bytes, sec_hole: int | None = None,
                 nsec_hole: int | None = None):
        """``sec_hole`` / ``nsec_hole``: the values written as the message's log time in whole seconds /
        the nanoseconds past them (integers, as a Foxglove ``time`` wants; their block column is ignored)."""
        self.n_cols = len(pieces)
        # the message as one bytes %-format: pieces and closing around a %s per value
        self.format = b"%s".join(bytes(p).replace(b"%", b"%%") for p in list(pieces) + [closing])
        self.sec_hole, self.nsec_hole = sec_hole, nsec_hole
        self.channel_id = int(channel_id)
        self.channel_ids = np.array([channel_id], np.int64)

    def encode(self, block: np.ndarray, log_time: np.ndarray, seq) -> tuple[np.ndarray, np.ndarray]:
        """Message records (uint8 array) and record offsets (rows x 1) for a float64 block.

        ``seq``: the first row's sequence number (the rows count up from it) or one per row."""
        n, k = block.shape[0], self.n_cols
        flat = np.ascontiguousarray(np.asarray(block, dtype=np.float64)).reshape(-1)
        tokens = json_codec.dumps_floats(flat)[1:-1].split(b",") if flat.size else []
        for i in np.flatnonzero(np.isinf(flat)).tolist():
            tokens[i] = b"1e999" if flat[i] > 0 else b"-1e999"
        lt = np.asarray(log_time, np.int64).tolist()
        seq = (np.arange(n, dtype=np.int64) + int(seq)) if np.ndim(seq) == 0 else np.asarray(seq, np.int64)
        records, fmt, ch = [], self.format, self.channel_id
        sec, nsec = self.sec_hole, self.nsec_hole
        for i, (t, sq) in enumerate(zip(lt, seq.tolist())):
            row = tokens[i * k:(i + 1) * k]
            if sec is not None:
                row[sec] = b"%d" % (t // 1_000_000_000)
            if nsec is not None:
                row[nsec] = b"%d" % (t % 1_000_000_000)
            records.append(message_record(ch, t, fmt % tuple(row), sq))
        sizes = np.fromiter(map(len, records), np.int64, len(records))
        offsets = (np.cumsum(sizes) - sizes).reshape(n, 1)
        return np.frombuffer(b"".join(records), np.uint8), offsets


def template_layout(channel_id: int, example: dict, holes: tuple[str, ...]) -> TemplateLayout:
    """The :class:`TemplateLayout` of messages shaped like ``example``, whose variable values are the
    strings ``holes`` (each once in the JSON text, in this order; "$name" keeps them apart from real
    strings). The holes "$sec" and "$nsec" become the log-time stamp (see ``sec_hole``). The block
    handed to ``encode`` has one column per hole, in the order of ``holes``."""
    text = json_codec.dumps(example)
    pieces, sec_hole, nsec_hole = [], None, None
    for q, name in enumerate(holes):
        token = json_codec.dumps(name)
        head, found, text = text.partition(token)
        if not found or token in text:
            raise ValueError(f"hole {name!r} must appear exactly once in the template, after the holes before it")
        pieces.append(head)
        sec_hole = q if name == "$sec" else sec_hole
        nsec_hole = q if name == "$nsec" else nsec_hole
    return TemplateLayout(channel_id, pieces, text, sec_hole, nsec_hole)


def message_record(channel_id: int, log_time: int, data: bytes, sequence: int = 0) -> bytes:
    """One MCAP Message record (for the few messages not laid out in bulk)."""
    return struct.pack("<BQHIQQ", Opcode.MESSAGE, 22 + len(data), channel_id, sequence & 0xFFFFFFFF,
                       log_time, log_time) + data


class ChunkBuffer:
    """The message records of one chunk being assembled. :meth:`finish` puts them in log-time order
    (a stable sort: messages of one log time keep the order they were added in), so that a reader
    that goes through the file front to back sees log time never go back inside a chunk.

    What is sorted are units: one row's messages of a block (all its topics, one log time) or one
    single message; a chunk of 1000 rows has about 1000 units, not 5000 messages."""

    def __init__(self):
        self.parts: list = []
        self.size = 0
        self._lt: list = []           # per added piece: log time, start and length of each unit
        self._start: list = []
        self._len: list = []
        self._blocks: list = []       # per added piece: (channel ids, offsets of its messages in each unit)
        self.count: dict[int, int] = {}
        self.start_time = None
        self.end_time = None

    def __len__(self):
        return sum(self.count.values())

    def _add(self, lt, start, length, channels, intra, part, nbytes):
        self._lt.append(lt)
        self._start.append(start + self.size)
        self._len.append(length)
        self._blocks.append((channels, intra))
        self.parts.append(part)
        self.size += nbytes
        for ch in channels:
            self.count[int(ch)] = self.count.get(int(ch), 0) + len(lt)
        lo, hi = int(lt.min()), int(lt.max())
        self.start_time = lo if self.start_time is None else min(self.start_time, lo)
        self.end_time = hi if self.end_time is None else max(self.end_time, hi)

    def add_rows(self, records: np.ndarray, offsets: np.ndarray, log_time: np.ndarray, channel_ids):
        """Records laid out row-major (row i's messages, topic by topic; ``offsets[i, j]`` = where
        row i's topic j starts), as :class:`TemplateLayout` and ``BinaryRows`` give them."""
        if len(log_time) == 0:
            return
        offsets = np.asarray(offsets, np.int64)
        start = offsets[:, 0]
        length = np.diff(np.append(start, len(records)))
        self._add(np.asarray(log_time, np.int64), start, length, np.asarray(channel_ids, np.int64),
                  offsets - start[:, None], records, len(records))

    def add_message(self, channel_id: int, log_time: int, data: bytes, sequence: int = 0):
        rec = message_record(channel_id, log_time, data, sequence)
        self._add(np.array([log_time], np.int64), np.zeros(1, np.int64), np.array([len(rec)], np.int64),
                  np.array([channel_id], np.int64), np.zeros((1, 1), np.int64), rec, len(rec))

    def finish(self) -> tuple[list, dict]:
        """(the chunk's data as parts, {channel: (log times, record offsets)}), messages in log-time order."""
        lt = np.concatenate(self._lt)
        start = np.concatenate(self._start)
        parts = self.parts
        if lt.size > 1 and np.any(np.diff(lt) < 0):
            order = np.argsort(lt, kind="stable")
            s_o = start[order]
            l_o = np.concatenate(self._len)[order]
            start = np.empty_like(start)
            start[order] = np.cumsum(l_o) - l_o
            # runs of units that follow each other in one part are copied as one slice
            arrays = [np.frombuffer(p, np.uint8) if isinstance(p, (bytes, bytearray)) else p for p in self.parts]
            bases = np.cumsum([0] + [len(a) for a in arrays])
            pid = np.searchsorted(bases, s_o, side="right") - 1
            cut = np.ones(len(s_o), bool)
            cut[1:] = (s_o[1:] != s_o[:-1] + l_o[:-1]) | (pid[1:] != pid[:-1])
            first = np.flatnonzero(cut)
            last = np.append(first[1:], len(s_o)) - 1
            lo = (s_o[first] - bases[pid[first]]).tolist()
            hi = (s_o[last] + l_o[last] - bases[pid[first]]).tolist()
            parts = [np.concatenate([arrays[p][a:b] for p, a, b in zip(pid[first].tolist(), lo, hi)])]
        found: dict = {}
        u = 0
        for (channels, intra), times in zip(self._blocks, self._lt):
            units = start[u:u + len(times)]
            for j, ch in enumerate(channels.tolist()):
                found.setdefault(ch, []).append((times, units + intra[:, j]))
            u += len(times)
        index = {}
        for ch, pieces in found.items():
            times = np.concatenate([t for t, _ in pieces])
            offs = np.concatenate([o for _, o in pieces])
            if len(pieces) > 1 or parts is not self.parts:   # the final places are in log-time order
                order = np.argsort(offs, kind="stable")
                times, offs = times[order], offs[order]
            index[ch] = (times.astype(np.uint64), offs.astype(np.uint64))
        return parts, index


def _merge_small(parts: list) -> list:
    """Runs of small bytes parts joined into one (fewer compressor calls); big arrays passed as they are."""
    out, small = [], []
    for p in parts:
        if isinstance(p, bytes) and len(p) < 65536:
            small.append(p)
            continue
        if small:
            out.append(b"".join(small))
            small = []
        out.append(p)
    if small:
        out.append(b"".join(small))
    return out


class McapFileWriter:
    """Writes one MCAP file: data section as it comes, summary and footer on :meth:`finish`."""

    def __init__(self, path, profile: str = "", library: str = "usv_mj.outputs.log", compression_level: int = 1):
        self.path = str(path)
        self._file = open(path, "wb")
        self._good = None
        self._crc = 0
        self._compressor = zstandard.ZstdCompressor(level=compression_level)
        self.schemas: dict[int, Schema] = {}
        self.tee = None   # an object with chunk(writer, parts): sees every chunk's messages (usv_mj.outputs.log.live)
        self.channels: dict[int, Channel] = {}
        self.chunk_indexes: list[ChunkIndex] = []
        self.attachment_indexes: list[AttachmentIndex] = []
        self.metadata_indexes: list[MetadataIndex] = []
        self.stats = Statistics(attachment_count=0, channel_count=0, channel_message_counts={}, chunk_count=0,
                                message_count=0, message_end_time=0, message_start_time=0, metadata_count=0,
                                schema_count=0)
        self.finished = False
        self.failed: OSError | None = None
        self._write(MAGIC)
        self._write_record(Header(profile=profile, library=library))
        self._checkpoint()

    # faults: a write that fails (disk full) cuts the file back to its last complete
    # record and closes it with a summary if there is room, so that it reads up to that record
    def _checkpoint(self):
        self._file.flush()
        self._good = (self._file.tell(), self._crc, len(self.chunk_indexes), len(self.metadata_indexes),
                      len(self.attachment_indexes), dataclasses.replace(
                          self.stats, channel_message_counts=dict(self.stats.channel_message_counts)))

    def _salvage(self, exc: OSError) -> None:
        self.failed = exc
        offset, crc, n_chunks, n_meta, n_att, stats = self._good
        fd = os.dup(self._file.fileno())
        try:
            self._file.close()          # flushes what is buffered (fails again), then closes
        except OSError:
            pass
        self._crc = crc
        del self.chunk_indexes[n_chunks:], self.metadata_indexes[n_meta:], self.attachment_indexes[n_att:]
        self.stats = stats
        os.ftruncate(fd, offset)
        self._file = os.fdopen(fd, "r+b")
        self._file.seek(offset)
        self.finished = False
        try:
            self._finish()
        except OSError:                 # no room even for the summary: the data section alone
            self.finished = True
            try:
                self._file.close()
            except OSError:
                pass
            os.truncate(self.path, offset)

    def _guard(self, fn, *args, **kwargs):
        """``fn`` (a record writer); on OSError the file is salvaged and the error raised again."""
        if self.failed is not None:
            raise OSError(self.failed.errno, self.failed.strerror, self.path)
        try:
            value = fn(*args, **kwargs)
            if not self.finished:
                self._checkpoint()
            return value
        except OSError as exc:
            if self.failed is None:
                self._salvage(exc)
            raise

    # low level
    def _write(self, data):
        self._file.write(data)
        self._crc = zlib.crc32(data, self._crc)

    def _write_record(self, record) -> tuple[int, int]:
        builder = RecordBuilder()
        record.write(builder)
        data = builder.end()
        offset = self._file.tell()
        self._write(data)
        return offset, len(data)

    # records
    def register_schema(self, *args, **kwargs):
        return self._guard(self._register_schema, *args, **kwargs)

    def _register_schema(self, name: str, encoding: str, data: bytes) -> int:
        sid = len(self.schemas) + 1
        self.schemas[sid] = Schema(id=sid, data=data, encoding=encoding, name=name)
        self.stats.schema_count += 1
        self._write_record(self.schemas[sid])
        return sid

    def register_channel(self, *args, **kwargs):
        return self._guard(self._register_channel, *args, **kwargs)

    def _register_channel(self, topic: str, message_encoding: str, schema_id: int, metadata: dict | None = None) -> int:
        cid = len(self.channels) + 1
        self.channels[cid] = Channel(id=cid, topic=topic, message_encoding=message_encoding,
                                     metadata=dict(metadata or {}), schema_id=schema_id)
        self.stats.channel_count += 1
        self._write_record(self.channels[cid])
        return cid

    def add_metadata(self, *args, **kwargs):
        return self._guard(self._add_metadata, *args, **kwargs)

    def _add_metadata(self, name: str, data: dict[str, str]):
        offset, length = self._write_record(Metadata(name=name, metadata=data))
        self.metadata_indexes.append(MetadataIndex(offset=offset, length=length, name=name))
        self.stats.metadata_count += 1
        self._file.flush()

    def add_attachment(self, *args, **kwargs):
        return self._guard(self._add_attachment, *args, **kwargs)

    def _add_attachment(self, name: str, media_type: str, data: bytes, log_time: int = 0, create_time: int = 0):
        att = Attachment(create_time=create_time, log_time=log_time, name=name, media_type=media_type, data=data)
        offset, length = self._write_record(att)
        self.attachment_indexes.append(AttachmentIndex(offset=offset, length=length, log_time=log_time,
                                                       create_time=create_time, data_size=len(data), name=name,
                                                       media_type=media_type))
        self.stats.attachment_count += 1

    def write_chunk(self, *args, **kwargs):
        return self._guard(self._write_chunk, *args, **kwargs)

    def _write_chunk(self, buf: ChunkBuffer):
        """Compress and write one chunk, then its message indexes; flush to the OS."""
        if not len(buf):
            return
        parts, index = buf.finish()
        cobj = self._compressor.compressobj(size=buf.size)
        pieces, crc = [], 0
        for part in _merge_small(parts):
            crc = zlib.crc32(part, crc)
            pieces.append(cobj.compress(part))
        pieces.append(cobj.flush())
        compressed = b"".join(pieces)
        chunk = Chunk(compression="zstd", data=compressed, message_start_time=buf.start_time,
                      message_end_time=buf.end_time, uncompressed_crc=crc, uncompressed_size=buf.size)
        chunk_offset, chunk_length = self._write_record(chunk)
        index_start = self._file.tell()
        index_offsets = {}
        pieces = []
        pos = index_start
        for ch in sorted(index):
            lt, off = index[ch]                        # in log-time order (finish)
            pairs = np.empty(2 * len(lt), "<u8")
            pairs[0::2] = lt
            pairs[1::2] = off
            body = pairs.tobytes()
            rec = struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 6 + len(body), ch, len(body)) + body
            index_offsets[ch] = pos
            pieces.append(rec)
            pos += len(rec)
        self._write(b"".join(pieces))
        self.chunk_indexes.append(ChunkIndex(
            message_start_time=buf.start_time, message_end_time=buf.end_time, chunk_start_offset=chunk_offset,
            chunk_length=chunk_length, message_index_offsets=index_offsets, message_index_length=pos - index_start,
            compression="zstd", compressed_size=len(compressed), uncompressed_size=buf.size))
        st = self.stats
        n = len(buf)
        if st.message_count == 0:
            st.message_start_time = buf.start_time
        else:
            st.message_start_time = min(st.message_start_time, buf.start_time)
        st.message_end_time = max(st.message_end_time, buf.end_time)
        st.message_count += n
        st.chunk_count += 1
        for ch, c in buf.count.items():
            st.channel_message_counts[ch] = st.channel_message_counts.get(ch, 0) + c
        self._file.flush()
        if self.tee is not None:       # usv_mj.outputs.log.live: the same messages to the live viewers,
            self.tee.chunk(self, parts)  # once the file holds them (a viewer never sees more than the file)

    def finish(self):
        if self.finished:
            return
        self._guard(self._finish)

    def _finish(self):
        """Data end, summary (schemas, channels, statistics, chunk/attachment/metadata indexes), footer."""
        if self.finished:
            return
        self.finished = True
        self._write_record(DataEnd(data_section_crc=self._crc))
        summary_start = self._file.tell()
        builder = RecordBuilder()
        offsets = []

        def group(opcode, records):
            start = builder.count
            for r in records:
                r.write(builder)
            if builder.count > start:
                offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + start,
                                             group_length=builder.count - start))

        group(Opcode.SCHEMA, self.schemas.values())
        group(Opcode.CHANNEL, self.channels.values())
        group(Opcode.STATISTICS, [self.stats])
        group(Opcode.CHUNK_INDEX, self.chunk_indexes)
        group(Opcode.ATTACHMENT_INDEX, self.attachment_indexes)
        group(Opcode.METADATA_INDEX, self.metadata_indexes)
        summary_offset_start = summary_start + builder.count
        for o in offsets:
            o.write(builder)
        summary = builder.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start), crc)
        self._file.write(summary)
        footer = RecordBuilder()
        Footer(summary_start=summary_start, summary_offset_start=summary_offset_start, summary_crc=crc).write(footer)
        self._file.write(footer.end())
        self._file.write(MAGIC)
        self._file.close()

    def abandon(self):
        """Close without a summary (what a killed process leaves), for tests and fatal errors."""
        if not self.finished:
            self.finished = True
            self._file.close()
