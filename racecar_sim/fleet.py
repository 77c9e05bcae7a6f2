"""The core that every env steps its cars through: N cars' state on arrays and the step they share.

A [`CarFleet`][racecar_sim.fleet.CarFleet] owns the per-car state that the single env
([`RacecarEnv`][racecar_sim.env.RacecarEnv], N = 1), the vector env (N independent cars) and the
race (N cars that see and touch each other) keep alike: the commands on their way to the body
(each car's [`CommandDelay`][racecar_sim.sensors.vesc.CommandDelay]), the rear-axle poses and
true twists, the clocks and scan schedule ([`CarClocks`][racecar_sim.car.clock.CarClocks]), the
last scans and the poses they were taken at, the last odometry. It does the per-step sequence
they share:

1. [`clip()`][racecar_sim.fleet.CarFleet.clip] the commands to the action box and
   [`command()`][racecar_sim.fleet.CarFleet.command]: push them through the delay, getting the
   commands that reach the body now;
2. [`step()`][racecar_sim.fleet.CarFleet.step]: the physics (the cars far from walls in one numba
   call, the others through pymunk), the new poses, the clocks; returns the cars whose scan is due;
3. the caller casts those scans (each env its own way: with obstacles and scan effects, N cars in
   one call, or cut at the other cars' boxes) from the seeds of
   [`scan_seeds()`][racecar_sim.fleet.CarFleet.scan_seeds] and hands them to
   [`scanned()`][racecar_sim.fleet.CarFleet.scanned];
4. [`odometry()`][racecar_sim.fleet.CarFleet.odometry]: the VESC's noisy twist from the wheels.

Each car draws from its own generator in this order (scan seed, then six normals of odometry), as
the single env always has, so car ``i`` gives the same numbers whichever env steps it. One car
steps through the ``*_one`` methods, in plain floats (the single env's hot path); N cars through
the array methods, with the same doubles (tested).

Frames: world (the map's; metres, radians), car (x forward, y left, origin at the rear axle).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from racecar_sim.car.clock import CarClocks
from racecar_sim.car.free_batch import FreeStepBatch
from racecar_sim.car.physics import RacecarPhysics
from racecar_sim.sensors.odometry import Odometry
from racecar_sim.sensors.vesc import CommandDelay, lead_steps, vesc_odometry, wheel_twist
from racecar_sim.settings.config import EnvConfig

__all__ = ["CarFleet", "FleetCar"]

_ONE = np.uint64(1)


class FleetCar(Protocol):
    """What the fleet reads of a car: its physics and its random generator (a
    [`RacecarEnv`][racecar_sim.env.RacecarEnv] is one)."""

    @property
    def physics(self) -> RacecarPhysics:
        """The car's physics (its state)."""
        ...

    @property
    def np_random(self) -> np.random.Generator:
        """The car's random generator (read at every draw: a reset may replace it)."""
        ...


