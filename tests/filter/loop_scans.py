"""Exact scans of the bundled basement_loop for the tests of the checks that compare scans with
each other (the standstill check, the scale's and the turn's matchers): the env, its lidar and
mount, and free poses drawn by its reset."""

from __future__ import annotations

import numpy as np

from racecar_sim.env import RacecarEnv

ENV = RacecarEnv("basement_loop")
LIDAR = ENV.lidar
MOUNT = np.array([ENV.lidar_params.mount_offset, 0.0, 0.0])
"""The lidar's pose in the car frame [x m, y m, theta rad]."""
MAX_RANGE = ENV.lidar_params.max_range
DT = 0.025
"""Seconds between two scans."""


def free_pose(seed: int) -> np.ndarray:
    """A free world pose [x m, y m, theta rad] of the loop, drawn by the env's reset."""
    ENV.reset(seed=seed)
    return ENV.pose
