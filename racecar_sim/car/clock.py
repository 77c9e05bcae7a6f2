"""The cars' clocks and their lidars' schedule: the one place that says when a car's time
advances and when its next scan is due.

A car's time is ``steps * dt`` seconds since its reset (not a running sum, so no rounding drifts
in). A scan is taken at reset and at the end of the first step whose end time reaches the next
scan's due time, give or take [`EPS_TIME`][racecar_sim.car.clock.EPS_TIME]; after a scan at time
``t`` the next one is due at the first multiple of the lidar period after ``t``.
[`CarClocks`][racecar_sim.car.clock.CarClocks] keeps this for N cars on arrays (the core of
every env, [`racecar_sim.fleet`][racecar_sim.fleet]), with a path for one car in plain floats that
gives the same doubles (tested).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["EPS_TIME", "CarClocks"]

EPS_TIME = 1e-9
"""Seconds of tolerance when comparing the clock with the next scan's due time."""


class CarClocks:
    """N cars' clocks and scan schedules on arrays (see the module doc).

    Args:
        n: number of cars.
        dt: seconds per step.
        period: seconds between two scans of every car (``1 / lidar_rate``).
    """

    def __init__(self, n: int, dt: float, period: float) -> None:
        self.dt = float(dt)
        self.period = float(period)
        self.steps = np.zeros(n, dtype=np.int64)
        """(N,) steps since each car's reset."""
        self.times = np.zeros(n)
        """(N,) seconds since each car's reset (a car that does not step keeps its time)."""
        self.next_scan = np.zeros(n)
        """(N,) seconds since each car's reset at which its next scan is due."""
        self._views()

    def _views(self) -> None:
        # The same memory as plain Python ints and floats, for the one-car path (numpy's scalars
        # cost twice as much per access on the single env's hot path).
        self._steps1, self._times1, self._next1 = (
            memoryview(self.steps), memoryview(self.times), memoryview(self.next_scan)
        )

    def __getstate__(self) -> dict:
        """For pickle and deepcopy (an env is copied whole): the arrays, not their views."""
        return {k: v for k, v in self.__dict__.items() if not isinstance(v, memoryview)}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._views()

    def reset(self, cars: np.ndarray | list[int] | None = None) -> None:
        """``cars`` (int indices; None: every car) back to time 0 with a scan due now."""
        if cars is None:
            cars = slice(None)
        self.steps[cars] = 0
        self.times[cars] = 0.0
        self.next_scan[cars] = 0.0

    def tick(self, cars: np.ndarray) -> np.ndarray:
        """Advance ``cars`` (int indices, ascending) by one step; returns those of them whose scan
        is due at the step's end."""
        self.steps[cars] += 1
        times = self.steps[cars] * self.dt
        self.times[cars] = times
        return cars[times + EPS_TIME >= self.next_scan[cars]]

    def scanned(self, cars: np.ndarray) -> None:
        """``cars`` took a scan now: each one's next is due at the next multiple of the period."""
        done = np.floor((self.times[cars] + EPS_TIME) / self.period) + 1.0
        self.next_scan[cars] = done * self.period

    def time(self, i: int) -> float:
        """Seconds since car ``i``'s reset."""
        return self._times1[i]

    def tick_one(self, i: int) -> bool:
        """`tick()` of car ``i`` alone, in plain floats; returns whether its scan is due."""
        steps = self._steps1[i] + 1
        self._steps1[i] = steps
        time = steps * self.dt
        self._times1[i] = time
        return time + EPS_TIME >= self._next1[i]

    def scanned_one(self, i: int) -> None:
        """`scanned()` of car ``i`` alone, in plain floats."""
        done = math.floor((self._times1[i] + EPS_TIME) / self.period) + 1
        self._next1[i] = done * self.period
