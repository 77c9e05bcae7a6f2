"""Read a lidar + odometry recording from a ROS 1 ``.bag`` or a ROS 2 bag (sqlite3 or MCAP storage).

Uses ``rosbags`` (pure Python, no ROS installation). `read_bag()` returns a `BagData`:
every scan of one ``sensor_msgs/LaserScan`` topic, every message of one ``nav_msgs/Odometry``
topic, the lidar mount, and ``/ground_truth`` poses when the bag has them (a recorded simulated
drive, [`mcl.io.bag_writer`][mcl.io.bag_writer]).

Conventions:

- Times are seconds since the bag's first message (the recording's log time, the order the filter
  replays them in).
- Scan ranges are metres, float64; a beam outside ``[range_min, range_max]`` or not finite is a
  *no-return* and becomes NaN (a real Hokuyo reports 65.533 m for those: not a wall 65 m away).
- Beam angles are car-frame radians: ``angle_min + i * angle_increment`` turned by the mount's yaw
  (and mirrored when ``/tf_static`` says the lidar is mounted upside down).
- The mount (metres ahead of base_link, along its x axis) comes from ``/tf_static`` (the chain of
  transforms from ``base_link`` to the scan's frame) when the bag has it, else from the caller's
  default (0.275 m, the MIT racecar).
- Odometry: the twist ``[vx, vy, omega]`` in the child (car) frame, m/s and rad/s, and the pose
  ``[x, y, theta]`` in the odometry frame.

Errors are `BagError` with one line saying what is wrong: not a bag, a missing topic (naming
the topics that are there), scans whose beam count changes. A truncated or corrupt file keeps what
was read before the damage and says so in `BagData.warnings`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mcl.io.bag_order import TimeOrder, copies_warning
from mcl.io.salvage import Copies, salvage_bag
from mcl.io.scan_checks import scan_problem, scan_warning
from mcl.io.tf_mount import BASE_FRAME, static_mount, yaw_of

__all__ = [
    "DEFAULT_MOUNT_OFFSET",
    "DEFAULT_ODOM_TOPICS",
    "DEFAULT_SCAN_TOPIC",
    "BagData",
    "BagError",
    "read_bag",
]

DEFAULT_SCAN_TOPIC = "/scan"
DEFAULT_ODOM_TOPICS: tuple[str, ...] = ("/vesc/odom", "/odom")
"""Odometry topics tried in order when none is named."""
DEFAULT_MOUNT_OFFSET = 0.275
"""Metres from base_link forward to the lidar on the MIT racecar (used without /tf_static)."""
GROUND_TRUTH_TOPIC = "/ground_truth"


class BagError(ValueError):
    """A bag that cannot be replayed; the message is one line naming the problem."""


@dataclass
class BagData:
    """What `read_bag()` read (module docstring for units and frames).

    Attributes:
        path: the bag (a ``.bag`` file, an ``.mcap`` / ``.db3`` file or a ROS 2 bag folder).
        scan_topic, odom_topic: the topics read.
        scan_times: (S,) seconds since the first message of the bag.
        scans: (S, B) ranges in metres, NaN for no-returns.
        angles: (B,) car-frame beam angles, radians.
        range_min, range_max: metres, of the first scan.
        scan_frame: the scans' frame id.
        odom_times: (O,) seconds. odom_twist: (O, 3) [vx, vy, omega]. odom_pose: (O, 3) [x, y, theta].
        mount_offset: metres ahead of base_link. mount_source: ``"tf_static"`` or ``"default"``.
        truth_times, truth: (G,) seconds and (G, 3) map-frame poses from ``/ground_truth``, or None.
        duration: seconds from the first to the last message read.
        topics: every topic of the bag -> message type.
        warnings: problems that did not stop the reading (truncation, mount not along x, ...).
        scan_stamps, odom_stamps: (S,) and (O,) the messages' header stamps on the same clock
            (seconds since the bag's first message's log time); a Hokuyo stamps its first beam.
            They default to ``scan_times`` / ``odom_times``. Log times jitter by up to ~40 ms
            on the real bags, so the noise calibration, which pairs scans with odometry, uses
            these.
        time_increment: seconds between two consecutive beams of one sweep (0 when unknown).
        start_ns: log time of the bag's first message, ns since the Unix epoch (time 0 above).
    """

    path: Path
    scan_topic: str
    odom_topic: str
    scan_times: np.ndarray
    scans: np.ndarray
    angles: np.ndarray
    range_min: float
    range_max: float
    scan_frame: str
    odom_times: np.ndarray
    odom_twist: np.ndarray
    odom_pose: np.ndarray
    mount_offset: float
    mount_source: str
    truth_times: np.ndarray | None = None
    truth: np.ndarray | None = None
    duration: float = 0.0
    topics: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    scan_stamps: np.ndarray | None = None
    odom_stamps: np.ndarray | None = None
    time_increment: float = 0.0
    start_ns: int = 0

    def __post_init__(self) -> None:
        if self.scan_stamps is None:
            self.scan_stamps = self.scan_times
        if self.odom_stamps is None:
            self.odom_stamps = self.odom_times

    @property
    def name(self) -> str:
        """The bag's file (or folder) name."""
        return self.path.name

    @property
    def n_scans(self) -> int:
        """Number of scans read."""
        return int(self.scans.shape[0])

    @property
    def n_beams(self) -> int:
        """Beams per scan."""
        return int(self.scans.shape[1])

    def summary(self) -> str:
        """One line: file, duration, scans, odometry, mount."""
        return (
            f"{self.path.name}: {self.duration:.1f} s, {self.n_scans} scans x {self.n_beams} beams "
            f"on {self.scan_topic}, {self.odom_times.size} odometry messages on {self.odom_topic}, "
            f"lidar {self.mount_offset:.3f} m ahead of {BASE_FRAME} ({self.mount_source})"
        )


