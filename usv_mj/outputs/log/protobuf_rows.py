"""The per-step topics as protobuf messages: schemas from the protobuf library, messages laid out in bulk.

A run logs one message per control step on each row topic (and on ``P/obstacles``,
``P/environment`` when it has them): 300,001 steps x 5 topics in the paper run. As JSON that cost
about 15 us of writer CPU a row, more than the compiled loop's whole step; as protobuf the writer's
row costs about 2.7 us (0.3 us of it this layout), the file is about as large (5 % more at zstd
level -3), and every float64 comes back with its bits (NaN payloads, -0.0, +-inf)
because a protobuf ``double`` is the IEEE value itself. Foxglove, the mcap CLI and the mcap
library's ``mcap-protobuf-support`` read these channels from the schema in the file.

**Fixed layout.** Every double field of these messages is written (a proto3 parser accepts a
field written explicitly with its default value), a double is 8 little-endian bytes after its tag
(wire type 1), and a topic's strings and repeated counts are the same for the whole run (an
obstacle's name, the number of obstacles). So every message of a topic is the same bytes with 8-byte
holes at fixed places. :class:`FixedLayout` finds them with the protobuf library itself: it builds
one message with a distinct sentinel in every double, serializes it, and records where each
sentinel's bytes are. Writing a block of rows is then a copy of that template and one strided copy
per field (:class:`BinaryRows`); reading is the reverse, after checking that every message has the
template's bytes outside the holes (:func:`decode_payloads`; anything else, e.g. a message written by
another writer that leaves default fields out, is parsed by the protobuf library, message by message).

**Schemas** (:func:`file_descriptor_set`): one ``.proto`` file per topic message, package
``usv_mj``, proto3, sub-messages nested in the topic's message; the MCAP schema is the serialized
``FileDescriptorSet`` (encoding ``protobuf``), named by the message's full name (``usv_mj.State``),
as Foxglove expects. Every field's documentation (units, conventions) is its leading comment in
the descriptor's ``source_code_info``.
"""

from __future__ import annotations

import dataclasses
import re
import struct

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

PACKAGE = "usv_mj"
_F = descriptor_pb2.FieldDescriptorProto


@dataclasses.dataclass(frozen=True)
class Field:
    """One field of a message: ``kind`` is "double", "string" or a nested :class:`Message`."""

    name: str
    kind: object = "double"
    doc: str = ""
    repeated: bool = False


@dataclasses.dataclass(frozen=True)
class Message:
    """A message type: ``name`` is the full name for a topic's message ("usv_mj.State"), the short
    name for a nested one ("Vector3")."""

    name: str
    fields: tuple
    doc: str = ""


def field_names(names) -> list[str]:
    """Protobuf field names for column names, in order: a name that is not an identifier
    ([A-Za-z_][A-Za-z0-9_]*: a controller may declare "speed gap" or "psi-err") gets "_" for each
    other character (and a leading "_" before a digit), then "_2", "_3", ... until unique. The
    field's comment keeps the original, and the reader maps the fields back by position."""
    out, seen = [], set()
    for name in names:
        base = re.sub(r"[^A-Za-z0-9_]", "_", str(name)) or "_"
        base = "_" + base if base[0].isdigit() else base
        candidate, k = base, 1
        while candidate in seen:
            k += 1
            candidate = f"{base}_{k}"
        seen.add(candidate)
        out.append(candidate)
    return out


def flat_message(full_name: str, fields, docs: dict | None = None, doc: str = "") -> Message:
    """A message of float64 fields only (the row topics), each documented from ``docs``; fields
    named by :func:`field_names` (a renamed one says its column's name in its comment)."""
    docs = docs or {}
    return Message(full_name, tuple(
        Field(p, "double", (docs.get(f, "") if p == f else f"column {f!r}" + (f": {docs[f]}" if f in docs else "")))
        for f, p in zip(fields, field_names(fields))), doc)


def file_descriptor_set(message: Message) -> bytes:
    """The serialized ``FileDescriptorSet`` of ``message`` (the MCAP schema data, encoding ``protobuf``)."""
    package, _, short = message.name.rpartition(".")
    fd = descriptor_pb2.FileDescriptorProto(name=f"{message.name.replace('.', '/')}.proto",
                                            package=package or PACKAGE, syntax="proto3")
    comments = fd.source_code_info

    def comment(path, text):
        if text:
            comments.location.add(path=path, span=[0, 0, 0], leading_comments=f" {text}\n")

    def fill(proto, msg, path, nested_into):
        comment(path, msg.doc)
        for i, f in enumerate(msg.fields):
            fp = proto.field.add(name=f.name, number=i + 1, json_name=f.name,
                                 label=_F.LABEL_REPEATED if f.repeated else _F.LABEL_OPTIONAL)
            if isinstance(f.kind, Message):
                fp.type = _F.TYPE_MESSAGE
                fp.type_name = f".{package or PACKAGE}.{short}.{f.kind.name}"
                if f.kind.name not in nested_into:
                    nested_into[f.kind.name] = len(nested_into)
                    sub = top.nested_type.add(name=f.kind.name)
                    fill(sub, f.kind, [4, 0, 3, nested_into[f.kind.name]], nested_into)
            elif f.kind == "string":
                fp.type = _F.TYPE_STRING
            elif f.kind == "double":
                fp.type = _F.TYPE_DOUBLE
            else:
                raise ValueError(f"field {f.name!r} of {msg.name}: kind must be 'double', 'string' or a Message")
            comment(path + [2, i], f.doc)

    top = fd.message_type.add(name=short)
    fill(top, message, [4, 0], {})
    return descriptor_pb2.FileDescriptorSet(file=[fd]).SerializeToString()


