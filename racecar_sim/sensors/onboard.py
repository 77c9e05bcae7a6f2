"""The sensors on board one car: its scan and its odometry (and gyro) read from the car's state,
their noise drawn from the env's generator in a fixed order, so the same seed gives the same
measurements whichever env (single, vector, race) steps the car.

[`CarSensors`][racecar_sim.sensors.onboard.CarSensors] is a base of
[`RacecarEnv`][racecar_sim.env.RacecarEnv], which sets its fields; the car's last scan, its
schedule and its odometry live in its row ``car_index`` of the env's core
([`CarFleet`][racecar_sim.fleet.CarFleet]). Frames: world (metres, radians) and car (x forward,
y left, origin at the rear axle).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from racecar_sim.sensors.lidar import Lidar
from racecar_sim.sensors.odometry import Odometry

__all__ = ["CarSensors"]


class CarSensors:
    """The car's lidar, VESC odometry and gyro as they measure the car (fields set by the env):
    ``physics`` (the car's state), ``lidar``, ``odometry``, ``imu``, ``odom_bias``,
    ``scan_effects``, ``obstacles``, ``fleet`` (the core whose row ``car_index`` is this car),
    ``np_random``."""

    physics: Any
    lidar: Lidar
    odometry: Odometry
    imu: Any
    odom_bias: Any
    scan_effects: Any
    obstacles: Any
    fleet: Any
    car_index: int
    lidar_params: Any
    np_random: np.random.Generator

    @property
    def last_scan(self) -> np.ndarray:
        """(n_beams,) float32 the last scan, metres (the car's row of the core: do not write it)."""
        return self.fleet.scans[self.car_index]

    @property
    def last_scan_pose(self) -> np.ndarray:
        """(3,) the rear-axle world pose [x, y, theta] the last scan was taken at (metres,
        radians; the core's row: do not write it)."""
        return self.fleet.scan_poses[self.car_index]

    def observation(self, twist: np.ndarray) -> dict[str, np.ndarray]:
        """The observation of the car now: the last scan, then the odometry (kept in the core)
        and (if on) the IMU's yaw rate from the true car-frame ``twist`` (m/s, m/s, rad/s), their
        noise drawn from ``np_random`` in this order, as
        [`step`][racecar_sim.env.RacecarEnv.step] returns it (for cars that the race steps)."""
        fleet, i = self.fleet, self.car_index
        odom = fleet.odometry_one(i)
        if self.odom_bias is not None:
            odom = self.odom_bias.apply(odom)
        fleet.odom[i] = odom
        obs = {"scan": fleet.scans[i].copy(), "odom": odom}
        imu = self.imu
        if imu is not None:
            rate = float(twist[2]) + imu.bias + imu.sigma * float(self.np_random.standard_normal())
            obs["imu"] = np.array([rate], dtype=np.float32)
        return obs

    def _take_scan(self, pose: np.ndarray) -> None:
        """Scan from the car's current rear-axle ``pose`` and schedule the next scan one lidar
        period later."""
        self.keep_scan(pose, self._measure_scan(pose))

    def _measure_scan(self, pose: np.ndarray) -> np.ndarray:
        """A scan from rear-axle ``pose``: the map's ranges, cut by obstacles, then the noise
        (the four-part beam model, or the profile's scan effects)."""
        if self.obstacles is None and self.scan_effects is None:
            return self.lidar.measure(pose, self.np_random)
        ranges = self.lidar.true_ranges(pose)
        max_range = self.lidar_params.max_range
        if self.obstacles is not None:
            mount = self.lidar.mount_pose(pose)
            ranges = self.obstacles.clip_ranges(mount, self.lidar.angles, ranges, max_range)
        if self.scan_effects is None:
            return self.lidar.add_noise(ranges, self.np_random)
        return self.scan_effects.apply(ranges, max_range, self.np_random)

    def keep_scan(self, pose: np.ndarray, scan: np.ndarray) -> None:
        """Keep ``scan`` (float32 (n_beams,), metres, taken now at rear-axle world ``pose``) as the
        car's last scan and schedule the next one (in the core: ``fleet.scanned_one``)."""
        self.fleet.scanned_one(self.car_index, pose, scan)