def _header_seconds(msg, t0_ns: int) -> float:
    """A message's header stamp in seconds after ``t0_ns`` (nanoseconds, the bag's clock)."""
    stamp = msg.header.stamp
    return (stamp.sec * 1_000_000_000 + stamp.nanosec - t0_ns) * 1e-9


def _typestore_for(path: Path):
    from rosbags.typesys import Stores, get_typestore

    # ROS 1 bags and ROS 2 bags without definitions both need a store; the reader prefers the
    # definitions stored in the bag itself.
    return get_typestore(Stores.ROS1_NOETIC if path.suffix == ".bag" else Stores.ROS2_HUMBLE)


def _open_paths(path: Path) -> list[Path]:
    """The path to give AnyReader: a ROS 1 file, or a ROS 2 bag folder (a lone .mcap/.db3 file is
    read through its folder when that has a metadata.yaml)."""
    if path.is_dir():
        return [path]
    if path.suffix in (".mcap", ".db3") and (path.parent / "metadata.yaml").exists():
        return [path.parent]
    return [path]


def read_bag(
    path: str | os.PathLike[str],
    scan_topic: str = DEFAULT_SCAN_TOPIC,
    odom_topic: str | None = None,
    mount_offset: float | None = None,
    default_mount_offset: float = DEFAULT_MOUNT_OFFSET,
) -> BagData:
    """Read scans, odometry, mount and ground truth from a ROS 1 or ROS 2 bag.

    Args:
        path: a ROS 1 ``.bag`` file, a ROS 2 bag folder, or the ``.mcap`` / ``.db3`` file in one.
        scan_topic: the ``sensor_msgs/LaserScan`` topic.
        odom_topic: the ``nav_msgs/Odometry`` topic; None tries `DEFAULT_ODOM_TOPICS`.
        mount_offset: metres from base_link to the lidar; None takes it from ``/tf_static``
            when the bag has the transform, else ``default_mount_offset``.
        default_mount_offset: metres, see ``mount_offset``.

    Raises:
        BagError: not a bag, a topic missing (the message lists the bag's topics), scans of
            different beam counts, no scan or no odometry message.
        FileNotFoundError: the path does not exist.
    """
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no such bag: {path}")
    warnings: list[str] = []
    reader = None
    copies = Copies()
    try:
        reader = AnyReader(_open_paths(path), default_typestore=_typestore_for(path))
        reader.open()
        topics = {c.topic: c.msgtype for c in reader.connections}
    except Exception as exc:  # rosbags raises several types for unreadable files
        salvaged = salvage_bag(path)
        if not salvaged or not salvaged.messages:
            if salvaged is not None and salvaged.state.cut_at is not None:
                raise BagError(
                    f"{path}: {salvaged.describe()}, before its first complete message"
                ) from None
            raise BagError(f"{path}: not a readable ROS 1 or ROS 2 bag ({exc})") from None
        messages, topics = salvaged.messages, salvaged.topics
        reader = None
        last = (messages[-1][2] - messages[0][2]) * 1e-9
        why = "" if salvaged.state.cut_at is not None else f" ({exc})"
        warnings.append(
            f"{salvaged.describe()}{why}; read {len(messages)} messages ({last:.3f} s) from its "
            "start"
        )
        copies = salvaged.state.copies
    try:

        def missing(what: str, wanted: str) -> BagError:
            have = ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "none"
            damage = f" ({warnings[0]})" if warnings else ""
            return BagError(f"{path.name}: no {what} topic {wanted}; the bag has: {have}{damage}")

        if scan_topic not in topics:
            raise missing("scan", scan_topic)
        if odom_topic is None:
            odom_topic = next((t for t in DEFAULT_ODOM_TOPICS if t in topics), None)
            if odom_topic is None:
                raise missing("odometry", " or ".join(DEFAULT_ODOM_TOPICS))
        elif odom_topic not in topics:
            raise missing("odometry", odom_topic)
        for topic, kind in ((scan_topic, "LaserScan"), (odom_topic, "Odometry")):
            if not topics[topic].endswith("/" + kind):
                raise BagError(f"{path.name}: topic {topic} holds {topics[topic]}, not {kind}")
        truth_topic = GROUND_TRUTH_TOPIC if GROUND_TRUTH_TOPIC in topics else None
        wanted = {scan_topic, odom_topic} | ({truth_topic} if truth_topic else set())

        if reader is not None:
            cons = [c for c in reader.connections if c.topic in wanted]
            t0 = reader.start_time

            def source():
                for con, t, raw in reader.messages(connections=cons):
                    if not copies.is_copy(con.topic, t, raw):
                        yield con.topic, con.msgtype, t, reader.deserialize(raw, con.msgtype)

            stream = source()
        else:
            t0 = min(m[2] for m in messages)
            stream = iter([m for m in messages if m[0] in wanted])
        col = _Collected()
        last_t = t0
        order = TimeOrder(t0)
        try:
            for topic, _kind, t, msg in stream:
                order.add(t)
                last_t = max(last_t, t)
                col.add(path, topic, (t - t0) * 1e-9, t0, msg, scan_topic, odom_topic)
        except BagError:
            raise
        except Exception as exc:
            warnings.append(
                f"the bag is truncated or corrupt after {(last_t - t0) * 1e-9:.3f} s "
                f"({type(exc).__name__}: {exc}); kept the {len(col.scans)} scans and "
                f"{len(col.odom_t)} odometry messages read before"
            )
        if copies.n:
            warnings.append(copies_warning(copies.n))
        if order.n_back:
            warnings.append(order.warning())
            col.sort_by_time()
        if not col.scans:
            raise BagError(f"{path.name}: no scan could be read on {scan_topic}")
        if not col.odom_t:
            raise BagError(f"{path.name}: no odometry message could be read on {odom_topic}")
        first = col.first
        angles = first.angle_min + first.angle_increment * np.arange(col.scans[0].size)
        mismatch = scan_warning(first, col.scans[0].size)
        if mismatch is not None:
            warnings.append(mismatch)
        scan_frame = str(first.header.frame_id)

        mount_source = "argument"
        yaw, mirrored = 0.0, False
        if mount_offset is None:
            mount = None
            if "/tf_static" in topics:
                try:
                    if reader is not None:
                        tf_cons = [c for c in reader.connections if c.topic == "/tf_static"]
                        tf_msgs = [
                            reader.deserialize(raw, con.msgtype)
                            for con, _t, raw in reader.messages(connections=tf_cons)
                        ]
                    else:
                        tf_msgs = [m[3] for m in messages if m[0] == "/tf_static"]
                    mount = static_mount(tf_msgs, scan_frame, warnings)
                except Exception as exc:
                    warnings.append(f"/tf_static could not be read ({exc})")
            if mount is not None:
                mount_offset, yaw, mirrored = mount
                mount_source = "tf_static"
            else:
                mount_offset, mount_source = default_mount_offset, "default"
        end = last_t if warnings or reader is None else max(last_t, reader.end_time)
        duration = (end - t0) * 1e-9
    finally:
        if reader is not None:
            reader.close()

    return BagData(
        path=path,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        scan_times=np.asarray(col.scan_t),
        scans=np.vstack(col.scans),
        angles=yaw + (-1.0 if mirrored else 1.0) * np.asarray(angles, dtype=np.float64),
        range_min=float(first.range_min),
        range_max=float(first.range_max),
        scan_frame=scan_frame,
        odom_times=np.asarray(col.odom_t),
        odom_twist=np.asarray(col.odom_tw, dtype=np.float64).reshape(-1, 3),
        odom_pose=np.asarray(col.odom_p, dtype=np.float64).reshape(-1, 3),
        mount_offset=float(mount_offset),
        mount_source=mount_source,
        truth_times=np.asarray(col.truth_t) if col.truth_p else None,
        truth=np.asarray(col.truth_p, dtype=np.float64) if col.truth_p else None,
        duration=float(duration),
        topics=topics,
        warnings=warnings,
        scan_stamps=np.asarray(col.scan_stamp),
        odom_stamps=np.asarray(col.odom_stamp),
        time_increment=float(first.time_increment),
        start_ns=int(t0),
    )


