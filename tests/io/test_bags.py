"""Reading bags (ROS 1, ROS 2 / MCAP, damaged ones) and recording them."""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from mcl.io import BagError, read_bag
from tests.io.bag_fixtures import ANGLES, BAG1, MOUNT, record_drive, recorded_fixture, shared_bag

recorded = recorded_fixture()


def test_recording_reads_back_with_mcap_alone(recorded):
    path, truth = recorded
    from mcap.reader import make_reader

    (mcap_file,) = path.glob("*.mcap")
    with mcap_file.open("rb") as fh:
        reader = make_reader(fh)
        counts: dict[str, int] = {}
        for _schema, channel, _message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts["/map"] == 1
    assert counts["/scan"] == 120
    assert counts["/odom"] == counts["/ground_truth"] == len(truth["times"])
    assert counts["/tf"] == counts["/odom"] + counts["/pf/pose"]  # odom->base_link, map->odom
    assert {"/tf_static", "/pf/particles"} <= set(counts)


def test_recording_reads_back(recorded):
    path, truth = recorded
    data = read_bag(path)
    assert data.odom_topic == "/odom"  # the fallback after /vesc/odom
    assert data.n_scans == 120 and data.n_beams == ANGLES.size
    assert data.mount_source == "tf_static"
    assert data.mount_offset == pytest.approx(MOUNT)
    np.testing.assert_allclose(data.angles, ANGLES, atol=1e-6)
    # no-returns (written as +inf) come back as NaN, every other beam as written
    assert np.isnan(data.scans[:, ::97]).all()
    assert np.isfinite(np.delete(data.scans, np.s_[::97], axis=1)).all()
    assert data.truth is not None
    np.testing.assert_allclose(data.truth, truth["poses"], atol=1e-6)
    np.testing.assert_allclose(data.odom_twist[0], [1.0, 0.0, 0.15])
    assert data.scan_times[0] == pytest.approx(0.005, abs=1e-6)  # first message at 0 s
    assert not data.warnings


def test_missing_topic_names_the_topics_there(recorded):
    path, _ = recorded
    with pytest.raises(BagError, match=r"no scan topic /laser; the bag has: .*/scan \(sensor_msgs"):
        read_bag(path, scan_topic="/laser")
    with pytest.raises(BagError, match="no odometry topic /vesc/odom;"):
        read_bag(path, odom_topic="/vesc/odom")
    with pytest.raises(BagError, match="holds nav_msgs/msg/Odometry, not LaserScan"):
        read_bag(path, scan_topic="/odom")


def test_not_a_bag(tmp_path):
    for name, content, message in (
        ("notes.bag", b"hello", "not a readable ROS 1 or ROS 2 bag"),
        ("x.mcap", b"\x89MCAP0\r\n", "MCAP bag is truncated: it ends after 8 bytes, before its"),
    ):
        (tmp_path / name).write_bytes(content)
        with pytest.raises(BagError, match=message):
            read_bag(tmp_path / name)
    with pytest.raises(FileNotFoundError):
        read_bag(tmp_path / "absent.bag")


def test_beam_count_change(tmp_path, room):
    record_drive(tmp_path / "b", room, duration=0.3, beams=[1081, 1081, 1080])
    with pytest.raises(BagError, match="has 1080 beams, the first had 1081"):
        read_bag(tmp_path / "b")


def test_truncated_mcap_keeps_what_was_read(tmp_path, room):
    # long enough for several 1 MB chunks; cut in the last one
    record_drive(tmp_path / "long", room, duration=12.0)
    (mcap_file,) = (tmp_path / "long").glob("*.mcap")
    full = read_bag(tmp_path / "long")
    blob = mcap_file.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(blob[: int(len(blob) * 0.8)])
    data = read_bag(cut)
    assert data.warnings and "MCAP bag is truncated" in data.warnings[0]
    assert 0 < data.n_scans < full.n_scans
    np.testing.assert_array_equal(data.scans, full.scans[: data.n_scans])


