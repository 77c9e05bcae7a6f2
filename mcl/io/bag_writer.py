"""Record a drive as a ROS 2 bag with MCAP storage (rosbags' writer; opens in Foxglove).

Topics (ROS 2 Humble message types, frames as amcl publishes them):

- ``/scan`` ``sensor_msgs/msg/LaserScan`` (frame ``laser``; no-returns as +inf, which every ROS
  consumer reads as out of range),
- ``/odom`` ``nav_msgs/msg/Odometry`` (``odom`` -> ``base_link``, twist in base_link),
- ``/tf`` ``tf2_msgs/msg/TFMessage``: ``odom`` -> ``base_link`` from the odometry and
  ``map`` -> ``odom`` from the estimate (so that map -> base_link is the estimate),
- ``/tf_static``: ``base_link`` -> ``laser`` (the mount); ``/ground_truth``
  ``geometry_msgs/msg/PoseStamped`` (map frame, the simulator's true pose),
- ``/pf/pose`` ``geometry_msgs/msg/PoseWithCovarianceStamped`` (map frame, the estimate), ``/pf/particles`` ``geometry_msgs/msg/PoseArray`` (map frame, a subsample),
- ``/map`` ``nav_msgs/msg/OccupancyGrid`` once at the start (0 free, 100 occupied or unknown).

Times: seconds of the drive, as ns after [EPOCH_NS][mcl.io.bag_writer.EPOCH_NS] (2000-01-01),
so the bag's first message is at (about) 0 s for [read_bag][mcl.io.bag_reader.read_bag].
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

import gymnasium as gym
import numpy as np

import mcl.io.cdr as cdr
from mcl.io.bag_folder import remove_recording
from mcl.io.cdr import ros2_typestore
from racecar_sim.maps import OccupancyMap

if TYPE_CHECKING:
    from mcl.io.live import LiveServer
    from mcl.wrappers.hooks import StepRecord

__all__ = ["EPOCH_NS", "LIVE_RATE", "TOPICS", "UNPACED_LIVE_RATE", "BagRecorder", "DriveRecorder", "start_live"]

LIVE_RATE = 20.0
"""The live view's default frames per second (simulated time): what a screen shows smoothly."""
UNPACED_LIVE_RATE = 10.0
"""Frames per wall-clock second of ``drive --live-speed 0`` (it shares the cores with the server)."""

EPOCH_NS = 946_684_800 * 10**9
"""Nanoseconds of the bag's time 0 (2000-01-01 00:00:00 UTC)."""

TOPICS = {
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/ground_truth": "geometry_msgs/msg/PoseStamped",
    "/pf/pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/pf/particles": "geometry_msgs/msg/PoseArray",
    "/map": "nav_msgs/msg/OccupancyGrid",
}
"""Topic -> ROS 2 message type of every recording (a folder is replaced only when its bag has
exactly these: [bag_folder][mcl.io.bag_folder])."""


