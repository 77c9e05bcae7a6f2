"""Several cars on one map, stepped together: the part of the race that knows no agent API.

`RaceWorld` holds one [`RacecarEnv`][racecar_sim.env.RacecarEnv] per car (its physics, its lidar
settings, its odometry and its own random generator, exactly the single env's pieces) and steps
them the way [`RacecarVectorEnv`][racecar_sim.vector_env.RacecarVectorEnv] does (the free steps of all cars in
one numba call, the others through pymunk), with two things added: cars that could touch within a
step see each other's boxes in their pymunk spaces ([`racecar_sim.race.contact`][racecar_sim.race.contact]), and every
due scan is cast in one numba call that cuts the beams at the other cars' boxes
([`racecar_sim.race.lidar`][racecar_sim.race.lidar]). Each car's generator draws, per step, its scan's seed and then
its odometry's six normals, as the single env's does, so a world of one car gives what
``RacecarSim-v0`` gives for the same seed, start and actions.

Per step, the work for all cars is done on arrays, not car by car, by the core every env steps
through ([`CarFleet`][racecar_sim.fleet.CarFleet]): the commands' delay, the physics step, the
clocks and scan schedule, the poses, the last scans and the poses they were taken at, the scan
seeds and the odometry; each car's ``RacecarEnv`` is a row of it and keeps its physics, its lidar
settings and its generator. The race adds the contacts between cars and the cast that sees them.
What stays per car in Python is what is per car by nature: one raw draw and one draw of six
normals from each car's generator, and the pymunk step of a car near a wall or another car.

Frames: world (the map's), car (x forward, y left, origin at the rear axle).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from racecar_sim.env import RacecarEnv
from racecar_sim.fleet import CarFleet
from racecar_sim.race.contact import (
    WALL,
    CarContacts,
    bounding_radius,
    box_centres,
    near_pairs,
)
from racecar_sim.race.lidar import car_boxes, race_scans_serial, race_scans_shared
from racecar_sim.raycast.kernels import PARALLEL_MIN_RAYS
from racecar_sim.raycast.shared_work import run_shared
from racecar_sim.settings.config import EnvConfig
from racecar_sim.settings.validation import check_poses

__all__ = ["RaceWorld", "boxes_overlap"]

_START_TRIES = 200  # random starts tried per car before giving up (no track)
_CHUNK = 2  # cars per work item of a threaded cast


def boxes_overlap(a: np.ndarray, b: np.ndarray, gap: float = 0.0) -> bool:
    """Whether two convex boxes (4, 2) (world corners, in order) come closer than ``gap`` metres
    (separating axis test on their edge normals; ``gap`` 0: whether they overlap)."""
    for box in (a, b):
        edges = np.roll(box, -1, axis=0) - box
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        normals /= np.hypot(normals[:, 0], normals[:, 1])[:, None]
        pa, pb = a @ normals.T, b @ normals.T
        if (
            (pa.min(axis=0) >= pb.max(axis=0) + gap) | (pb.min(axis=0) >= pa.max(axis=0) + gap)
        ).any():
            return False
    return True


class RaceWorld:
    """``n_cars`` cars on the map of ``config`` (see the module doc).

    Args:
        n_cars: number of cars (>= 1).
        config: the settings of every car (an `EnvConfig` whose map is loaded).
        workers: threads casting the scans (default 1: on the calling thread). Threads pay off
            from `PARALLEL_MIN_RAYS` rays per step on idle
            cores.

    Raises:
        ValueError: a setting the race's cast does not know (scan effects, obstacles),
            ``n_cars`` < 1.
    """

    def __init__(self, n_cars: int, config: EnvConfig, workers: int = 1) -> None:
        if not isinstance(n_cars, int) or isinstance(n_cars, bool) or n_cars < 1:
            raise ValueError(f"n_cars must be a positive integer, got {n_cars!r}")
        if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
            raise ValueError(f"workers must be a positive integer, got {workers!r}")
        extras = [n for n in ("scan_effects", "obstacles") if getattr(config, n) is not None]
        if extras:
            raise ValueError(
                f"a race does not support {', '.join(extras)} (set by a noise profile or given); "
                "use RacecarSim-v0 for these"
            )
        self.n_cars = n_cars
        self.cars: list[RacecarEnv] = [RacecarEnv(config=config) for _ in range(n_cars)]
        first = self.cars[0]
        self.config = config
        self.map = first.map
        self.dt = first.dt
        self.car_params = first.car_params
        self.lidar_params = first.lidar_params
        self.fleet = CarFleet(self.cars, config, first.lidar.period, first.odometry,
                              self.lidar_params.n_beams)  # fmt: skip
        """The cars' core ([`CarFleet`][racecar_sim.fleet.CarFleet]): their command delays,
        physics step, clocks, poses, last scans and odometry on arrays; each car is a row of it."""
        for i, car in enumerate(self.cars):
            car.join(self.fleet, i)
        self._phys = self.fleet.physics
        self._pairs = np.triu_indices(n_cars, 1)
        self.contacts = CarContacts([c.physics for c in self.cars])
        lidar = first.lidar
        self._field, self._geometry, self._cos_a, self._sin_a, self._noise = lidar.kernel_inputs
        angles = lidar.angles
        self._angle0 = float(angles[0])
        self._step = float(angles[1] - angles[0]) if len(angles) > 1 else 0.0
        self._corners = first.physics.local_corners
        self._centre = self._corners.mean(axis=0)  # car frame, the box's centre
        self.radius = bounding_radius(self._corners)
        """Metres from a car box's centre to its corners."""
        self._speed_factor = first.physics.speed_bound
        self._workers = workers
        self._threaded = n_cars * self.lidar_params.n_beams >= PARALLEL_MIN_RAYS and workers > 1
        n, m = n_cars, self.lidar_params.n_beams
        self.poses = self.fleet.poses
        """(N, 3) rear-axle world poses [x, y, theta] after the last reset or step (the core's)."""
        self.scans = self.fleet.scans
        """(N, n_beams) the last scan of every car (noisy, metres; the core's)."""
        self.ranges = np.zeros((n, m))
        """(N, n_beams) the exact ranges of the last scan (walls and cars, no noise), metres."""
        self.odom = self.fleet.odom
        """(N, 3) the last odometry of every car (the VESC's noisy car-frame twist; the core's)."""
        self.imu = np.zeros((n, 1), dtype=np.float32)
        """(N, 1) the last IMU yaw rate of every car (rad/s; zeros without the ``imu`` setting)."""
        self.twists = np.zeros((n, 3))
        self.fresh = np.zeros(n, dtype=np.bool_)
        self.time = 0.0
        """Seconds since the reset: the clock of the car that has driven longest."""
        self.car_time = self.fleet.clocks.times
        """(N,) each car's clock, seconds (a car stops its clock when it leaves the race)."""
        self.scan_poses = self.fleet.scan_poses
        """(N, 3) the rear-axle world poses the last scans were taken at (the core's)."""
        self._everyone = np.arange(n)

    # ------------------------------------------------------------------ geometry
    def boxes(self, poses: np.ndarray | None = None) -> np.ndarray:
        """(N, 4, 2) world corners of every car's box (at ``poses``, default the current ones)."""
        return car_boxes(self.poses if poses is None else poses, self._corners)

    def check_poses(self, poses: Any) -> np.ndarray:
        """``poses`` as (N, 3) float64, or ValueError naming the first car that cannot be there
        (not finite, in a wall, off the map, or overlapping an earlier car)."""
        n = self.n_cars
        arr = check_poses("poses", poses, n)
        boxes = self.boxes(arr)
        for i in range(n):
            if not self.cars[i].physics.pose_is_free(arr[i]):
                raise ValueError(
                    f"poses[{i}] = {arr[i].tolist()} puts car_{i} in a wall or off the map"
                )
            for j in range(i):
                if boxes_overlap(boxes[i], boxes[j]):
                    raise ValueError(f"poses[{i}] puts car_{i} onto car_{j} at {arr[j].tolist()}")
        return arr

    def random_poses(self) -> np.ndarray:
        """A random free start per car (its own generator, as the single env), none overlapping
        another car or closer than ``start_clearance``."""
        gap = float(self.config.start_clearance)
        poses = np.zeros((self.n_cars, 3))
        for i, car in enumerate(self.cars):
            for _ in range(_START_TRIES):
                pose = car.random_start()
                box = car_boxes(pose[None], self._corners)[0]
                if not any(boxes_overlap(box, b, gap) for b in self.boxes(poses[:i])):
                    poses[i] = pose
                    break
            else:
                raise ValueError(
                    f"found no start for car_{i} clear of the others in {_START_TRIES} tries"
                )
        return poses

    # ------------------------------------------------------------------ simulation
    def reset(self, seeds: list[int | None], poses: np.ndarray | None) -> None:
        """Seed every car's generator, place the cars at rest (``poses`` (N, 3); None: random,
        see `random_poses()`) and take every first scan and odometry."""
        self.contacts.remove_all()
        given = None if poses is None else self.check_poses(poses)  # before anything changes
        for car, seed in zip(self.cars, seeds, strict=True):
            gym.Env.reset(car, seed=seed)
        arr = self.random_poses() if given is None else given
        for i, car in enumerate(self.cars):
            car.physics.reset(arr[i])
        everyone = np.arange(self.n_cars)
        self.time = 0.0
        self.fleet.reset(everyone.tolist())  # clocks, command delays, poses
        self.twists = self.fleet.twists.copy()
        self.fresh[:] = True
        self._cast(everyone)
        self._measure_odometry(everyone)
        self.contacts.clear()

    def step(self, actions: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Drive the ``active`` cars (bool (N,)) ``dt`` seconds by their rows of ``actions`` (N, 2)
        = [steer rad, speed m/s] (finite, clipped to the car's box); the others stand still and
        are seen and touched where they stand. Returns the collided flags (N,)."""
        n = self.n_cars
        stepped_arr = self._everyone if active.all() else np.flatnonzero(active)
        fleet = self.fleet
        # The body gets each command odom_lead late (racecar_sim.sensors.vesc).
        actions = fleet.command(stepped_arr.tolist(), actions)
        poses = self.poses
        phys = self._phys
        speed = np.array([p.speed for p in phys])
        travel = self.dt * np.maximum(np.abs(speed), np.abs(actions[:, 1])) * self._speed_factor
        travel[~active] = 0.0
        centres = box_centres(poses, self._centre)
        pairs = near_pairs(centres, self.radius, travel, self._pairs)
        vel = np.zeros((n, 3))  # world velocities of the cars that could touch (still: zero)
        if len(pairs):
            for i in np.unique(pairs).tolist():
                if active[i]:
                    vel[i] = phys[i].world_velocity()
        self.contacts.clear()
        self.contacts.show(pairs, poses, vel)
        collided = np.zeros(n, dtype=np.bool_)
        collided[stepped_arr], due = fleet.step(stepped_arr, actions)  # poses, clocks
        self.time = float(self.car_time.max())
        self.twists[stepped_arr] = fleet.twists[stepped_arr]
        self.fresh[:] = False
        self.fresh[due] = True
        self._cast(due)
        self._measure_odometry(stepped_arr)
        return collided

    def touched(self, i: int) -> tuple[str, ...]:
        """What car ``i`` touched in the last step: ``"wall"`` and/or ``"car_j"``, walls first."""
        hit = self.contacts.touched[i]
        return tuple("wall" if j == WALL else f"car_{j}" for j in sorted(hit))

    # ------------------------------------------------------------------ internals
    def _cast(self, due: np.ndarray) -> None:
        """Cast the scans of cars ``due`` at their current poses (boxes of all cars as they stand)."""
        k = len(due)
        if k == 0:
            return
        m = self.lidar_params.n_beams
        seeds = self.fleet.scan_seeds(due.tolist())
        everyone = k == self.n_cars  # due ascending: every car, in order
        ranges = self.ranges if everyone else np.empty((k, m))  # the kernel writes in place
        out = self.scans if everyone else np.empty((k, m), dtype=np.float32)
        status = np.zeros(k, dtype=np.int64)
        args = (self._field, self.poses, due, self._geometry, self._cos_a, self._sin_a, self._angle0,
                self._step, self.boxes(), self.radius, seeds, self._noise, ranges, out, status)  # fmt: skip
        if self._threaded and k > 1:
            run_shared(race_scans_shared, (*args, _CHUNK), self._workers)
        else:
            race_scans_serial(*args)
        if status.any():  # pragma: no cover - physics poses are finite and on the map
            raise RuntimeError(f"lidar cast failed for cars {due[status != 0]}")
        if not everyone:
            self.ranges[due] = ranges
        self.fleet.scanned(due, None if everyone else out)

    def _measure_odometry(self, cars: np.ndarray) -> None:
        """The odometry (and IMU) of ``cars`` after their scans, as the single env measures it
        ([`CarSensors.observation`][racecar_sim.sensors.onboard.CarSensors.observation]), drawn
        from each car's generator in its order: with an IMU or an odometry bias, the single env's
        own call per car; else the core's (the VESC's twist from the wheels and the noise on
        arrays, or car by car with an odometry lead: the same draws and double operations)."""
        if len(cars) == 0:
            return
        first = self.cars[0]
        if first.imu is not None or first.odom_bias is not None:
            for i in cars.tolist():
                obs = self.cars[i].observation(self.twists[i])  # keeps the odometry in the core
                if "imu" in obs:
                    self.imu[i] = obs["imu"]
            return
        self.fleet.odometry(cars.tolist())  # kept in the core's odom (this world's too)