def test_truncated_ros1_keeps_what_was_read(tmp_path):
    blob = shared_bag(BAG1).read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(blob[: len(blob) // 2])
    data = read_bag(cut)
    full = read_bag(BAG1)
    assert data.warnings and "ROS 1 bag is truncated" in data.warnings[0]
    assert 0 < data.n_scans < full.n_scans
    np.testing.assert_array_equal(data.scans, full.scans[: data.n_scans])
    np.testing.assert_allclose(data.scan_times, full.scan_times[: data.n_scans])


def test_shared_bag_facts():
    data = read_bag(shared_bag(BAG1))
    assert data.odom_topic == "/vesc/odom" and data.mount_source == "default"
    assert data.mount_offset == pytest.approx(0.275)
    assert (data.n_scans, data.n_beams) == (281, 1081)
    assert data.angles[0] == pytest.approx(-2.356, abs=1e-3)
    valid = data.scans[np.isfinite(data.scans)]
    assert valid.max() <= data.range_max and valid.min() >= data.range_min
    assert np.isnan(data.scans).mean() > 0.01  # the Hokuyo's 65.533 m no-returns
    assert data.duration == pytest.approx(7.0, abs=0.05)
    # Header stamps, not log times: a 40 Hz Hokuyo stamps its sweeps 25 ms apart (the log times
    # jitter), each sweep 1081 beams x time_increment long.
    assert data.time_increment * data.n_beams == pytest.approx(0.01875, rel=0.01)
    assert np.median(np.diff(data.scan_stamps)) == pytest.approx(0.025, abs=5e-4)
    assert np.std(np.diff(data.scan_stamps)) < 0.1 * np.std(np.diff(data.scan_times))
    assert not np.allclose(data.scan_stamps, data.scan_times, atol=1e-3)
    assert np.all(np.abs(data.odom_stamps - data.odom_times) < 0.1)


def test_ros1_converted_to_mcap_replays_to_the_same_place(tmp_path, stata_map):
    from rosbags.convert import convert

    from mcl.experiments.replay import ReplayConfig, replay

    src = shared_bag(BAG1)
    dst = tmp_path / "bag1_ros2"
    convert(
        [src], dst, "mcap", 9, None, "none", None, None, [], [], [], []
    )  # what `rosbags-convert --dst-storage mcap` does
    ros1, ros2 = read_bag(src), read_bag(dst)
    np.testing.assert_array_equal(ros1.scans, ros2.scans)
    np.testing.assert_array_equal(ros1.odom_twist, ros2.odom_twist)
    np.testing.assert_allclose(ros1.scan_times, ros2.scan_times)

    def head(d, n=121):  # to 3.0 s
        return dataclasses.replace(d, scans=d.scans[:n], scan_times=d.scan_times[:n])

    config = ReplayConfig(init=(-21.08, -0.06, 1.26), seed=3)
    a = replay(head(ros1), stata_map, config)
    b = replay(head(ros2), stata_map, config)
    np.testing.assert_allclose(a.rows[:, :4], b.rows[:, :4])
    # where a brute-force search of the floor puts the lidar 3 s in (issue 11): (-19.4, 5.7)
    x, y, th = a.rows[-1, 1:4]
    lidar = (x + 0.275 * math.cos(th), y + 0.275 * math.sin(th))
    assert math.hypot(lidar[0] + 19.4, lidar[1] - 5.7) < 0.3


def test_damaged_copy_of_recording_keeps_static_mount(recorded, tmp_path):
    path, _ = recorded
    copy = tmp_path / "copy"
    shutil.copytree(path, copy)
    (copy / "metadata.yaml").unlink()
    (mcap_file,) = copy.glob("*.mcap")
    data = read_bag(mcap_file)  # no metadata.yaml: read through the mcap file alone
    assert data.n_scans == 120 and data.mount_source == "tf_static"


def test_recorded_file_is_under_the_folder(recorded):
    path, _ = recorded
    assert Path(path, "metadata.yaml").exists()


def test_ros2_sqlite3_bag_reads_the_same(tmp_path):
    from rosbags.convert import convert

    src = shared_bag(BAG1)
    dst = tmp_path / "bag1_db3"
    convert([src], dst, "sqlite3", 8, None, "none", None, None, [], [], [], [])
    ros1, ros2 = read_bag(src), read_bag(dst)
    assert next(dst.glob("*.db3")).exists()
    np.testing.assert_array_equal(ros1.scans, ros2.scans)
    np.testing.assert_array_equal(ros1.odom_pose, ros2.odom_pose)
    assert ros2.odom_topic == "/vesc/odom" and ros2.mount_source == "default"


def _tf(parent: str, child: str, x: float, y: float, yaw: float, upside_down: bool = False):
    """A /tf_static transform as the reader sees it (roll pi when upside down)."""
    from types import SimpleNamespace as NS

    if upside_down:  # yaw then roll pi: q = q_yaw * q_roll
        cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
        q = NS(x=cy, y=sy, z=0.0, w=0.0)
    else:
        q = NS(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
    return NS(
        header=NS(frame_id=parent),
        child_frame_id=child,
        transform=NS(translation=NS(x=x, y=y, z=0.1), rotation=q),
    )


def test_static_mount_follows_the_chain_and_upside_down_lidars():
    from types import SimpleNamespace as NS

    from mcl.io.tf_mount import static_mount as _static_mount

    chain = [
        NS(
            transforms=[
                _tf("base_link", "mast", 0.2, 0.0, 0.0),
                _tf("mast", "laser", 0.1, 0.0, 0.3),
            ]
        )
    ]
    x, yaw, mirrored = _static_mount(chain, "laser", [])
    assert (x, yaw, mirrored) == (pytest.approx(0.3), pytest.approx(0.3), False)
    flipped = [NS(transforms=[_tf("base_link", "laser", 0.275, 0.0, 0.0, upside_down=True)])]
    x, yaw, mirrored = _static_mount(flipped, "laser", [])
    assert x == pytest.approx(0.275) and mirrored and yaw == pytest.approx(0.0, abs=1e-12)
    warnings: list[str] = []
    _static_mount([NS(transforms=[_tf("base_link", "laser", 0.2, 0.1, 0.0)])], "laser", warnings)
    assert warnings and "to the side" in warnings[0]
    assert _static_mount(chain, "other_frame", []) is None


@pytest.mark.parametrize("frame", ["map", "ab", "a_longer_frame"])
def test_pose_array_bytes_decode_as_rosbags_serializes_them(frame: str) -> None:
    from rosbags.typesys import Stores, get_typestore

    from mcl.io.cdr import pose_array

    ts = get_typestore(Stores.ROS2_HUMBLE)
    poses = np.random.default_rng(len(frame)).normal(0, 5, (23, 3))
    stamp = 946_684_800 * 10**9 + 123_456_789
    data = pose_array(stamp, frame, poses)
    msg = ts.deserialize_cdr(data, "geometry_msgs/msg/PoseArray")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (946_684_800, 123_456_789)
    assert msg.header.frame_id == frame and len(msg.poses) == len(poses)
    got = np.array([[p.position.x, p.position.y, p.position.z, p.orientation.z, p.orientation.w] for p in msg.poses])
    np.testing.assert_array_equal(got[:, :3], np.column_stack([poses[:, :2], np.zeros(len(poses))]))
    np.testing.assert_allclose(got[:, 3:], np.column_stack([np.sin(poses[:, 2] / 2), np.cos(poses[:, 2] / 2)]), atol=1e-15)
    again = ts.serialize_cdr(msg, "geometry_msgs/msg/PoseArray")
    assert len(again) == len(data)  # the same layout (padding, alignment) as rosbags writes