class BagRecorder:
    """Writes a ROS 2 / MCAP bag folder (module docstring), and / or streams the same messages
    live to Foxglove ([LiveServer][mcl.io.live.LiveServer]); use as a context manager.

    Args:
        path: the bag folder to create; None writes no bag. An existing folder is replaced
            when ``overwrite`` and it holds exactly a recording of ours
            ([recording_problem][mcl.io.bag_folder.recording_problem]), else refused.
        occupancy_map: written once to ``/map``.
        angles: (B,) car-frame beam angles of the scans, radians, evenly spaced.
        range_max: metres; the lidar's range (range_min is 0.02 m).
        mount_offset: metres from base_link forward to the lidar (written to ``/tf_static``).
        scan_period: seconds between scans (LaserScan.scan_time).
        max_particles: particles per ``/pf/particles`` message (an even stride through them).
        overwrite: replace an existing recording of ours at ``path``.
        live: a Foxglove server that gets every message too (see [mcl.io.live][mcl.io.live]).
        epoch_ns: time 0 in ns since the Unix epoch (a replay streams on its bag's own clock).

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is False, or it is not exactly a
            recording of ours ([NotOurs][racecar_sim.file_guard.NotOurs]; nothing is removed).
    """

    def __init__(
        self,
        path: str | os.PathLike[str] | None,
        occupancy_map: OccupancyMap,
        angles: np.ndarray,
        range_max: float,
        mount_offset: float,
        scan_period: float = 0.025,
        max_particles: int = 500,
        overwrite: bool = True,
        live: LiveServer | None = None,
        epoch_ns: int = EPOCH_NS,
    ) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        if path is None and live is None:
            raise ValueError("BagRecorder needs a bag folder, a live server or both")
        self.path = Path(path) if path is not None else None
        if self.path is not None and os.path.lexists(self.path):
            if not overwrite:
                raise FileExistsError(f"{self.path} exists")
            remove_recording(self.path, TOPICS)
        self.ts = ros2_typestore()
        self.live, self.epoch_ns = live, int(epoch_ns)
        self._t = self.ts.types
        self.map = occupancy_map
        self.angles = np.asarray(angles, dtype=np.float64)
        self.range_max = float(range_max)
        self.mount_offset = float(mount_offset)
        self.scan_period = float(scan_period)
        self.max_particles = int(max_particles)
        self._writer, self._cons = None, {}
        if self.path is not None:
            self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
            self._writer.open()
            self._cons = {
                topic: self._writer.add_connection(topic, kind, typestore=self.ts)
                for topic, kind in TOPICS.items()
            }
        self._last_odom: np.ndarray | None = None
        self.live_due = True
        """Whether this moment's messages go to the live server (a bag gets every message)."""
        self.batch_live = False  # True: live messages wait for flush_live() (one write a step)
        self._map_written = False
        self.n_messages = 0

    # ------------------------------------------------------------------ helpers
    def wants(self, topic: str) -> bool:
        """Whether a message on ``topic`` goes anywhere (the bag, or a live subscriber)."""
        return self._writer is not None or (
            self.live is not None and self.live_due and self.live.wants(topic)
        )

    def _write(self, topic: str, t: float, msg) -> None:
        if self.wants(topic):
            self._write_raw(topic, t, self.ts.serialize_cdr(msg, TOPICS[topic]))

    def _write_raw(self, topic: str, t: float, data: bytes) -> None:
        ns = self._stamp_ns(t)
        if self._writer is not None:
            self._writer.write(self._cons[topic], ns, data)
        if self.live is not None and self.live_due:
            batch = {"flush": False} if self.batch_live else {}  # a plain publish() for other sinks
            self.live.publish(topic, ns, bytes(data), **batch)
        self.n_messages += 1

    def _stamp_ns(self, t: float) -> int:
        return self.epoch_ns + round(max(t, 0.0) * 1e9)

    def _header(self, t: float, frame: str):
        ns = self._stamp_ns(t)
        time = self._t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        return self._t["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def _pose(self, x: float, y: float, theta: float):
        T = self._t
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
            orientation=self._quat(theta),
        )

    def _quat(self, theta: float):
        return self._t["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(theta / 2.0), w=math.cos(theta / 2.0)
        )

    def _transform(self, t: float, parent: str, child: str, x: float, y: float, theta: float):
        T = self._t
        return T["geometry_msgs/msg/TransformStamped"](
            header=self._header(t, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=0.0),
                rotation=self._quat(theta),
            ),
        )

    # ------------------------------------------------------------------ topics
    def write_static(self, t: float = 0.0) -> None:
        """``/map`` (the occupancy grid) and ``/tf_static`` (base_link -> laser), once."""
        if self._map_written:
            return
        self._map_written = True
        T, m = self._t, self.map
        # ROS grids start at the bottom-left cell, rows going up: flip the image rows.
        data = np.where(m.occupied[::-1], 100, 0).astype(np.int8).reshape(-1)
        ox, oy, oyaw = m.origin
        info = T["nav_msgs/msg/MapMetaData"](
            map_load_time=self._header(t, "map").stamp, resolution=float(m.resolution),
            width=m.width, height=m.height, origin=self._pose(ox, oy, oyaw),
        )  # fmt: skip
        grid = T["nav_msgs/msg/OccupancyGrid"](header=self._header(t, "map"), info=info, data=data)
        self._write("/map", t, grid)
        tf = self._transform(t, "base_link", "laser", self.mount_offset, 0.0, 0.0)
        self._write("/tf_static", t, T["tf2_msgs/msg/TFMessage"](transforms=[tf]))

    def write_scan(self, t: float, ranges: np.ndarray) -> None:
        """``/scan``: ranges in metres; NaN, inf and values beyond range_max become +inf."""
        if not self.wants("/scan"):
            return
        r = np.asarray(ranges, dtype=np.float32).copy()
        r[~np.isfinite(r) | (r > self.range_max)] = np.inf
        a = self.angles
        increment = float((a[-1] - a[0]) / max(a.size - 1, 1))
        floats = (float(a[0]), float(a[-1]), increment, 0.0, self.scan_period, 0.02, self.range_max)
        self._write_raw("/scan", t, cdr.laser_scan(self._stamp_ns(t), "laser", floats, r))

    def write_odom(self, t: float, pose: np.ndarray, twist: np.ndarray) -> None:
        """``/odom`` and the ``odom`` -> ``base_link`` part of ``/tf``.

        Args:
            pose: [x, y, theta] of base_link in the odometry frame (integrated odometry).
            twist: [vx, vy, omega] in base_link (m/s, rad/s).
        """
        self._last_odom = np.array([float(v) for v in pose])
        if not (self.wants("/odom") or self.wants("/tf")):
            return
        x, y, th = (float(v) for v in pose)
        twist = tuple(float(v) for v in twist)
        ns = self._stamp_ns(t)
        if self.wants("/odom"):
            self._write_raw("/odom", t, cdr.odometry(ns, "odom", "base_link", (x, y, th), twist))
        if self.wants("/tf"):
            self._write_raw("/tf", t, cdr.tf_message(ns, "odom", "base_link", x, y, th))

    def write_truth(self, t: float, pose: np.ndarray) -> None:
        """``/ground_truth``: the true base_link pose [x, y, theta] in the map frame."""
        if not self.wants("/ground_truth"):
            return
        x, y, th = (float(v) for v in pose)
        self._write_raw("/ground_truth", t, cdr.pose_stamped(self._stamp_ns(t), "map", x, y, th))

    def write_estimate(
        self,
        t: float,
        pose: np.ndarray,
        covariance: np.ndarray,
        particles: np.ndarray | None = None,
    ) -> None:
        """``/pf/pose``, ``map`` -> ``odom`` on ``/tf`` and (when given) ``/pf/particles``.

        Args:
            pose: the estimate [x, y, theta] of base_link in the map frame.
            covariance: (3, 3) over [x, y, theta] (m², rad²), put in the 6 x 6 ROS layout.
            particles: (N, 3) map-frame poses; at most ``max_particles`` are written.
        """
        if not (self.wants("/pf/pose") or self.wants("/tf") or self.wants("/pf/particles")):
            return
        cov6 = np.zeros((6, 6))
        idx = [0, 1, 5]
        cov6[np.ix_(idx, idx)] = np.asarray(covariance, dtype=np.float64)
        ns = self._stamp_ns(t)
        ex, ey, eth = (float(v) for v in pose)
        if self.wants("/pf/pose"):
            msg = cdr.pose_with_covariance_stamped(ns, "map", ex, ey, eth, cov6)
            self._write_raw("/pf/pose", t, msg)
        if self._last_odom is not None and self.wants("/tf"):
            # map -> odom = estimate (map <- base) composed with the inverse of odom <- base.
            ox, oy, oth = self._last_odom
            yaw = eth - oth
            c_, s_ = math.cos(yaw), math.sin(yaw)
            tx, ty = ex - (c_ * ox - s_ * oy), ey - (s_ * ox + c_ * oy)
            self._write_raw("/tf", t, cdr.tf_message(ns, "map", "odom", tx, ty, yaw))
        if particles is not None and len(particles) and self.wants("/pf/particles"):
            p = np.asarray(particles, dtype=np.float64)
            step = max(1, math.ceil(len(p) / self.max_particles))
            self._write_raw("/pf/particles", t, cdr.pose_array(self._stamp_ns(t), "map", p[::step]))

    def flush_live(self) -> None:
        """Hand the queued live messages (``batch_live``) to the server's pipe in one write."""
        if self.live is not None and self.batch_live:
            self.live.flush()

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Finish the MCAP file and its metadata.yaml (the live server is the caller's to stop)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> BagRecorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def start_live(address: str | int, wait: bool = True) -> LiveServer:
    """A Foxglove WebSocket server for the recording's topics at ``"[HOST:]PORT"`` (bound to
    127.0.0.1 unless a host is given; ``wait``: see [LiveServer][mcl.io.live.LiveServer]); see
    [mcl.io.live][mcl.io.live]."""
    from mcl.io.live import LiveServer

    return LiveServer(address, TOPICS, ros2_typestore(), wait=wait)


class DriveRecorder:
    """Records a [LocalizationWrapper][mcl.wrappers.single.LocalizationWrapper] drive step by step: a
    step hook ([`mcl.wrappers.hooks`][mcl.wrappers.hooks]; attach it with
    [`add_step_hook()`][mcl.wrappers.single.LocalizationWrapper.add_step_hook] or the wrapper's
    ``on_step``). Odometry every step, the scan, the estimate and the particles at every fresh
    scan, the true pose every step.

    Odometry: the env's twist of step k describes the motion from ``t_k - dt`` to ``t_k``, so its
    message is stamped ``t_k - dt`` with the integrated odometry pose at that time (a reader that
    holds each twist until the next message integrates exactly the simulated motion). Scans and
    truth are stamped ``t_k``; the sim's no-returns (``max_range``) are written as +inf. A record
    of step 0 (a reset) starts the odometry again at the origin.

    Args:
        path: the bag folder to create; None writes no bag (``live`` only).
        wrapped: the wrapper around a ``RacecarSim-v0`` env (its lidar, its world map and its
            time step are recorded).
        live: a Foxglove server ([start_live][mcl.io.bag_writer.start_live]), the same messages;
            the caller closes it after the recorder.
        live_rate: the live view's frames per second of simulated time (1-1000 Hz): a step's
            messages go live when ``1 / live_rate`` seconds have passed since the last step that
            went live (a reset always does); the bag gets every message. A viewer needs no more
            than a screen shows, and the drive does not pay for packing what no one can see.
        live_wall_rate: also at most this many frames per wall-clock second (None: no bound): a
            drive faster than real time then streams a screen's worth (skipping simulated frames)
            and pays per wall second what a real-time one does.

    Example:
        ```python
        server = start_live(0)  # or None; ws://localhost:PORT
        recorder = DriveRecorder("out/bag", env, live=server)
        env.add_step_hook(recorder)
        ...  # env.reset(), env.step(...)
        recorder.close()
        server.close()
        ```
    """

    def __init__(
        self,
        path: str | os.PathLike[str] | None,
        wrapped: gym.Env,
        live: LiveServer | None = None,
        live_rate: float = LIVE_RATE,
        live_wall_rate: float | None = None,
    ) -> None:
        wall = 1.0 if live_wall_rate is None else live_wall_rate
        for name, rate in (("live_rate", live_rate), ("live_wall_rate", wall)):
            if isinstance(rate, bool) or not (isinstance(rate, int | float) and 1.0 <= rate <= 1000.0):
                raise ValueError(f"{name} must be 1 to 1000 frames per second, got {rate!r}")
        self.live_period = 1.0 / float(live_rate)
        self.live_wall_period = 0.0 if live_wall_rate is None else 1.0 / float(live_wall_rate)
        self._live_t = self._live_wall = -math.inf
        env = wrapped.unwrapped
        lidar = env.lidar
        self.max_range = float(lidar.params.max_range)
        self.dt = float(env.dt)
        self.recorder = BagRecorder(path, env.map, lidar.angles, self.max_range,
                                    lidar.params.mount_offset, lidar.period, live=live)  # fmt: skip
        self.recorder.batch_live = True  # each step's messages in one write (flush_live)
        self.recorder.write_static(0.0)
        self._odom = np.zeros(3)
        self._first = True

    def __call__(self, record: StepRecord) -> None:
        """Write the messages of one reset or step."""
        from mcl.filter.motion_model import compose, twist_to_odometry

        t = record.time
        rec = self.recorder
        if record.step == 0:  # a new episode: odometry starts again
            self._odom = np.zeros(3)
            self._first = True
            self._live_t = self._live_wall = -math.inf
        now = time.perf_counter() if self.live_wall_period else 0.0
        wall_due = now - self._live_wall >= self.live_wall_period
        rec.live_due = wall_due and t - self._live_t >= self.live_period - 1e-9
        if rec.live_due:
            self._live_t, self._live_wall = t, now
        if not self._first:
            twist = np.asarray(record.odom, dtype=np.float64)
            rec.write_odom(t - self.dt, self._odom, twist)
            self._odom = compose(self._odom[None], twist_to_odometry(twist, self.dt))[0]
        rec.write_truth(t, record.truth)
        if self._first or record.new_scan:
            if rec.wants("/scan"):
                scan = np.array(record.scan, dtype=np.float64)
                scan[scan >= self.max_range] = np.inf
                rec.write_scan(t, scan)
            if any(rec.wants(topic) for topic in ("/pf/pose", "/tf", "/pf/particles")):
                rec.write_estimate(t, record.estimate, record.covariance, record.particles)
        self._first = False
        rec.flush_live()

    def close(self) -> None:
        """Finish the bag (the live server is the caller's to stop)."""
        self.recorder.close()