def message_class(schema_data: bytes, full_name: str):
    """The protobuf message class of ``full_name`` from a serialized ``FileDescriptorSet``."""
    pool = descriptor_pool.DescriptorPool()
    files = list(descriptor_pb2.FileDescriptorSet.FromString(schema_data).file)
    added: set = set()
    while files:               # every file after the files it depends on (a set may list them in any order)
        ready = [fd for fd in files if set(fd.dependency) <= added] or files[:1]
        for fd in ready:
            pool.Add(fd)
            added.add(fd.name)
            files.remove(fd)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(full_name))


def _sentinel(k: int) -> float:
    # a double whose 8 bytes cannot be a tag, a length or another sentinel's (checked below)
    return struct.unpack("<d", b"\xa7\x5e" + k.to_bytes(3, "little") + b"\x93\xd1\x41")[0]


def _fill(msg, shape: dict, holes: list, prefix: str = ""):
    """Set every double of ``msg`` to a new sentinel (its path appended to ``holes``), strings and
    repeated sub-messages from ``shape`` (a dict like the message: {"name": "buoy", "obstacles":
    [{...}, ...]}), depth first in field-number order."""
    for fd in msg.DESCRIPTOR.fields:
        path = prefix + fd.name
        if fd.type == fd.TYPE_MESSAGE:
            items = shape.get(fd.name, [] if _repeated(fd) else {})
            if _repeated(fd):
                for i, item in enumerate(items):
                    _fill(getattr(msg, fd.name).add(), item, holes, f"{path}.{i}.")
            else:
                _fill(getattr(msg, fd.name), items, holes, path + ".")
        elif fd.type == fd.TYPE_DOUBLE and not _repeated(fd):
            setattr(msg, fd.name, _sentinel(len(holes)))
            holes.append(path)
        elif fd.type == fd.TYPE_STRING and not _repeated(fd):
            setattr(msg, fd.name, str(shape.get(fd.name, "")))
        else:
            raise ValueError(f"{msg.DESCRIPTOR.full_name}.{fd.name}: only doubles, strings and sub-messages "
                             "have a fixed layout")


def _repeated(fd) -> bool:
    if hasattr(fd, "is_repeated"):      # protobuf >= 5.29 (``label`` went in 7)
        return bool(fd.is_repeated)
    return fd.label == fd.LABEL_REPEATED


class FixedLayout:
    """The bytes every message of one topic shares, and where its float64 values go.

    ``paths``: the doubles in the order of the block's columns (depth first in field order, e.g.
    "t", "obstacles.0.clearance_m", "obstacles.0.center.x"); ``template``: the serialized message
    (uint8); ``offsets``: the byte offset of each value's 8 bytes in it; ``strings``: the message's
    fixed strings by path.
    """

    def __init__(self, cls, shape: dict | None = None):
        self.cls = cls
        holes: list = []
        example = cls()
        _fill(example, shape or {}, holes)
        data = example.SerializeToString(deterministic=True)
        self.template = np.frombuffer(data, np.uint8)
        offsets = []
        for k, path in enumerate(holes):
            token = struct.pack("<d", _sentinel(k))
            at = data.find(token)
            if at < 0 or data.find(token, at + 1) >= 0:
                raise ValueError(f"{cls.DESCRIPTOR.full_name}: the value {path} has no fixed place")
            offsets.append(at)
        self.paths = tuple(holes)
        self.offsets = np.array(offsets, np.int64)
        self.size = len(data)
        self.strings = {k: v for k, v in flatten(example).items() if isinstance(v, str)}
        fixed = np.ones(self.size, bool)
        for at in offsets:
            fixed[at:at + 8] = False
        self.fixed = np.flatnonzero(fixed)
        self.value_bytes = (self.offsets[:, None] + np.arange(8)).reshape(-1)

    def encode_one(self, values) -> bytes:
        """One message (for tests and the odd single message): ``values`` in the order of :attr:`paths`."""
        out = self.template.copy()
        out[self.value_bytes] = np.asarray(values, "<f8").view(np.uint8)
        return out.tobytes()


