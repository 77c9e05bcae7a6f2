"""N cars stepped together on arrays: the work the vector env and the race share per step.

A fleet holds N cars (each a [`RacecarEnv`][racecar_sim.env.RacecarEnv]: its physics, its lidar
settings, its generator) and does for all of them at once what the single env does for one: the
physics step (the cars far from walls in one numba call, the others through pymunk), the seeds of
the scans due (one raw draw from each car's generator, as
[`Lidar.measure`][racecar_sim.sensors.lidar.Lidar.measure] draws it) and the odometry (six normals from
each car's generator, then the VESC's twist and its noise in one numba call, the single env's
doubles). The clocks are the car's ([`racecar_sim.car.clock`][racecar_sim.car.clock]).
Frames: world (the map's), car (x forward, y left, origin at the rear axle).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from racecar_sim.car.free_batch import FreeStepBatch
from racecar_sim.sensors.vesc import vesc_odometry

if TYPE_CHECKING:  # the envs build fleets; a fleet only steps their cars
    from racecar_sim.env import RacecarEnv

__all__ = ["CarFleet"]

_ONE = np.uint64(1)


class CarFleet:
    """The per-step work of ``cars`` (one map, one car model, one lidar and odometry model).

    Args:
        cars: the cars, in index order.
    """

    def __init__(self, cars: list[RacecarEnv]) -> None:
        first = cars[0]
        self.cars = cars
        self.physics = [c.physics for c in cars]
        self.batch = FreeStepBatch(self.physics)
        """The cars' free steps in one kernel call (their twists are rows of ``batch.twists``)."""
        self.wheelbase = float(first.car_params.wheelbase)
        self._prop = first.odometry.proportional
        self._add = first.odometry.additive
        self._z = np.zeros((len(cars), 6))
        self._z_rows = list(self._z)

    @property
    def twists(self) -> np.ndarray:
        """(N, 3) every car's true car-frame twist over its last step (m/s, m/s, rad/s)."""
        return self.batch.twists

    def step(
        self, stepped: list[int], commands: np.ndarray, dt: float, poses: np.ndarray
    ) -> np.ndarray:
        """Drive cars ``stepped`` (ascending) ``dt`` seconds by their rows of ``commands`` (N, 2) =
        [steer rad, speed m/s] (finite); write their new rear-axle world poses into their rows of
        ``poses`` (N, 3). Returns whether each of ``stepped`` touched a wall (or, in a race,
        another car's box)."""
        hits, free = self.batch.step(stepped, commands, dt)
        if free:
            poses[free] = self.batch.poses(free)
        if len(free) < len(stepped):  # stepped through pymunk: the body's pose
            done_free = set(free)
            physics = self.physics
            for i in stepped:
                if i not in done_free:
                    poses[i] = physics[i].pose
        return hits

    def scan_seeds(self, due: list[int]) -> np.ndarray:
        """(K,) int64 the scan seeds of cars ``due``: one raw draw from each car's generator, its
        top 63 bits (``racecar_sim.raycast.rand.seed_from``)."""
        cars = self.cars
        raw = np.array([cars[i].np_random.bit_generator.random_raw() for i in due], dtype=np.uint64)
        return (raw >> _ONE).astype(np.int64)

    def odometry(self, cars: list[int]) -> np.ndarray:
        """(K, 3) float32 the VESC's noisy car-frame twist [vx m/s, vy m/s, omega rad/s] of
        ``cars`` from their wheels now, drawing six standard normals from each car's generator
        (the single env's draws and doubles, without an odometry bias, lead or IMU)."""
        rows, envs, physics = self._z_rows, self.cars, self.physics
        for i in cars:
            envs[i].np_random.standard_normal(out=rows[i])
        steer = np.array([physics[i].steer for i in cars])
        wheel_speed = np.array([physics[i].wheel_speed for i in cars])
        out = np.empty((len(cars), 3), dtype=np.float32)
        vesc_odometry(steer, wheel_speed, self.wheelbase, self._z[cars], self._prop, self._add, out)
        return out
