"""Read what precedes the damage in a truncated or corrupt bag, record by record.

rosbags opens a bag through its index (ROS 1: at the end of the file; MCAP: the summary section),
which a recording cut short never got. These readers walk the file from its start instead and yield
every message they can decode, ``(topic, msgtype, log time ns, message)``, stopping quietly at the
first damaged record; :func:`mcl.io.read_bag` reports how far they got.

- ROS 1 (format 2.0): bag header, then chunk records (compression none, bz2 or lz4) holding
  connection and message-data records; connection records name topic and type.
- MCAP: the ``mcap`` package's non-seeking reader (messages in file order).
"""

from __future__ import annotations

import bz2
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = ["salvage_bag", "salvage_mcap", "salvage_ros1"]

_ROS1_MAGIC = b"#ROSBAG V2.0\n"
Message = tuple[str, str, int, Any]


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


def _records(buf: bytes) -> Iterator[tuple[dict[str, bytes], bytes]]:
    """(header fields, data) of each complete record in ``buf``."""
    pos = 0
    while pos + 4 <= len(buf):
        (hlen,) = struct.unpack_from("<I", buf, pos)
        if pos + 8 + hlen > len(buf):
            return
        header = _fields(buf[pos + 4 : pos + 4 + hlen])
        (dlen,) = struct.unpack_from("<I", buf, pos + 4 + hlen)
        start = pos + 8 + hlen
        if start + dlen > len(buf):
            return
        yield header, buf[start : start + dlen]
        pos = start + dlen


def _ros2_name(ros1_type: str) -> str:
    pkg, _, name = ros1_type.partition("/")
    return f"{pkg}/msg/{name}"


def salvage_ros1(path: Path, typestore, topics: set[str] | None = None) -> Iterator[Message]:
    """Messages of a ROS 1 bag in file order, up to the first damaged record."""
    data = path.read_bytes()
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
            msg = typestore.deserialize_ros1(body, msgtype)
            yield topic, msgtype, sec * 10**9 + nsec, msg

    for header, body in _records(data[len(_ROS1_MAGIC) :]):
        op = header.get("op", b"\x00")[0]
        if op == 0x05:  # chunk
            kind = header.get("compression", b"none").decode()
            try:
                if kind == "bz2":
                    body = bz2.decompress(body)
                elif kind == "lz4":
                    import lz4.frame

                    body = lz4.frame.decompress(body)
            except Exception:
                return
            for inner in _records(body):
                yield from handle(*inner)
        else:
            yield from handle(header, body)


def salvage_mcap(path: Path, typestore, topics: set[str] | None = None) -> Iterator[Message]:
    """Messages of an MCAP file in file order, up to the first damaged record."""
    try:
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
                    msg = typestore.deserialize_cdr(record.data, msgtype)
                    yield topic, msgtype, record.log_time, msg
        except Exception:
            return


def salvage_bag(path: Path) -> tuple[list, dict[str, str]] | None:
    """Messages readable from the start of a damaged ROS 1 or MCAP bag (None: not such a file)."""
    from rosbags.typesys import Stores, get_typestore

    if path.is_dir():
        files = sorted(path.glob("*.mcap"))
        if not files:
            return None
        path = files[0]
    with path.open("rb") as fh:
        magic = fh.read(13)
    if magic.startswith(b"#ROSBAG V2.0"):
        messages = list(salvage_ros1(path, get_typestore(Stores.ROS1_NOETIC)))
    elif magic.startswith(b"\x89MCAP"):
        messages = list(salvage_mcap(path, get_typestore(Stores.ROS2_HUMBLE)))
    else:
        return None
    return messages, {topic: kind for topic, kind, _, _ in messages}
