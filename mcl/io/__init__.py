"""Real data in and out: read ROS 1 / ROS 2 bags (`read_bag()`), record drives as ROS 2 / MCAP
bags (`BagRecorder`), stream them live to Foxglove (`start_live()`). Needs ``rosbags`` (a core dependency)."""

from mcl.io.bag_reader import (
    DEFAULT_MOUNT_OFFSET,
    DEFAULT_ODOM_TOPICS,
    DEFAULT_SCAN_TOPIC,
    BagData,
    BagError,
    read_bag,
)
from mcl.io.bag_writer import BagRecorder, DriveRecorder, start_live

__all__ = [
    "DEFAULT_MOUNT_OFFSET",
    "DEFAULT_ODOM_TOPICS",
    "DEFAULT_SCAN_TOPIC",
    "BagData",
    "BagError",
    "BagRecorder",
    "DriveRecorder",
    "read_bag",
    "start_live",
]
