"""Read what precedes the damage in a truncated or corrupt bag, record by record.

rosbags opens a bag through its index (ROS 1: at the end of the file; MCAP: the summary section),
which a recording cut short never got. These readers walk the file from its start instead and yield
every message they can decode, ``(topic, msgtype, log time ns, message)``, stopping quietly at the
first damaged record; `salvage_bag()` says how far they got (`Salvaged`), and
[`mcl.io.read_bag()`][mcl.io.read_bag] reports it.

- ROS 1 (format 2.0): bag header, then chunk records (compression none, bz2 or lz4) holding
  connection and message-data records; connection records name topic and type. A file that ends
  inside a chunk (a recording cut short, even in its first chunk) keeps the chunk's complete
  messages.
- MCAP: the ``mcap`` package's non-seeking reader (messages in file order).

A message that is an exact copy of one read before (same topic, log time and bytes: a chunk
written twice) is read once (`Copies`).
"""

from __future__ import annotations

import bz2
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Copies", "SalvageState", "Salvaged", "salvage_bag", "salvage_mcap", "salvage_ros1"]

_ROS1_MAGIC = b"#ROSBAG V2.0\n"
Message = tuple[str, str, int, Any]


class Copies:
    """Remembers the messages read (topic, log time ns, a digest of the bytes) to tell an exact
    copy of one of them; `n` counts the copies found."""

    def __init__(self) -> None:
        self._seen: set[tuple[str, int, int, int]] = set()
        self.n = 0

    def is_copy(self, topic: str, time_ns: int, raw: bytes | memoryview) -> bool:
        """Whether this message was read before (then it is counted, not remembered again)."""
        data = bytes(raw)
        key = (topic, int(time_ns), len(data), hash(data))
        if key in self._seen:
            self.n += 1
            return True
        self._seen.add(key)
        return False


@dataclass
class SalvageState:
    """How a walk through a damaged file went.

    Attributes:
        size: bytes of the file.
        cut_at: byte where a record runs past the end of the file (the file is truncated there),
            or None (the walk stopped at damage, or read to the end).
        cut_in_chunk: the chunk (0 = the first) the file ends inside, or None.
        chunks: chunk records met (a cut-short one included).
        cut_compression: the compression of the chunk cut short (``"none"``, ``"bz2"``,
            ``"lz4"``), or None; a bz2 block cut short decompresses to nothing.
        copies: messages dropped as exact copies of earlier ones.
    """

    size: int = 0
    cut_at: int | None = None
    cut_in_chunk: int | None = None
    chunks: int = 0
    cut_compression: str | None = None
    copies: Copies = field(default_factory=Copies)


@dataclass
class Salvaged:
    """What `salvage_bag()` read: messages in file order, topic -> type, and the walk's state."""

    messages: list[Message]
    topics: dict[str, str]
    state: SalvageState
    kind: str

    def describe(self) -> str:
        """What happened to the file, for a one-line warning or error: truncated (where) or
        corrupt."""
        s = self.state
        if s.cut_at is None:
            return f"the {self.kind} bag is corrupt"
        where = "" if s.cut_in_chunk is None else f", inside its {_ordinal(s.cut_in_chunk)} chunk"
        if s.cut_compression == "bz2":
            where += " (bz2-compressed: a bz2 block cut short cannot be decompressed)"
        return f"the {self.kind} bag is truncated: it ends after {s.size} bytes{where}"


def _ordinal(k: int) -> str:
    return {0: "first", 1: "second", 2: "third"}.get(k, f"{k + 1}th")


def _fields(buf: bytes) -> dict[str, bytes]:
    """A ROS 1 record header: (uint32 length, b'name=value') pairs."""
    out: dict[str, bytes] = {}
    pos = 0
    while pos + 4 <= len(buf):
        (n,) = struct.unpack_from("<I", buf, pos)
        pos += 4
        name, _, value = buf[pos : pos + n].partition(b"=")
        out[name.decode()] = value
        pos += n
    return out


def _records(
    buf: bytes, cut: list[int] | None = None
) -> Iterator[tuple[dict[str, bytes], bytes, bool]]:
    """(header fields, data, complete) of each record in ``buf``. A last record whose header is
    whole but whose data runs past the end is yielded with the data there is and ``complete``
    False; where a record runs past the end, its offset is appended to ``cut``."""
    pos = 0
    while pos + 4 <= len(buf):
        (hlen,) = struct.unpack_from("<I", buf, pos)
        if pos + 8 + hlen > len(buf):
            if cut is not None:
                cut.append(pos)
            return
        header = _fields(buf[pos + 4 : pos + 4 + hlen])
        (dlen,) = struct.unpack_from("<I", buf, pos + 4 + hlen)
        start = pos + 8 + hlen
        if start + dlen > len(buf):
            if cut is not None:
                cut.append(pos)
            yield header, buf[start:], False
            return
        yield header, buf[start : start + dlen], True
        pos = start + dlen
    if pos < len(buf) and cut is not None:
        cut.append(pos)


