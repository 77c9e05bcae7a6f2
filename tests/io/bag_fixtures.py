"""Fixtures and helpers for bag tests: a synthetic recording (a car driving an arc through the test
room, written with BagRecorder) and the real bags in ../shared/bags."""

from __future__ import annotations

import dataclasses
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from mcl.filter.motion_model import compose, twist_to_odometry
from mcl.io import BagRecorder
from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import RayCaster
from tests.skips import shared_missing

REPO = Path(__file__).resolve().parents[2]
SHARED_BAGS = REPO.parent / "shared" / "bags"
BAG1 = SHARED_BAGS / "localization_bag1_2022-03-29-19-23-29.bag"
BAG2 = SHARED_BAGS / "localization_bag2_2022-03-29-19-24-34.bag"
ANGLES = np.linspace(-3 * math.pi / 4, 3 * math.pi / 4, 1081)
MOUNT = 0.3
START = np.array([5.0, 2.0, 0.0])
TWIST = np.array([1.0, 0.0, 0.15])


def shared_bag(path: Path) -> Path:
    """A bag in ../shared/bags, or skip with the reason."""
    if not path.exists():
        pytest.skip(shared_missing(path))
    return path


def record_drive(
    path: Path,
    occupancy_map: OccupancyMap,
    duration: float = 3.0,
    beams: list[int] | None = None,
    seed: int = 0,
) -> dict:
    """Drive START with TWIST for ``duration`` s: odometry at 50 Hz, scans at 40 Hz (exact cast
    + 1 cm noise, every 97th beam a no-return), truth and a fake estimate; returns the truth.

    ``beams``: per-scan beam counts to write instead of 1081 (for the beam-count error)."""
    rng = np.random.default_rng(seed)
    caster = RayCaster(occupancy_map, 30.0, method="exact")
    truth_t, truth = [], []
    with BagRecorder(path, occupancy_map, ANGLES, 30.0, MOUNT) as rec:
        rec.write_static(0.0)
        events = sorted(
            [(k * 0.02, "odom") for k in range(int(duration / 0.02) + 1)]
            + [(0.005 + k * 0.025, "scan") for k in range(int(duration / 0.025))]
        )
        for i, (t, kind) in enumerate(events):
            pose = compose(START[None], twist_to_odometry(TWIST, t))[0]
            if kind == "odom":
                rec.write_odom(t, pose - START, TWIST)  # odometry frame = start pose frame
                rec.write_truth(t, pose)
                truth_t.append(t)
                truth.append(pose)
            else:
                lidar = pose + np.array([MOUNT * math.cos(pose[2]), MOUNT * math.sin(pose[2]), 0.0])
                ranges = caster.cast(lidar, ANGLES)[0] + rng.normal(0, 0.01, ANGLES.size)
                ranges[::97] = np.nan
                if beams is not None:
                    ranges = ranges[: beams[i % len(beams)]]
                rec.write_scan(t, ranges)
                rec.write_estimate(t, pose, np.eye(3) * 1e-4, pose + rng.normal(0, 0.05, (50, 3)))
    return {"times": np.array(truth_t), "poses": np.array(truth)}


def recorded_fixture():
    """A session fixture ``recorded``: (bag folder, truth) of a 3 s synthetic drive in the room
    (each test module assigns it: ``recorded = recorded_fixture()``)."""

    @pytest.fixture(scope="session")
    def recorded(tmp_path_factory, room) -> tuple[Path, dict]:
        path = tmp_path_factory.mktemp("bags") / "drive"
        return path, record_drive(path, room)

    return recorded


