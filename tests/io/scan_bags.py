"""Small ROS 2 bags (MCAP or sqlite3 ``.db3``) with a LaserScan header of one's choosing: hostile
scans for the reader's checks (0 beams, NaN / infinite angles and ranges, ranges whose length
disagrees with the angles, huge beam counts). Written with rosbags, as a real recorder would."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_scan_bag"]


def write_scan_bag(
    path: Path,
    storage: str = "mcap",
    beams: int = 10,
    angle_min: float = -1.0,
    angle_increment: float = 0.2,
    range_min: float = 0.02,
    range_max: float = 30.0,
    n_ranges: int | None = None,
    scans: int = 5,
) -> Path:
    """A bag at ``path`` with ``scans`` LaserScans on ``/scan`` (``n_ranges`` ranges of 2 m,
    default ``beams``; ``angle_max`` as ``beams`` imply) and as many still Odometry messages on
    ``/odom``, 25 ms apart; ``storage`` is ``"mcap"`` or ``"sqlite3"``. Returns ``path``."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    vec = T["geometry_msgs/msg/Vector3"]
    zero = vec(x=0.0, y=0.0, z=0.0)
    pose = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    with Writer(path, version=9 if storage == "mcap" else 8, storage_plugin=plugin) as writer:
        scan_con = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        odom_con = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        for k in range(scans):
            ns = 10**9 + k * 25_000_000
            stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            scan = T["sensor_msgs/msg/LaserScan"](
                header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="laser"),
                angle_min=angle_min,
                angle_max=angle_min + angle_increment * max(beams - 1, 0),
                angle_increment=angle_increment,
                time_increment=0.0,
                scan_time=0.025,
                range_min=range_min,
                range_max=range_max,
                ranges=np.full(beams if n_ranges is None else n_ranges, 2.0, np.float32),
                intensities=np.zeros(0, np.float32),
            )
            writer.write(scan_con, ns, store.serialize_cdr(scan, "sensor_msgs/msg/LaserScan"))
            odom = T["nav_msgs/msg/Odometry"](
                header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="odom"),
                child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                    covariance=np.zeros(36),
                ),
            )
            writer.write(odom_con, ns, store.serialize_cdr(odom, "nav_msgs/msg/Odometry"))
    return path
