"""The live view: a Foxglove WebSocket client on localhost receives and decodes the drive's
messages while it runs (a [DriveRecorder][mcl.io.bag_writer.DriveRecorder] streaming to a server,
attached as the wrapper's step hook, and ``racecar-sim drive --live``), and the drive is the same
with and without it.

The client is a plain ``websockets`` client speaking the Foxglove WebSocket protocol as served by
foxglove-sdk (subprotocol ``foxglove.sdk.v1``): it reads the server's ``advertise``, sends
``subscribe`` for the channels it wants, and decodes the binary ``messageData`` frames (opcode 1,
subscription id u32, log time u64, then the CDR payload)."""

from __future__ import annotations

import asyncio
import json
import math
import os
import re
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import racecar_sim  # noqa: F401
from mcl.io.live import DEFAULT_HOST, parse_live_address

pytest.importorskip("foxglove", reason="the live view needs foxglove-sdk (extra [live])")
websockets = pytest.importorskip("websockets", reason="the test client needs websockets ([dev])")
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from mcl import LocalizationWrapper  # noqa: E402
from mcl.io.bag_writer import EPOCH_NS  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)
SUBPROTOCOL = "foxglove.sdk.v1"


class Client(threading.Thread):
    """Subscribes to ``topics`` on ws://127.0.0.1:port and keeps every message's payload."""

    def __init__(self, port: int, topics: set[str], until, timeout: float = 120.0) -> None:
        super().__init__(daemon=True)
        self.port, self.topics, self.until, self.timeout = port, topics, until, timeout
        self.messages: dict[str, list[bytes]] = {}
        self.advertised: dict[str, dict] = {}
        self.subscribed = threading.Event()
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            asyncio.run(self._run())
        except BaseException as exc:  # reported by the test
            self.error = exc

    async def _run(self) -> None:
        url = f"ws://127.0.0.1:{self.port}"
        async with websockets.connect(url, subprotocols=[SUBPROTOCOL]) as ws:
            subscriptions: dict[int, str] = {}
            stop_at = time.monotonic() + self.timeout
            while time.monotonic() < stop_at and not self.until(self.messages):
                frame = await asyncio.wait_for(ws.recv(), stop_at - time.monotonic())
                if isinstance(frame, str):
                    message = json.loads(frame)
                    if message.get("op") != "advertise":
                        continue
                    wanted = []
                    for channel in message["channels"]:
                        self.advertised[channel["topic"]] = channel
                        if channel["topic"] in self.topics:
                            sub_id = len(subscriptions) + 1
                            subscriptions[sub_id] = channel["topic"]
                            wanted.append({"id": sub_id, "channelId": channel["id"]})
                    if wanted:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": wanted}))
                        self.subscribed.set()
                elif frame[0] == 1:  # messageData
                    sub_id, _log_time = struct.unpack_from("<IQ", frame, 1)
                    self.messages.setdefault(subscriptions[sub_id], []).append(bytes(frame[13:]))


