"""Autopilots for headless drives: a lidar wall follower and a pure-pursuit waypoint follower.

A driver is a callable ``driver(obs, pose=None) -> np.ndarray`` returning the action
``float32 [steer, speed]`` (front wheel angle in radians, positive to the left; speed in m/s along the
car's x axis). ``obs`` is the env's observation dict (``scan``, ``odom`` and, under
``mcl.LocalizationWrapper``, ``pose_estimate``); ``pose`` is a world pose [x, y, theta] of the rear
axle when the caller knows it.

Frames: scans are in the lidar frame (x forward, y left, at the lidar); the wall follower works in
it directly. Waypoints and poses are in the world frame (metres, radians).
"""

from racecar_sim.drivers.base import Driver, despeckle
from racecar_sim.drivers.loop_recorder import waypoints_from_drive
from racecar_sim.drivers.pure_pursuit import PurePursuit
from racecar_sim.drivers.wall_follower import WallFollower
from racecar_sim.world.track import resample_polyline

__all__ = [
    "Driver",
    "PurePursuit",
    "WallFollower",
    "despeckle",
    "resample_polyline",
    "waypoints_from_drive",
]
