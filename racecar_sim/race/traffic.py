"""What the scripted drivers of a race know about the cars: where each one is on the track.

[Traffic][racecar_sim.race.traffic.Traffic] turns the race's poses (rear axles, world frame) into
the track's frame once per step, for all cars at once: arc length ``s``, lateral offset, speed along
the track, and the gaps along the track between every pair of cars. The speeds are what an opponent
sees: the change of a car's place on the track between two updates, not the simulator's twist. It
also places each car's outline (points on its box's edges) in the track's frame, for the drivers'
last check ahead.

The race updates it: ``RacecarRace-v0`` after every reset and step; with
[RaceEnv][racecar_sim.race.env.RaceEnv] call ``traffic.update(env.poses, env.world.time)`` after
each step. Drivers read it ([RacingDriver][racecar_sim.race.racing_driver.RacingDriver]).
"""

from __future__ import annotations

import numpy as np

from racecar_sim.settings.config import CarParams
from racecar_sim.world.track import Track

__all__ = ["Traffic"]

_OUTLINE_POINTS = (
    5  # points along each long side of a car's box (the short sides get their middles)
)


class Traffic:
    """The cars of a race in the track's frame (see the module doc).

    Args:
        track: the race's track.
        n_cars: number of cars.
        car: their geometry (``length``, ``width``, ``rear_overhang``; every car's the same).
        smoothing: weight of the newest speed measurement (1: no smoothing).

    Attributes:
        poses: (N, 3) rear-axle world poses [x, y, theta] of the last update.
        s: (N,) arc length of each car on the track, metres in [0, length).
        lateral: (N,) metres left (positive) or right of the centerline.
        speed: (N,) metres per second along the track (0 at a reset).
        gaps: (N, N) metres along the track from car i's rear axle forwards to car j's,
            in [-length / 2, length / 2) (negative: j is behind i).
        outline_s, outline_lateral: (N, P) arc length and lateral offset (metres) of P points
            on the edges of each car's box.
        time: seconds of the last update.
        dt: seconds between the last two updates (0 after a reset).
    """

    def __init__(self, track: Track, n_cars: int, car: CarParams, smoothing: float = 0.5) -> None:
        if not isinstance(n_cars, int) or n_cars < 1:
            raise ValueError(f"Traffic.n_cars = {n_cars!r} must be a positive integer")
        if not 0 < smoothing <= 1:
            raise ValueError(f"Traffic.smoothing = {smoothing!r} must be in (0, 1]")
        self.track = track
        self.n_cars = n_cars
        self.car = car
        self.smoothing = float(smoothing)
        front = car.length - car.rear_overhang
        along = np.linspace(-car.rear_overhang, front, _OUTLINE_POINTS)
        half = car.width / 2
        self._outline = np.concatenate(
            [
                np.stack([along, np.full_like(along, half)], axis=1),
                np.stack([along, np.full_like(along, -half)], axis=1),
                [[-car.rear_overhang, 0.0], [front, 0.0]],
            ]
        )  # car frame
        self.poses = np.zeros((n_cars, 3))
        self.s = np.zeros(n_cars)
        self.lateral = np.zeros(n_cars)
        self.speed = np.zeros(n_cars)
        self.gaps = np.zeros((n_cars, n_cars))
        self.outline_s = np.zeros((n_cars, len(self._outline)))
        self.outline_lateral = np.zeros((n_cars, len(self._outline)))
        self.time = 0.0
        self.dt = 0.0
        self._hint = np.full(n_cars, -1, dtype=np.int64)

    def reset(self, poses: np.ndarray, time: float = 0.0) -> None:
        """The cars stand at ``poses`` (N, 3) at ``time`` seconds; speeds 0."""
        self._hint[:] = -1
        self._place(poses)
        self.speed[:] = 0.0
        self.time = float(time)
        self.dt = 0.0

    def update(self, poses: np.ndarray, time: float) -> None:
        """The cars moved to ``poses`` (N, 3) by ``time`` seconds (later than the last update)."""
        old_s = self.s.copy()
        self._place(poses)
        dt = float(time) - self.time
        if dt > 0:
            length = self.track.length
            moved = np.mod(self.s - old_s + length / 2, length) - length / 2
            a = self.smoothing
            self.speed = a * (moved / dt) + (1 - a) * self.speed
        self.dt = max(dt, 0.0)
        self.time = float(time)

    def _place(self, poses: np.ndarray) -> None:
        poses = np.asarray(poses, dtype=np.float64)
        if poses.shape != (self.n_cars, 3):
            raise ValueError(f"Traffic: poses must be ({self.n_cars}, 3), got {poses.shape}")
        self.poses = poses.copy()
        self.s, self.lateral, self._hint = self.track.locate(poses[:, :2], self._hint)
        length = self.track.length
        self.gaps = np.mod(self.s[None, :] - self.s[:, None] + length / 2, length) - length / 2
        points = self.outlines().reshape(-1, 2)
        hint = np.repeat(self._hint, len(self._outline))  # each point near its car's place
        s, lateral, _ = self.track.locate(points, hint)
        self.outline_s = s.reshape(self.n_cars, -1)
        self.outline_lateral = lateral.reshape(self.n_cars, -1)

    def outlines(self) -> np.ndarray:
        """(N, P, 2) world points on the edges of every car's box at the last update."""
        c, s = np.cos(self.poses[:, 2]), np.sin(self.poses[:, 2])
        x, y = self._outline[:, 0], self._outline[:, 1]
        wx = self.poses[:, :1] + c[:, None] * x - s[:, None] * y
        wy = self.poses[:, 1:2] + s[:, None] * x + c[:, None] * y
        return np.stack([wx, wy], axis=2)