def test_live_address_parsing() -> None:
    assert parse_live_address("8765") == (DEFAULT_HOST, 8765)
    assert parse_live_address(8765) == ("127.0.0.1", 8765)
    assert parse_live_address("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert parse_live_address("[::1]:9000") == ("::1", 9000)
    for bad in ("", "abc", "host:", ":80", "70000", "-1", "host:port"):
        with pytest.raises(ValueError, match="PORT"):
            parse_live_address(bad)


def _wait(condition, seconds: float = 60.0) -> None:
    stop_at = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < stop_at, "timed out"
        time.sleep(0.02)


def test_wrapper_streams_scans_the_client_decodes_and_the_map_to_a_late_subscriber() -> None:
    from mcl.io import DriveRecorder, start_live

    env = LocalizationWrapper(gym.make("RacecarSim-v0", map="office"), {"filter": {"n_particles": 200}})
    server = start_live(0)
    recorder = DriveRecorder(None, env, live=server)
    env.add_step_hook(recorder)
    assert server is not None and server.host == "127.0.0.1" and server.port > 0
    obs, info = env.reset(seed=3)  # /map goes out now, before anyone listens
    client = Client(server.port, {"/scan", "/map", "/pf/particles", "/tf"}, lambda m: len(m.get("/scan", [])) >= 5 and "/map" in m)
    client.start()
    assert client.subscribed.wait(60), client.error
    _wait(lambda: server.wants("/scan"))
    sent = []
    for _ in range(40):
        obs, _, _, _, info = env.step([0.0, 1.0])
        if info["new_scan"]:
            sent.append(obs["scan"].copy())
    client.join(60)
    env.close()
    recorder.close()
    server.close()
    assert client.error is None, client.error
    assert client.advertised["/scan"]["schemaName"] == "sensor_msgs/msg/LaserScan"
    assert client.advertised["/scan"]["encoding"] == "cdr"
    scans = [TYPESTORE.deserialize_cdr(m, "sensor_msgs/msg/LaserScan") for m in client.messages["/scan"]]
    assert scans[0].header.frame_id == "laser" and len(scans[0].ranges) == obs["scan"].size
    max_range = env.unwrapped.lidar.params.max_range
    expected = [np.where(s >= max_range, np.inf, s).astype(np.float32) for s in sent]
    # each scan received is one the env measured (the live view sends 20 frames a second of 40 scans)
    for scan in scans:
        assert any(np.array_equal(scan.ranges, e) for e in expected)
    assert len(scans) >= 5
    grid = TYPESTORE.deserialize_cdr(client.messages["/map"][0], "nav_msgs/msg/OccupancyGrid")
    assert (grid.info.width, grid.info.height) == (env.map.width, env.map.height)
    particles = TYPESTORE.deserialize_cdr(client.messages["/pf/particles"][-1], "geometry_msgs/msg/PoseArray")
    assert 0 < len(particles.poses) <= 200


def _drive(tmp_path: Path, name: str, *extra: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "mcl.cli.main", "drive", "--map", "office", "--duration", "3",
           "--particles", "300", "--video-fps", "0", "--quiet", "--seed", "4",
           "--out", str(tmp_path / name), *extra]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _log_without_timing(path: Path) -> list[list[str]]:
    lines = path.read_text(encoding="utf-8").splitlines()
    column = lines[0].split(",").index("update_s")  # wall-clock timing differs from run to run
    return [[v for j, v in enumerate(line.split(",")) if j != column] for line in lines]


@pytest.mark.slow
def test_drive_live_streams_to_a_client_and_drives_the_same(tmp_path: Path) -> None:
    plain = _drive(tmp_path, "plain")
    _, plain_err = plain.communicate(timeout=600)
    assert plain.returncode == 0, plain_err
    # paced at 0.4 x real time: the 3 s drive lasts 7.5 s of wall time, so a client that takes a few
    # seconds to connect on a loaded machine still sees 20 of its 60 scans
    live = _drive(tmp_path, "live", "--live", "0", "--live-speed", "0.4")
    url = None
    for line in live.stderr:  # the server says where it listens once it does
        match = re.search(r"ws://localhost:(\d+)", line)
        if match:
            url = int(match.group(1))
            break
    assert url is not None, "no live-view address printed"
    client = Client(url, {"/scan", "/ground_truth"}, lambda m: len(m.get("/scan", [])) >= 20, timeout=300)
    client.start()
    _, err = live.communicate(timeout=600)
    client.join(30)
    assert live.returncode == 0, err
    assert client.error is None, client.error
    scans = [TYPESTORE.deserialize_cdr(m, "sensor_msgs/msg/LaserScan") for m in client.messages["/scan"]]
    assert len(scans) >= 20 and all(len(s.ranges) == 1080 for s in scans)
    stamps = [s.header.stamp.sec + 1e-9 * s.header.stamp.nanosec for s in scans]
    assert np.all(np.diff(stamps) > 0)  # in the order they were made
    assert _log_without_timing(tmp_path / "live" / "error_log.csv") == _log_without_timing(
        tmp_path / "plain" / "error_log.csv"
    )


@pytest.mark.slow
def test_replay_live_streams_the_filter_on_a_recorded_drive(tmp_path: Path) -> None:
    from mcl.io import DriveRecorder
    from racecar_sim.drivers import WallFollower

    env = LocalizationWrapper(gym.make("RacecarSim-v0", map="office"), {"filter": {"n_particles": 200}})
    recorder = DriveRecorder(tmp_path / "bag", env)
    env.add_step_hook(recorder)  # records the reset and every step
    obs, info = env.reset(seed=1)
    start = info["pose"]  # the replay starts its filter here
    driver = WallFollower.for_env(env)
    for _ in range(120):  # 3 s
        obs, _, _, _, info = env.step(driver(obs))
    recorder.close()
    cmd = [sys.executable, "-m", "mcl.cli.main", "replay", str(tmp_path / "bag"), "--map", "office",
           "--init", ",".join(f"{v:.4f}" for v in start), "--video-fps", "0",
           "--out", str(tmp_path / "replay"), "--live", "0", "--live-speed", "1"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    port = None
    for line in proc.stderr:
        match = re.search(r"ws://localhost:(\d+)", line)
        if match:
            port = int(match.group(1))
            break
    assert port is not None, "no live-view address printed"
    client = Client(port, {"/scan", "/pf/pose", "/map"}, lambda m: len(m.get("/pf/pose", [])) >= 30, timeout=300)
    client.start()
    _, err = proc.communicate(timeout=600)
    client.join(30)
    assert proc.returncode == 0, err
    assert client.error is None, client.error
    assert "/map" in client.messages
    scans = [TYPESTORE.deserialize_cdr(m, "sensor_msgs/msg/LaserScan") for m in client.messages["/scan"]]
    assert len(scans) >= 30 and len(scans[0].ranges) == obs["scan"].size
    rows = np.genfromtxt(tmp_path / "replay" / "trajectory.csv", delimiter=",", names=True)
    for payload in client.messages["/pf/pose"]:  # each streamed estimate is the replay's own
        msg = TYPESTORE.deserialize_cdr(payload, "geometry_msgs/msg/PoseWithCovarianceStamped")
        t = (msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec - EPOCH_NS) * 1e-9
        row = rows[np.argmin(np.abs(rows["time"] - t))]
        assert abs(row["time"] - t) < 1e-6
        np.testing.assert_allclose(
            [msg.pose.pose.position.x, msg.pose.pose.position.y], [row["x"], row["y"]], atol=1e-6
        )


def test_the_live_view_goes_at_its_own_rate_and_the_bag_gets_every_scan(tmp_path: Path) -> None:
    from mcl.io import DriveRecorder, read_bag, start_live

    env = LocalizationWrapper(gym.make("RacecarSim-v0", map="office"), {"filter": {"n_particles": 200}})
    server = start_live(0)
    recorder = DriveRecorder(tmp_path / "bag", env, live=server, live_rate=10.0)
    env.add_step_hook(recorder)
    env.reset(seed=3)
    client = Client(server.port, {"/scan", "/ground_truth"}, lambda m: False, timeout=30)
    client.start()
    assert client.subscribed.wait(60), client.error
    _wait(lambda: server.wants("/scan") and server.wants("/ground_truth"))
    n_scans = 0
    for _ in range(80):  # 2 s at dt = 0.025 s, a 40 Hz lidar: a fresh scan every step
        _, _, _, _, info = env.step([0.0, 1.0])
        n_scans += bool(info["new_scan"])
    time.sleep(1.0)
    recorder.close()
    server.close()
    client.join(30)
    truths = [TYPESTORE.deserialize_cdr(m, "geometry_msgs/msg/PoseStamped") for m in client.messages["/ground_truth"]]
    stamps = np.array([t.header.stamp.sec + 1e-9 * t.header.stamp.nanosec for t in truths])
    assert 19 <= len(stamps) <= 21  # 10 frames a second of the 2 s
    np.testing.assert_allclose(np.diff(stamps), 0.1, atol=1e-6)
    assert len(client.messages["/scan"]) <= len(stamps)
    bag = read_bag(tmp_path / "bag")
    assert len(bag.scans) == n_scans + 1  # the reset's scan and every fresh one


@pytest.mark.parametrize("rate", [0.5, 1001, float("nan"), True, "20"])
def test_a_live_rate_out_of_range_is_refused_naming_it(rate) -> None:
    from mcl.io import DriveRecorder

    env = LocalizationWrapper(gym.make("RacecarSim-v0", map="corridor"), {"filter": {"n_particles": 50}})
    with pytest.raises(ValueError, match="live_rate must be 1 to 1000"):
        DriveRecorder(None, env, live_rate=rate)


def test_both_transforms_of_a_scan_step_reach_the_viewer() -> None:
    """A scan step publishes ``/tf`` twice (odom -> base_link from the odometry, map -> odom from
    the estimate); the step's batch sends both, neither replaces the other."""
    from mcl.io import DriveRecorder, start_live

    env = LocalizationWrapper(gym.make("RacecarSim-v0", map="office"), {"filter": {"n_particles": 200}})
    server = start_live(0)
    recorder = DriveRecorder(None, env, live=server)
    env.add_step_hook(recorder)
    env.reset(seed=3)
    client = Client(server.port, {"/tf"}, lambda m: len(m.get("/tf", [])) >= 10, timeout=60)
    client.start()
    assert client.subscribed.wait(60), client.error
    _wait(lambda: server.wants("/tf"))
    for _ in range(40):  # 1 s: 20 live frames, each with a fresh scan
        env.step([0.0, 1.0])
    client.join(60)
    recorder.close()
    server.close()
    assert client.error is None, client.error
    messages = [TYPESTORE.deserialize_cdr(m, "tf2_msgs/msg/TFMessage") for m in client.messages["/tf"]]
    pairs = {(t.header.frame_id, t.child_frame_id) for m in messages for t in m.transforms}
    assert pairs == {("odom", "base_link"), ("map", "odom")}
    assert server.n_dropped == 0


def test_a_server_started_without_waiting_serves_what_was_published_before_it_listened() -> None:
    """``wait=False`` returns before the server process listens (the drive goes on meanwhile);
    the latched ``/map`` published then reaches a client that subscribes later."""
    from mcl.io import start_live

    server = start_live(0, wait=False)
    try:
        payload = bytes(range(256)) * 10
        server.publish("/map", 5, payload)  # the pipe holds it until the server reads it
        client = Client(server.port, {"/map"}, lambda m: "/map" in m, timeout=60)
        client.start()
        client.join(90)
        assert client.error is None, client.error
        assert client.messages["/map"] == [payload]
    finally:
        server.close()


class _Sink:
    """A live server stand-in that wants every topic and keeps (topic, log time) of each message."""

    def __init__(self) -> None:
        self.messages: list[tuple[str, int]] = []

    def wants(self, topic: str) -> bool:
        return True

    def publish(self, topic: str, log_time_ns: int, data: bytes, flush: bool = True) -> None:
        self.messages.append((topic, log_time_ns))

    def flush(self) -> None:
        pass


@pytest.mark.parametrize("wall_rate", [None, 1.0])
def test_a_wall_rate_bounds_the_frames_of_a_drive_faster_than_real_time(wall_rate) -> None:
    from mcl.io import DriveRecorder

    env = LocalizationWrapper(gym.make("RacecarSim-v0", map="corridor"), {"filter": {"n_particles": 50}})
    sink = _Sink()
    env.add_step_hook(DriveRecorder(None, env, live=sink, live_wall_rate=wall_rate))
    start = time.perf_counter()
    env.reset(seed=0)
    for _ in range(40):  # 1 s of simulated time at dt = 0.025 s
        env.step([0.0, 1.0])
    elapsed = time.perf_counter() - start
    frames = {ns for topic, ns in sink.messages if topic == "/ground_truth"}
    if wall_rate is None:
        assert len(frames) == 21  # 20 a simulated second, from the reset's
    else:  # the reset's, then at most one a wall-clock second
        assert 1 <= len(frames) <= 1 + math.floor(elapsed * wall_rate)
