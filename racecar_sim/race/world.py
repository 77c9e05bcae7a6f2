"""Several cars on one map, stepped together: the part of the race that knows no agent API.

:class:`RaceWorld` holds one :class:`~racecar_sim.env.RacecarEnv` per car (its physics, its lidar
settings, its odometry and its own random generator, exactly the single env's pieces) and steps
them the way :class:`~racecar_sim.vector_env.RacecarVectorEnv` does (the free steps of all cars in
one numba call, the others through pymunk), with two things added: cars that could touch within a
step see each other's boxes in their pymunk spaces (:mod:`racecar_sim.race.contact`), and every
due scan is cast in one numba call that cuts the beams at the other cars' boxes
(:mod:`racecar_sim.race.lidar`). Each car's generator draws, per step, its scan's seed and then
its odometry's six normals, as the single env's does, so a world of one car gives what
``RacecarSim-v0`` gives for the same seed, start and actions.

Frames: world (the map's), car (x forward, y left, origin at the rear axle).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from racecar_sim.config import EnvConfig
from racecar_sim.env import RacecarEnv
from racecar_sim.free_batch import FreeStepBatch
from racecar_sim.race.contact import WALL, CarContacts, bounding_radius, near_pairs, world_velocity
from racecar_sim.race.lidar import car_boxes, race_scans_serial, race_scans_shared
from racecar_sim.rand import seed_from
from racecar_sim.raycast.kernels import PARALLEL_MIN_RAYS
from racecar_sim.raycast.shared_work import run_shared
from racecar_sim.vesc import wheel_twist

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
        config: the settings of every car (an :class:`EnvConfig` whose map is loaded).
        workers: threads casting the scans (default 1: on the calling thread). Threads pay off
            from :data:`~racecar_sim.raycast.kernels.PARALLEL_MIN_RAYS` rays per step on idle
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
        self._odo_prop, self._odo_add = first.odometry._prop, first.odometry._add
        self._physics = FreeStepBatch([c.physics for c in self.cars])
        self._phys = [c.physics for c in self.cars]
        self._pairs = np.triu_indices(n_cars, 1)
        self.contacts = CarContacts([c.physics for c in self.cars])
        lidar = first.lidar
        self._field, self._geometry = lidar._caster.field, lidar._geometry
        self._cos_a, self._sin_a, self._noise = lidar._cos_a, lidar._sin_a, lidar._noise
        angles = lidar.angles
        self._angle0 = float(angles[0])
        self._step = float(angles[1] - angles[0]) if len(angles) > 1 else 0.0
        self._corners = first.physics._local_corners.copy()
        self._centre = self._corners.mean(axis=0)  # car frame, the box's centre
        self.radius = bounding_radius(self._corners)
        """Metres from a car box's centre to its corners."""
        self._speed_factor = float(first.physics._free_const[6])
        self._workers = workers
        self._threaded = n_cars * self.lidar_params.n_beams >= PARALLEL_MIN_RAYS and workers > 1
        n, m = n_cars, self.lidar_params.n_beams
        self.poses = np.zeros((n, 3))
        """(N, 3) rear-axle world poses [x, y, theta] after the last reset or step."""
        self.scans = np.zeros((n, m), dtype=np.float32)
        """(N, n_beams) the last scan of every car (noisy, metres)."""
        self.ranges = np.zeros((n, m))
        """(N, n_beams) the exact ranges of the last scan (walls and cars, no noise), metres."""
        self.odom = np.zeros((n, 3), dtype=np.float32)
        """(N, 3) the last odometry of every car (the VESC's noisy car-frame twist)."""
        self.imu = np.zeros((n, 1), dtype=np.float32)
        """(N, 1) the last IMU yaw rate of every car (rad/s; zeros without the ``imu`` setting)."""
        self.twists = np.zeros((n, 3))
        self.fresh = np.zeros(n, dtype=np.bool_)
        self.time = 0.0

    # ------------------------------------------------------------------ geometry
    def boxes(self, poses: np.ndarray | None = None) -> np.ndarray:
        """(N, 4, 2) world corners of every car's box (at ``poses``, default the current ones)."""
        return car_boxes(self.poses if poses is None else poses, self._corners)

    def check_poses(self, poses: Any) -> np.ndarray:
        """``poses`` as (N, 3) float64, or ValueError naming the first car that cannot be there
        (not finite, in a wall, off the map, or overlapping an earlier car)."""
        arr = np.asarray(poses, dtype=np.float64)
        n = self.n_cars
        if arr.shape != (n, 3) or not np.isfinite(arr).all():
            raise ValueError(
                f"poses must be a finite ({n}, 3) array of [x, y, theta], got {poses!r}"
            )
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
                pose = car._random_start()
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
        see :meth:`random_poses`) and take every first scan and odometry."""
        self.contacts.remove_all()
        for car, seed in zip(self.cars, seeds, strict=True):
            gym.Env.reset(car, seed=seed)
        arr = self.random_poses() if poses is None else self.check_poses(poses)
        for i, car in enumerate(self.cars):
            car.physics.reset(arr[i])
            car._n_steps = 0
            car.time = 0.0
            car.command_delay.reset(car.physics.steer, car.physics.wheel_speed)
        self.time = 0.0
        self.poses = np.array([car.physics.pose for car in self.cars])
        self.twists = np.array([car.physics.twist for car in self.cars])
        everyone = np.arange(self.n_cars)
        self.fresh[:] = True
        self._cast(everyone)
        self._measure_odometry(everyone)
        self.contacts.clear()

    def step(self, actions: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Drive the ``active`` cars (bool (N,)) ``dt`` seconds by their rows of ``actions`` (N, 2)
        = [steer rad, speed m/s] (finite, clipped to the car's box); the others stand still and
        are seen and touched where they stand. Returns the collided flags (N,)."""
        n = self.n_cars
        stepped = np.flatnonzero(active).tolist()
        if self.cars[0].command_delay.n:  # the body gets each command odom_lead late (vesc.py)
            actions = actions.copy()
            for i in stepped:
                delay = self.cars[i].command_delay
                actions[i] = delay.push(float(actions[i, 0]), float(actions[i, 1]))
        poses = self.poses
        vel = np.zeros((n, 3))
        speed = np.zeros(n)
        phys = self._phys
        in_states = []  # cars whose motion state is in the free-step rows (pymunk's body lags)
        for i in stepped:
            p = phys[i]
            speed[i] = p.speed
            if p._free_valid:
                in_states.append(i)
            else:
                vel[i] = world_velocity(p)
        vel[in_states] = self._physics.states[in_states, 3:6]
        travel = self.dt * np.maximum(np.abs(speed), np.abs(actions[:, 1])) * self._speed_factor
        travel[~active] = 0.0
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        centres = poses[:, :2] + np.stack(
            [c * self._centre[0] - s * self._centre[1], s * self._centre[0] + c * self._centre[1]],
            axis=1,
        )
        self.contacts.clear()
        self.contacts.show(near_pairs(centres, self.radius, travel, self._pairs), poses, vel)
        hits, free = self._physics.step(stepped, actions, self.dt)
        collided = np.zeros(n, dtype=np.bool_)
        collided[stepped] = hits
        new_poses = poses.copy()
        if free:
            new_poses[free] = self._physics.poses(free)
        done_free = set(free)
        due = []
        self.fresh[:] = False
        for i in stepped:
            car = self.cars[i]
            if i not in done_free:
                new_poses[i] = car.physics.pose
            if car._tick():
                due.append(i)
        self.poses = new_poses
        self.time = max(car.time for car in self.cars)
        self.twists[stepped] = self._physics.twists[stepped]
        self.fresh[due] = True
        self._cast(np.array(due, dtype=np.int64))
        self._measure_odometry(np.array(stepped, dtype=np.int64))
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
        seeds = np.array([seed_from(self.cars[i].np_random) for i in due.tolist()], dtype=np.int64)
        ranges = np.empty((k, m))
        out = np.empty((k, m), dtype=np.float32)
        status = np.zeros(k, dtype=np.int64)
        args = (self._field, self.poses, due, self._geometry, self._cos_a, self._sin_a, self._angle0,
                self._step, self.boxes(), self.radius, seeds, self._noise, ranges, out, status)  # fmt: skip
        if self._threaded and k > 1:
            run_shared(race_scans_shared, (*args, _CHUNK), self._workers)
        else:
            race_scans_serial(*args)
        if status.any():  # pragma: no cover - physics poses are finite and on the map
            raise RuntimeError(f"lidar cast failed for cars {due[status != 0]}")
        self.ranges[due] = ranges
        self.scans[due] = out
        cars = self.cars
        for j, (i, pose) in enumerate(zip(due.tolist(), self.poses[due], strict=True)):
            cars[i]._store_scan(pose, out[j])

    def _measure_odometry(self, cars: np.ndarray) -> None:
        """The odometry (and IMU) of ``cars`` after their scans, as the single env measures it
        (:meth:`RacecarEnv._observation`), drawn from each car's generator in its order: with an
        IMU, an odometry bias or lead, the single env's own call per car; else the VESC's twist
        from the wheels and the noise on arrays (the same draws and double operations)."""
        if len(cars) == 0:
            return
        first = self.cars[0]
        if first.imu is not None or first.odom_bias is not None or first.command_delay.n:
            for i in cars.tolist():
                obs = self.cars[i]._observation(self.twists[i])
                self.odom[i] = obs["odom"]
                if "imu" in obs:
                    self.imu[i] = obs["imu"]
            return
        k = len(cars)
        z = np.empty((k, 6))
        wheels = np.empty((k, 3))
        wheelbase = first._wheelbase
        for j, i in enumerate(cars.tolist()):
            p = self._phys[i]
            wheels[j] = wheel_twist(p.wheel_speed, p.steer, wheelbase)
            self.cars[i].np_random.standard_normal(out=z[j])
        prop, add = self._odo_prop, self._odo_add
        self.odom[cars] = (wheels * (1.0 + prop * z[:, :3]) + add * z[:, 3:]).astype(np.float32)