def shape_of(msg) -> dict:
    """The strings and repeated sub-messages of a parsed message, as :class:`FixedLayout` takes them."""
    out = {}
    for fd, value in msg.ListFields():
        if fd.type == fd.TYPE_MESSAGE:
            out[fd.name] = [shape_of(v) for v in value] if _repeated(fd) else shape_of(value)
        elif fd.type == fd.TYPE_STRING:
            out[fd.name] = value
    return out


class BinaryRows:
    """Message records of several fixed-layout topics per row, laid out for a whole block at once.

    ``topics``: (channel id, :class:`FixedLayout`, block columns of its values) per topic; each row
    gives one MCAP Message record per topic (opcode 0x05, record length u64, channel u16,
    sequence u32, log_time u64, publish_time u64, the message), row after row. Same interface as
    :class:`usv_mj.outputs.log.mcap_file.TemplateLayout`: :meth:`encode` returns the records and their
    offsets for :meth:`usv_mj.outputs.log.mcap_file.ChunkBuffer.add_rows`.
    """

    HEADER = (("op", "u1"), ("length", "<u8"), ("channel", "<u2"), ("seq", "<u4"), ("log_time", "<u8"),
              ("publish_time", "<u8"))

    def __init__(self, topics):
        self.channel_ids = np.array([ch for ch, _, _ in topics], np.int64)
        names, formats, offsets, self._values = [], [], [], []
        template = bytearray()
        starts = []
        for j, (ch, layout, cols) in enumerate(topics):
            if len(cols) != len(layout.paths):
                raise ValueError(f"channel {ch}: {len(cols)} columns for {len(layout.paths)} values")
            starts.append(len(template))
            for name, fmt in self.HEADER:
                names.append(f"{name}{j}")
                formats.append(fmt)
                offsets.append(len(template))
                template += b"\0" * np.dtype(fmt).itemsize
            head = starts[-1]
            struct.pack_into("<BQH", template, head, 0x05, 22 + layout.size, ch)
            base = len(template)
            template += layout.template.tobytes()
            for q, (at, col) in enumerate(zip(layout.offsets, cols)):
                names.append(f"v{j}_{q}")
                formats.append("<f8")
                offsets.append(base + int(at))
                self._values.append((f"v{j}_{q}", int(col)))
        self.row_bytes = len(template)
        self.dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": self.row_bytes})
        self.template = np.frombuffer(bytes(template), np.uint8)
        self.starts = np.array(starts, np.int64)
        self.n_cols = 1 + max((c for _, c in self._values), default=0)

    def encode(self, block: np.ndarray, log_time: np.ndarray, seq) -> tuple[np.ndarray, np.ndarray]:
        """Records (uint8) and record offsets (rows x topics) of a float64 block; ``seq``: the first
        row's sequence number (the rows count up from it) or one per row."""
        n = block.shape[0]
        rows = np.empty(n, self.dtype)
        raw = rows.view(np.uint8).reshape(n, self.row_bytes)
        raw[:] = self.template
        lt = np.asarray(log_time, np.int64)
        seq = (np.arange(n, dtype=np.int64) + int(seq)) if np.ndim(seq) == 0 else np.asarray(seq, np.int64)
        seq = (seq & 0xFFFFFFFF).astype(np.uint32)
        for j in range(len(self.channel_ids)):
            rows[f"seq{j}"] = seq
            rows[f"log_time{j}"] = lt
            rows[f"publish_time{j}"] = lt
        block = np.asarray(block, np.float64)
        for name, col in self._values:
            rows[name] = block[:, col]
        offsets = np.add.outer(np.arange(n, dtype=np.int64) * self.row_bytes, self.starts)
        return raw.reshape(-1), offsets


def decode_payloads(buf: np.ndarray, starts: np.ndarray, ends: np.ndarray, layout: FixedLayout) -> np.ndarray | None:
    """The values (messages x len(layout.paths), float64) of the messages ``buf[starts[i]:ends[i]]``
    when every one has the layout's bytes outside its holes; None otherwise (parse them one by one)."""
    if starts.size == 0:
        return np.zeros((0, len(layout.paths)))
    if np.any(ends - starts != layout.size):
        return None
    payload = buf[starts[:, None] + np.arange(layout.size)]
    if not np.array_equal(payload[:, layout.fixed], np.broadcast_to(layout.template[layout.fixed],
                                                                    (len(starts), layout.fixed.size))):
        return None
    return np.ascontiguousarray(payload[:, layout.value_bytes]).view("<f8").reshape(len(starts), len(layout.paths))


def flatten(msg, prefix: str = "", out=None) -> dict:
    """A parsed message as {path: value} (doubles and strings; repeated items as "name.i.")."""
    out = {} if out is None else out
    for fd in msg.DESCRIPTOR.fields:
        path = prefix + fd.name
        value = getattr(msg, fd.name)
        if fd.type == fd.TYPE_MESSAGE:
            if _repeated(fd):
                for i, item in enumerate(value):
                    flatten(item, f"{path}.{i}.", out)
            else:
                flatten(value, path + ".", out)
        elif not _repeated(fd):
            out[path] = value
    return out