def _ros2_name(ros1_type: str) -> str:
    pkg, _, name = ros1_type.partition("/")
    return f"{pkg}/msg/{name}"


def _decompress(kind: str, body: bytes, complete: bool) -> bytes:
    """A chunk's records; of a chunk cut short, what its first bytes decompress to."""
    if kind == "bz2":
        return bz2.decompress(body) if complete else bz2.BZ2Decompressor().decompress(body)
    if kind == "lz4":
        import lz4.frame

        if complete:
            return lz4.frame.decompress(body)
        return lz4.frame.LZ4FrameDecompressor().decompress(body)
    return body


def salvage_ros1(
    path: Path,
    typestore,
    topics: set[str] | None = None,
    state: SalvageState | None = None,
) -> Iterator[Message]:
    """Messages of a ROS 1 bag in file order, up to the first damaged record, each once; a chunk
    cut short by the end of the file gives its complete messages. ``state`` records how the walk
    went."""
    state = state if state is not None else SalvageState()
    data = path.read_bytes()
    state.size = len(data)
    if not data.startswith(_ROS1_MAGIC):
        return
    conns: dict[int, tuple[str, str]] = {}

    def handle(header: dict[str, bytes], body: bytes) -> Iterator[Message]:
        op = header.get("op", b"\x00")[0]
        if op == 0x07:  # connection
            info = _fields(body)
            conn = struct.unpack("<I", header["conn"])[0]
            conns[conn] = (header["topic"].decode(), _ros2_name(info["type"].decode()))
        elif op == 0x02:  # message data
            conn = struct.unpack("<I", header["conn"])[0]
            if conn not in conns:
                return
            topic, msgtype = conns[conn]
            if topics is not None and topic not in topics:
                return
            sec, nsec = struct.unpack("<II", header["time"])
            t = sec * 10**9 + nsec
            if state.copies.is_copy(topic, t, body):
                return
            msg = typestore.deserialize_ros1(body, msgtype)
            yield topic, msgtype, t, msg

    cut: list[int] = []
    try:
        for header, body, complete in _records(data[len(_ROS1_MAGIC) :], cut):
            op = header.get("op", b"\x00")[0]
            if op == 0x05:  # chunk
                state.chunks += 1
                kind = header.get("compression", b"none").decode()
                if not complete:
                    state.cut_in_chunk, state.cut_compression = state.chunks - 1, kind
                inner = _decompress(kind, body, complete)
                for fields, record, whole in _records(inner):
                    if whole:
                        yield from handle(fields, record)
            elif complete:
                yield from handle(header, body)
    except Exception:  # a damaged record (bad lengths, names, types, compressed data): stop here
        return
    if cut:
        state.cut_at = len(_ROS1_MAGIC) + cut[0]


def salvage_mcap(
    path: Path,
    typestore,
    topics: set[str] | None = None,
    state: SalvageState | None = None,
) -> Iterator[Message]:
    """Messages of an MCAP file in file order, up to the first damaged record, each once."""
    state = state if state is not None else SalvageState()
    state.size = path.stat().st_size
    try:
        from mcap.exceptions import EndOfFile
        from mcap.records import Channel, Schema
        from mcap.records import Message as McapMessage
        from mcap.stream_reader import StreamReader
    except ImportError:
        return
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    with path.open("rb") as fh:
        try:
            for record in StreamReader(fh, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
                elif isinstance(record, McapMessage) and record.channel_id in channels:
                    topic, msgtype = channels[record.channel_id]
                    if topics is not None and topic not in topics:
                        continue
                    if state.copies.is_copy(topic, record.log_time, record.data):
                        continue
                    msg = typestore.deserialize_cdr(record.data, msgtype)
                    yield topic, msgtype, record.log_time, msg
        except (EndOfFile, EOFError, struct.error):
            state.cut_at = state.size
        except Exception:
            return


def salvage_bag(path: Path) -> Salvaged | None:
    """Messages readable from the start of a damaged ROS 1 or MCAP bag (None: not such a file)."""
    from rosbags.typesys import Stores, get_typestore

    if path.is_dir():
        files = sorted(path.glob("*.mcap"))
        if not files:
            return None
        path = files[0]
    with path.open("rb") as fh:
        magic = fh.read(13)
    state = SalvageState()
    if magic.startswith(b"#ROSBAG V2.0"):
        kind = "ROS 1"
        messages = list(salvage_ros1(path, get_typestore(Stores.ROS1_NOETIC), state=state))
    elif magic.startswith(b"\x89MCAP"):
        kind = "MCAP"
        messages = list(salvage_mcap(path, get_typestore(Stores.ROS2_HUMBLE), state=state))
    else:
        return None
    topics = {topic: msgtype for topic, msgtype, _, _ in messages}
    return Salvaged(messages, topics, state, kind)