class CarFleet:
    """N cars' state and their shared step (see the module doc).

    Args:
        cars: the cars, in index order (one map, one car model, one lidar and odometry model).
        config: the cars' settings (``dt``, ``substep``, ``car``, ``odom_lead``).
        period: seconds between two scans of a car (the lidar's ``1 / lidar_rate``).
        odometry: the odometry's noise model (one for all cars).
        n_beams: beams per scan.
    """

    def __init__(
        self,
        cars: Sequence[FleetCar],
        config: EnvConfig,
        period: float,
        odometry: Odometry,
        n_beams: int,
    ) -> None:
        n = len(cars)
        self.n = n
        """Number of cars."""
        self.cars = list(cars)
        self.physics = [c.physics for c in cars]
        self.dt = float(config.dt)
        """Seconds per step."""
        self.batch = FreeStepBatch(self.physics)
        """The cars' free steps in one kernel call (their twists are rows of ``batch.twists``)."""
        car = config.car
        self.wheelbase = float(car.wheelbase)
        """Metres between the axles."""
        # The action box in float32, as the envs' action spaces hold it.
        box = np.array(
            [[-car.max_steer, -car.max_reverse_speed], [car.max_steer, car.max_speed]],
            dtype=np.float32,
        ).astype(np.float64)
        self.low, self.high = box[0], box[1]
        self._lo = (float(box[0, 0]), float(box[0, 1]))
        self._hi = (float(box[1, 0]), float(box[1, 1]))
        lead = lead_steps(config.odom_lead, self.dt)
        self.delays = [CommandDelay(lead, car, self.dt, config.substep) for _ in range(n)]
        """Each car's commands on their way to the body (``odom_lead``, [`racecar_sim.sensors.vesc`][racecar_sim.sensors.vesc])."""
        self.delayed = lead > 0
        """Whether the body gets each command ``odom_lead`` late."""
        self.clocks = CarClocks(n, self.dt, period)
        """Every car's clock and scan schedule ([`CarClocks`][racecar_sim.car.clock.CarClocks])."""
        self.poses = np.zeros((n, 3))
        """(N, 3) rear-axle world poses [x, y, theta] after each car's last reset or step."""
        self.scans = np.zeros((n, n_beams), dtype=np.float32)
        """(N, n_beams) every car's last scan, metres (noisy)."""
        self.scan_poses = np.zeros((n, 3))
        """(N, 3) the rear-axle world poses the last scans were taken at."""
        self.odom = np.zeros((n, 3), dtype=np.float32)
        """(N, 3) every car's last odometry: the VESC's noisy car-frame twist (m/s, m/s, rad/s)."""
        self.odometry_model = odometry
        """The odometry's noise ([`Odometry`][racecar_sim.sensors.odometry.Odometry])."""
        self._z = np.zeros((n, 6))
        self._z_rows = list(self._z)

    @property
    def twists(self) -> np.ndarray:
        """(N, 3) every car's true car-frame twist over its last step (m/s, m/s, rad/s): the
        physics' own rows (do not write them)."""
        return self.batch.twists

    # ------------------------------------------------------------------ commands
    def clip(self, commands: np.ndarray) -> np.ndarray:
        """(N, 2) float64 ``commands`` = [steer rad, speed m/s] clipped to the action box."""
        return np.minimum(np.maximum(commands, self.low), self.high)

    def command(self, cars: list[int], commands: np.ndarray) -> np.ndarray:
        """Give cars ``cars`` their rows of the clipped ``commands`` (N, 2); returns the commands
        that reach the bodies now (``commands`` itself without a delay, else a copy whose rows of
        ``cars`` are the commands given ``odom_lead`` earlier)."""
        if not self.delayed:
            return commands
        out = commands.copy()
        delays = self.delays
        for i in cars:
            out[i] = delays[i].push(float(commands[i, 0]), float(commands[i, 1]))
        return out

    # ------------------------------------------------------------------ stepping
    def reset(self, cars: list[int]) -> None:
        """Cars ``cars``, just placed at rest (their physics reset), start: clock at 0 with a scan
        due, the delay filled with the command that holds the wheels, the pose read."""
        self.clocks.reset(cars)
        for i in cars:
            physics = self.physics[i]
            self.delays[i].reset(physics.steer, physics.wheel_speed)
            self.poses[i] = physics.pose

    def step(self, cars: np.ndarray, commands: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Drive cars ``cars`` (int indices, ascending) ``dt`` seconds by their rows of the body
        ``commands`` (N, 2) (from `command()`), write their poses and tick their clocks.

        Returns:
            (whether each of ``cars`` touched a wall, or in a race another car's box; the cars
            whose scan is due now, ascending).
        """
        stepped = cars.tolist()
        hits, free = self.batch.step(stepped, commands, self.dt)
        poses = self.poses
        if free:
            poses[free] = self.batch.poses(free)
        if len(free) < len(stepped):  # stepped through pymunk: the body's pose
            done_free = set(free)
            physics = self.physics
            for i in stepped:
                if i not in done_free:
                    poses[i] = physics[i].pose
        return hits, self.clocks.tick(cars)

    def step_one(self, i: int, steer: float, speed: float) -> tuple[bool, bool, np.ndarray]:
        """`clip()`, `command()` and `step()` of car ``i`` alone, by a finite command (rad, m/s),
        in plain floats (the same doubles): returns (touched a wall, its scan is due, its new rear-axle world
        pose (3,))."""
        lo, hi = self._lo, self._hi
        steer = min(max(steer, lo[0]), hi[0])
        speed = min(max(speed, lo[1]), hi[1])
        delay = self.delays[i]
        if delay.n:
            steer, speed = delay.push(steer, speed)
        physics = self.physics[i]
        collided = physics.step((steer, speed), self.dt)
        pose = physics.pose
        self.poses[i] = pose
        return collided, self.clocks.tick_one(i), pose

    # ------------------------------------------------------------------ sensors
    def scan_seeds(self, due: list[int]) -> np.ndarray:
        """(K,) int64 the scan seeds of cars ``due``: one raw draw from each car's generator, its
        top 63 bits (``racecar_sim.raycast.rand.seed_from``, as
        [`Lidar.measure`][racecar_sim.sensors.lidar.Lidar.measure] draws it)."""
        cars = self.cars
        raw = np.array([cars[i].np_random.bit_generator.random_raw() for i in due], dtype=np.uint64)
        return (raw >> _ONE).astype(np.int64)

    def scanned(self, due: np.ndarray, scans: np.ndarray | None = None) -> None:
        """Cars ``due`` (ascending) took their scans at their current poses: keep ``scans`` (K,
        n_beams) as their last (None: already written into `scans`) and schedule the next."""
        if scans is not None:
            self.scans[due] = scans
        self.scan_poses[due] = self.poses[due]
        self.clocks.scanned(due)

    def scanned_one(self, i: int, pose: np.ndarray, scan: np.ndarray) -> None:
        """Car ``i`` took ``scan`` (n_beams,) at rear-axle world ``pose``: keep it, schedule the
        next."""
        self.scans[i] = scan
        self.scan_poses[i] = pose
        self.clocks.scanned_one(i)

    def odometry(self, cars: list[int]) -> np.ndarray:
        """(K, 3) float32 the VESC's noisy car-frame twist [vx m/s, vy m/s, omega rad/s] of
        ``cars`` from their wheels now (kept in `odom`), drawing six standard normals from each
        car's generator: the same draws and doubles as `odometry_one()` (without an odometry
        bias, which the env applies)."""
        if self.delayed:  # the wheels run ahead of the body: per car
            out = np.array([self.odometry_one(i) for i in cars], dtype=np.float32).reshape(-1, 3)
        else:
            rows, envs, physics = self._z_rows, self.cars, self.physics
            for i in cars:
                envs[i].np_random.standard_normal(out=rows[i])
            steer = np.array([physics[i].steer for i in cars])
            wheel_speed = np.array([physics[i].wheel_speed for i in cars])
            out = np.empty((len(cars), 3), dtype=np.float32)
            model = self.odometry_model
            vesc_odometry(steer, wheel_speed, self.wheelbase, self._z[cars], model.proportional,
                          model.additive, out)  # fmt: skip
        self.odom[cars] = out
        return out

    def odometry_one(self, i: int) -> np.ndarray:
        """(3,) float32 the VESC's noisy car-frame twist of car ``i`` from its wheels now, the
        wheels ahead of the body by the commands still on their way (six standard normals from
        its generator; not kept in `odom`: the env keeps it after its bias)."""
        physics = self.physics[i]
        steer, speed = physics.steer, physics.wheel_speed
        delay = self.delays[i]
        if delay.n:  # the wheels already have the commands the body has not
            steer, speed = delay.wheels_ahead(steer, speed)
        vx, vy, om = wheel_twist(speed, steer, self.wheelbase)
        return self.odometry_model.noisy(vx, vy, om, self.cars[i].np_random)
