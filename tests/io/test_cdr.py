"""The struct-packed CDR of mcl.io.cdr is byte for byte what rosbags serializes from the message
objects, for any pose, stamp, frame name and scan."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.typesys import Stores, get_typestore

from mcl.io import cdr

TS = get_typestore(Stores.ROS2_HUMBLE)
T = TS.types
finite = st.floats(-1e6, 1e6, allow_nan=False)
stamps = st.integers(0, 2**31 * 10**9 - 1)
frames = st.text(st.characters(min_codepoint=33, max_codepoint=126), min_size=0, max_size=12)


def _header(ns: int, frame: str):
    stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)


def _pose(x: float, y: float, th: float):
    q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(th / 2), w=math.cos(th / 2))
    return T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=q)


def _vector(x: float, y: float, z: float):
    return T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


@settings(max_examples=60, deadline=None)
@given(stamps, frames, frames, finite, finite, finite, finite, finite, finite)
def test_pose_odometry_and_tf_messages_match_rosbags(ns, frame, child, x, y, th, vx, vy, om) -> None:
    msg = T["geometry_msgs/msg/PoseStamped"](header=_header(ns, frame), pose=_pose(x, y, th))
    assert cdr.pose_stamped(ns, frame, x, y, th) == bytes(TS.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
    cov = np.arange(36, dtype=np.float64) * x
    msg = T["geometry_msgs/msg/PoseWithCovarianceStamped"](
        header=_header(ns, frame), pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(x, y, th), covariance=cov)
    )
    packed = cdr.pose_with_covariance_stamped(ns, frame, x, y, th, cov)
    assert packed == bytes(TS.serialize_cdr(msg, "geometry_msgs/msg/PoseWithCovarianceStamped"))
    zero = np.zeros(36)
    twist = T["geometry_msgs/msg/Twist"](linear=_vector(vx, vy, 0.0), angular=_vector(0.0, 0.0, om))
    msg = T["nav_msgs/msg/Odometry"](
        header=_header(ns, frame), child_frame_id=child,
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(x, y, th), covariance=zero),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=zero.copy()),
    )  # fmt: skip
    packed = cdr.odometry(ns, frame, child, (x, y, th), (vx, vy, om))
    assert packed == bytes(TS.serialize_cdr(msg, "nav_msgs/msg/Odometry"))
    q = _pose(0.0, 0.0, th).orientation
    tf = T["geometry_msgs/msg/TransformStamped"](
        header=_header(ns, frame), child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](translation=_vector(x, y, 0.0), rotation=q),
    )  # fmt: skip
    msg = T["tf2_msgs/msg/TFMessage"](transforms=[tf])
    assert cdr.tf_message(ns, frame, child, x, y, th) == bytes(TS.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))


@settings(max_examples=40, deadline=None)
@given(stamps, frames, st.integers(0, 2000), st.integers(0, 2**32 - 1))
def test_laser_scan_matches_rosbags(ns, frame, n, seed) -> None:
    ranges = np.random.default_rng(seed).uniform(0.0, 40.0, n).astype(np.float32)
    ranges[:: 7] = np.inf
    floats = (-2.35, 2.35, 0.0043, 0.0, 0.025, 0.02, 30.0)
    msg = T["sensor_msgs/msg/LaserScan"](
        header=_header(ns, frame), angle_min=floats[0], angle_max=floats[1],
        angle_increment=floats[2], time_increment=floats[3], scan_time=floats[4],
        range_min=floats[5], range_max=floats[6], ranges=ranges,
        intensities=np.zeros(0, dtype=np.float32),
    )  # fmt: skip
    assert cdr.laser_scan(ns, frame, floats, ranges) == bytes(TS.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))
