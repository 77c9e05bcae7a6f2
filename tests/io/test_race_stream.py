"""The race's live view: every step's true poses (and, localized, estimates and particles) as
PoseArrays in the map frame, the map once; ``racecar-sim race --live`` serves them."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pettingzoo", reason="RaceEnv needs the [race] extra (pettingzoo)")
from rosbags.typesys import Stores, get_typestore

from mcl.experiments.race_drivers import parse_drivers
from mcl.experiments.race_run import RaceSpec, run_race, setup_race
from mcl.io.bag_writer import EPOCH_NS
from mcl.io.race_stream import RACE_TOPICS, RaceStream

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)


class Listener:
    """Stands in for the Foxglove server: every topic is wanted, every message kept."""

    def __init__(self) -> None:
        self.messages: dict[str, list[tuple[int, bytes]]] = {}

    def wants(self, topic: str) -> bool:
        return topic in RACE_TOPICS

    def publish(self, topic: str, log_time_ns: int, data: bytes) -> None:
        self.messages.setdefault(topic, []).append((log_time_ns, bytes(data)))


def _poses(data: bytes) -> np.ndarray:
    msg = TYPESTORE.deserialize_cdr(data, "geometry_msgs/msg/PoseArray")
    assert msg.header.frame_id == "map"
    return np.array([[p.position.x, p.position.y, 2 * np.arctan2(p.orientation.z, p.orientation.w)]
                     for p in msg.poses])  # fmt: skip


@pytest.mark.parametrize("localize", [False, True])
def test_every_step_streams_the_cars_and_the_filters(localize) -> None:
    spec = RaceSpec("basement_loop", parse_drivers("pursuit", 2), (2.0, 2.5), duration=0.25,
                    localize=localize, particles=200)  # fmt: skip
    setup = setup_race(spec)
    listener = Listener()
    stream = RaceStream(setup.race, listener, max_particles=50)  # type: ignore[arg-type]
    last: dict = {}

    def on_step(env, obs, infos) -> None:
        stream(env, obs, infos)
        last.update(obs=obs, infos=infos)

    run_race(spec, setup, on_step=on_step)
    got = listener.messages
    assert len(got["/map"]) == 1
    grid = TYPESTORE.deserialize_cdr(got["/map"][0][1], "nav_msgs/msg/OccupancyGrid")
    assert (grid.info.width, grid.info.height) == (setup.race.map.width, setup.race.map.height)
    assert len(got["/race/cars"]) == 11  # the start and 10 steps of 0.025 s
    time_ns, data = got["/race/cars"][-1]
    assert time_ns == EPOCH_NS + round(last["infos"]["car_0"]["time"] * 1e9)
    truth = np.array([last["infos"][a]["pose"] for a in ("car_0", "car_1")])
    np.testing.assert_allclose(_poses(data), truth, atol=1e-9)
    if not localize:
        assert "/race/estimates" not in got and "/race/particles" not in got
        return
    estimates = np.array([last["obs"][a]["pose_estimate"] for a in ("car_0", "car_1")])
    np.testing.assert_allclose(_poses(got["/race/estimates"][-1][1]), estimates, atol=1e-9)
    assert len(_poses(got["/race/particles"][-1][1])) == 2 * 50


def test_race_live_serves_and_says_where(tmp_path, capsys) -> None:
    pytest.importorskip("foxglove", reason="the live view needs foxglove-sdk (extra [live])")
    from mcl.cli.main import main

    argv = ["race", "--cars", "2", "--duration", "0.25", "--video-fps", "0", "--live", "0",
            "--live-speed", "0", "--out", str(tmp_path / "live"), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    assert "live view: in Foxglove, Open connection, ws://localhost:" in capsys.readouterr().err