# ---------------------------------------------------------------------- ROS 1 bags, and damage to them
def write_ros1_drive(
    path: Path,
    occupancy_map: OccupancyMap,
    duration: float = 4.0,
    chunk_bytes: int = 150_000,
    twice: bool = False,
    compression: str | None = None,
) -> Path:
    """The synthetic drive of :func:`record_drive` as a ROS 1 ``.bag`` (rosbags' writer, chunks of
    about ``chunk_bytes`` uncompressed bytes: several chunks per second of scans) with /scan,
    /odom and /ground_truth; returns ``path``. ``twice``: every message written twice (a bag whose
    index lists each message two times); ``compression``: ``"bz2"`` or ``"lz4"`` chunks."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ros2 = path.with_name(path.stem + "_ros2")
    record_drive(ros2, occupancy_map, duration=duration)
    store = get_typestore(Stores.ROS1_NOETIC)
    with AnyReader([ros2]) as reader:
        wanted = [c for c in reader.connections if c.topic in ("/scan", "/odom", "/ground_truth")]
        writer = Writer(path)
        writer.chunk_threshold = chunk_bytes
        if compression is not None:
            writer.set_compression(getattr(Writer.CompressionFormat, compression.upper()))
        with writer:
            conns = {
                c.id: writer.add_connection(c.topic, c.msgtype, typestore=store) for c in wanted
            }
            for con, t, raw in reader.messages(connections=wanted):
                msg = _as_ros1(reader.deserialize(raw, con.msgtype), store)
                data = store.serialize_ros1(msg, con.msgtype)
                for _ in range(2 if twice else 1):
                    writer.write(conns[con.id], t, data)
    return path


def _as_ros1(msg, store):
    """A ROS 2 message rebuilt as the same ROS 1 type (headers get ``seq`` 0)."""
    cls = store.types[msg.__msgtype__]
    values = {}
    for f in dataclasses.fields(cls):
        value = 0 if f.name == "seq" else getattr(msg, f.name)
        if hasattr(value, "__msgtype__"):
            value = _as_ros1(value, store)
        elif isinstance(value, list) and value and hasattr(value[0], "__msgtype__"):
            value = [_as_ros1(v, store) for v in value]
        values[f.name] = value
    return cls(**values)


def ros1_records(blob: bytes) -> list[tuple[int, int, int]]:
    """(start, end, op) of each top-level record of a ROS 1 bag's bytes, after the magic line."""
    out = []
    pos = len(b"#ROSBAG V2.0\n")
    while pos + 4 <= len(blob):
        (hlen,) = struct.unpack_from("<I", blob, pos)
        header = blob[pos + 4 : pos + 4 + hlen]
        (dlen,) = struct.unpack_from("<I", blob, pos + 4 + hlen)
        end = pos + 8 + hlen + dlen
        at = header.find(b"op=")
        out.append((pos, end, header[at + 3]))
        pos = end
    return out


def chunk_spans(blob: bytes) -> list[tuple[int, int, int]]:
    """(start, data start, end) of each chunk record, its index records included in the end."""
    records = ros1_records(blob)
    spans = []
    for i, (start, end, op) in enumerate(records):
        if op != 0x05:
            continue
        j = i + 1
        while j < len(records) and records[j][2] == 0x04:  # the chunk's index data records
            end = records[j][1]
            j += 1
        (hlen,) = struct.unpack_from("<I", blob, start)
        spans.append((start, start + 8 + hlen, end))
    return spans


def duplicate_chunk(src: Path, dst: Path, k: int = 1) -> int:
    """Write ``src`` to ``dst`` with chunk ``k`` (and its index records) written twice in a row,
    as a byte-level copy (the index at the end no longer matches); returns the number of messages
    in that chunk."""
    blob = src.read_bytes()
    start, _, end = chunk_spans(blob)[k]
    dst.write_bytes(blob[:end] + blob[start:end] + blob[end:])
    return sum(1 for op in _chunk_ops(blob, k) if op == 0x02)


def _chunk_ops(blob: bytes, k: int) -> list[int]:
    """The record ops inside chunk ``k`` (uncompressed chunks only)."""
    start, data, _ = chunk_spans(blob)[k]
    (hlen,) = struct.unpack_from("<I", blob, start)
    (dlen,) = struct.unpack_from("<I", blob, start + 4 + hlen)
    inner = b"#ROSBAG V2.0\n" + blob[data : data + dlen]
    return [op for _, _, op in ros1_records(inner)]


def move_chunk(src: Path, dst: Path, k: int = 1) -> None:
    """Write ``src`` to ``dst`` with chunk ``k`` (and its index records) after chunk ``k + 1``:
    log time runs backwards once, by about a chunk's span, and no message is lost or doubled."""
    blob = src.read_bytes()
    spans = chunk_spans(blob)
    a, b = spans[k], spans[k + 1]
    assert a[2] == b[0]
    dst.write_bytes(blob[: a[0]] + blob[b[0] : b[2]] + blob[a[0] : a[2]] + blob[b[2] :])