class _Collected:
    """Messages gathered by topic while reading."""

    def sort_by_time(self) -> None:
        """Each topic's messages in the order of their log times (stable)."""
        for times, *lists in (
            ("scan_t", "scan_stamp", "scans"),
            ("odom_t", "odom_stamp", "odom_tw", "odom_p"),
            ("truth_t", "truth_p"),
        ):
            keys = getattr(self, times)
            order = sorted(range(len(keys)), key=keys.__getitem__)
            for name in (times, *lists):
                values = getattr(self, name)
                setattr(self, name, [values[i] for i in order])

    def __init__(self) -> None:
        self.first = None
        self.scan_t: list[float] = []
        self.scan_stamp: list[float] = []
        self.odom_stamp: list[float] = []
        self.scans: list[np.ndarray] = []
        self.odom_t: list[float] = []
        self.odom_tw: list[tuple[float, float, float]] = []
        self.odom_p: list[tuple[float, float, float]] = []
        self.truth_t: list[float] = []
        self.truth_p: list[tuple[float, float, float]] = []

    def add(
        self, path: Path, topic: str, sec: float, t0_ns: int, msg, scan_topic: str, odom_topic: str
    ) -> None:
        """Keep ``msg`` (read on ``topic`` at ``sec`` seconds since the start ``t0_ns``)."""
        if topic == scan_topic:
            ranges = np.asarray(msg.ranges, dtype=np.float64)
            if self.first is None:
                problem = scan_problem(msg, ranges.size)
                if problem is not None:
                    raise BagError(f"{path.name}: the first scan on {scan_topic} {problem}")
                self.first = msg
            elif ranges.size != self.scans[0].size:
                raise BagError(
                    f"{path.name}: scan {len(self.scans)} on {scan_topic} at {sec:.3f} s has "
                    f"{ranges.size} beams, the first had {self.scans[0].size}"
                )
            with np.errstate(invalid="ignore"):
                bad = ~np.isfinite(ranges) | (ranges < msg.range_min) | (ranges > msg.range_max)
            ranges[bad] = np.nan
            self.scan_t.append(sec)
            self.scan_stamp.append(_header_seconds(msg, t0_ns))
            self.scans.append(ranges)
        elif topic == odom_topic:
            tw, pose = msg.twist.twist, msg.pose.pose
            self.odom_t.append(sec)
            self.odom_stamp.append(_header_seconds(msg, t0_ns))
            self.odom_tw.append((tw.linear.x, tw.linear.y, tw.angular.z))
            self.odom_p.append((pose.position.x, pose.position.y, yaw_of(pose.orientation)))
        else:
            pose = msg.pose
            self.truth_t.append(sec)
            self.truth_p.append((pose.position.x, pose.position.y, yaw_of(pose.orientation)))
