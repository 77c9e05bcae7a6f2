"""Stream a race to Foxglove as it runs (``racecar-sim race --live``): the map once, and after
every step every car's true pose, and in a localized race every car's estimate and a subsample of
its particles, each as one ``geometry_msgs/msg/PoseArray`` in the ``map`` frame (ROS 2 CDR, the
recording's encoding, [`mcl.io.bag_writer`][mcl.io.bag_writer]), through the project's Foxglove
server ([`mcl.io.live.LiveServer`][mcl.io.live.LiveServer]).

Topics: ``/map`` (``nav_msgs/msg/OccupancyGrid``, latched), ``/race/cars`` (the true rear-axle
poses, car 0 first), ``/race/estimates`` (the filters' estimates, car 0 first) and
``/race/particles`` (at most ``max_particles`` of each car's particles). Times are the race's
seconds after [`EPOCH_NS`][mcl.io.bag_writer.EPOCH_NS], as a recorded drive's.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mcl.io.bag_writer import EPOCH_NS, BagRecorder
from mcl.io.cdr import pose_array, ros2_typestore
from mcl.io.live import LiveServer

__all__ = ["RACE_TOPICS", "RaceStream", "start_race_live"]

RACE_TOPICS: dict[str, str] = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/race/cars": "geometry_msgs/msg/PoseArray",
    "/race/estimates": "geometry_msgs/msg/PoseArray",
    "/race/particles": "geometry_msgs/msg/PoseArray",
}
"""Topic -> ROS 2 message type of the race's live view."""


def start_race_live(address: str | int, wait: bool = True) -> LiveServer:
    """A Foxglove WebSocket server for [`RACE_TOPICS`][mcl.io.race_stream.RACE_TOPICS] at
    ``"[HOST:]PORT"`` (``wait``: see [LiveServer][mcl.io.live.LiveServer])."""
    return LiveServer(
        address, RACE_TOPICS, ros2_typestore(), name="racecar-sim race", wait=wait
    )


class RaceStream:
    """The ``on_step(env, obs, infos)`` hook of
    [run_race][mcl.experiments.race_run.run_race] that streams to ``live`` (module doc).

    Args:
        race: the [`racecar_sim.RaceEnv`][racecar_sim.race.env.RaceEnv] (its map and lidar).
        live: the server ([`start_race_live`][mcl.io.race_stream.start_race_live]).
        max_particles: particles per car on ``/race/particles``.
    """

    def __init__(self, race: Any, live: LiveServer, max_particles: int = 200) -> None:
        lidar = race.cars[0].lidar
        self.live = live
        self.max_particles = int(max_particles)
        recorder = BagRecorder(
            None,
            race.map,
            lidar.angles,
            float(lidar.params.max_range),
            float(lidar.params.mount_offset),
            live=live,
        )
        recorder.write_static(0.0)  # the map, once (latched for later clients)

    def __call__(self, env: Any, obs: dict[str, Any], infos: dict[str, dict[str, Any]]) -> None:
        live = self.live
        agents = sorted(infos, key=lambda a: int(a[4:]))
        ns = EPOCH_NS + round(max(float(infos[agents[0]]["time"]), 0.0) * 1e9)
        if live.wants("/race/cars"):
            poses = np.array([infos[a]["pose"] for a in agents], dtype=np.float64)
            live.publish("/race/cars", ns, pose_array(ns, "map", poses))
        filters = getattr(env, "filters", None)
        if not filters:
            return
        if live.wants("/race/estimates"):
            estimates = np.array([obs[a]["pose_estimate"] for a in agents if a in filters])
            live.publish("/race/estimates", ns, pose_array(ns, "map", estimates))
        if live.wants("/race/particles"):
            clouds = []
            for a in agents:
                if a in filters:
                    p = filters[a].particles
                    clouds.append(p[:: max(1, len(p) // self.max_particles)])
            live.publish("/race/particles", ns, pose_array(ns, "map", np.vstack(clouds)))
