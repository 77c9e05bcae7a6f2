"""A recorded drive as arrays: lidar scans and wheel odometry read from a ROS bag with ``rosbags``.

Only what the noise calibration needs: scan stamps and ranges, the scan geometry, and the odometry's
stamps, twists and integrated poses. No-returns (not finite, or outside [range_min, range_max], as
the Hokuyo's 65.533 m) become NaN.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Recording", "read_recording"]


@dataclass(frozen=True)
class Recording:
    """Scans and odometry of one bag; times in seconds since the bag's first message.

    Attributes:
        name: the bag's file name.
        scan_times: (S,) header stamp of each scan (the first beam's time for a Hokuyo).
        ranges: (S, B) float64 metres, NaN for a no-return.
        angles: (B,) beam angles in the lidar frame, radians.
        time_increment: seconds between two consecutive beams of one sweep.
        range_min, range_max: the scans' valid interval, metres.
        odom_times: (K,) header stamps of the odometry messages.
        odom_twist: (K, 3) [vx m/s, vy m/s, omega rad/s], car frame.
        odom_pose: (K, 3) [x, y, theta] the odometry's own integrated pose (odom frame).
    """

    name: str
    scan_times: np.ndarray
    ranges: np.ndarray
    angles: np.ndarray
    time_increment: float
    range_min: float
    range_max: float
    odom_times: np.ndarray
    odom_twist: np.ndarray
    odom_pose: np.ndarray


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def read_recording(
    path: str | os.PathLike[str], scan_topic: str = "/scan", odom_topic: str = "/vesc/odom"
) -> Recording:
    """Read ``path`` (a ROS 1 ``.bag`` or a ROS 2 bag directory).

    Raises:
        ValueError: the bag has no such topic (the message names the topics it has), or the scans
            change their beam count.
    """
    from rosbags.highlevel import AnyReader  # core dependency, imported when needed

    path = Path(path)
    scans: list[np.ndarray] = []
    scan_t: list[float] = []
    odom_t: list[float] = []
    twist: list[tuple[float, float, float]] = []
    pose: list[tuple[float, float, float]] = []
    geometry = None
    with AnyReader([path]) as reader:
        topics = {c.topic for c in reader.connections}
        for topic in (scan_topic, odom_topic):
            if topic not in topics:
                raise ValueError(f"{path.name}: no topic {topic!r}; it has {sorted(topics)}")
        wanted = [c for c in reader.connections if c.topic in (scan_topic, odom_topic)]
        t_first = None
        for conn, t_ns, raw in reader.messages(connections=wanted):
            t_first = t_ns * 1e-9 if t_first is None else t_first
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == scan_topic:
                r = np.asarray(msg.ranges, dtype=np.float64)
                geo = (msg.angle_min, msg.angle_increment, r.size, msg.range_min, msg.range_max)
                if geometry is None:
                    geometry = (*geo, msg.time_increment)
                elif geo[:3] != geometry[:3]:
                    raise ValueError(f"{path.name}: the scans change their beam geometry")
                bad = ~np.isfinite(r) | (r < msg.range_min) | (r > msg.range_max)
                r[bad] = np.nan
                scans.append(r)
                scan_t.append(_stamp(msg))
            else:
                odom_t.append(_stamp(msg))
                tw = msg.twist.twist
                twist.append((tw.linear.x, tw.linear.y, tw.angular.z))
                p, q = msg.pose.pose.position, msg.pose.pose.orientation
                yaw = np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
                pose.append((p.x, p.y, yaw))
    if not scans or not odom_t:
        raise ValueError(f"{path.name}: no scans or no odometry messages")
    assert geometry is not None and t_first is not None
    a0, da, n, rmin, rmax, dt_beam = geometry
    t0 = min(scan_t[0], odom_t[0])
    return Recording(
        name=path.name,
        scan_times=np.asarray(scan_t) - t0,
        ranges=np.vstack(scans),
        angles=a0 + da * np.arange(n),
        time_increment=float(dt_beam),
        range_min=float(rmin),
        range_max=float(rmax),
        odom_times=np.asarray(odom_t) - t0,
        odom_twist=np.asarray(twist, dtype=np.float64),
        odom_pose=np.asarray(pose, dtype=np.float64),
    )
