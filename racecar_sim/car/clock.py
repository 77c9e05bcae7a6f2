"""The car's clock and its lidar's schedule: the one place that says when a car's time advances
and when its next scan is due.

A car's time is ``steps * dt`` seconds since its reset (not a running sum, so no rounding drifts
in). A scan is taken at reset and at the end of the first step whose end time reaches the next
scan's due time, give or take [`EPS_TIME`][racecar_sim.car.clock.EPS_TIME]; after a scan at time ``t`` the next one is due at
the first multiple of the lidar period after ``t``. [`CarClock`][racecar_sim.car.clock.CarClock] keeps this for one car in
plain floats (the single env, and each car of the vector env);
[`CarClocks`][racecar_sim.car.clock.CarClocks] for N cars on
arrays (the race), with the same doubles (tested).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["EPS_TIME", "CarClock", "CarClocks"]

EPS_TIME = 1e-9
"""Seconds of tolerance when comparing the clock with the next scan's due time."""


class CarClock:
    """One car's clock and scan schedule (see the module doc).

    Args:
        dt: seconds per step.
        period: seconds between two scans (``1 / lidar_rate``).
    """

    def __init__(self, dt: float, period: float) -> None:
        self.dt = float(dt)
        self.period = float(period)
        self.steps = 0
        """Steps since the reset."""
        self.time = 0.0
        """Seconds since the reset (``steps * dt``)."""
        self.next_scan = 0.0
        """Seconds since the reset at which the next scan is due."""

    def reset(self) -> None:
        """Back to time 0 with a scan due now."""
        self.steps = 0
        self.time = 0.0
        self.next_scan = 0.0

    def tick(self) -> bool:
        """Advance by one step; returns whether a scan is due at the step's end."""
        self.steps += 1
        self.time = self.steps * self.dt
        return self.time + EPS_TIME >= self.next_scan

    def scanned(self) -> None:
        """A scan was taken now: the next is due at the next multiple of the period."""
        self.next_scan = (math.floor((self.time + EPS_TIME) / self.period) + 1) * self.period


class CarClocks:
    """N cars' clocks and scan schedules on arrays (see the module doc): the same numbers as N
    [`CarClock`][racecar_sim.car.clock.CarClock].

    Args:
        n: number of cars.
        dt: seconds per step.
        period: seconds between two scans of every car.
    """

    def __init__(self, n: int, dt: float, period: float) -> None:
        self.dt = float(dt)
        self.period = float(period)
        self.steps = np.zeros(n, dtype=np.int64)
        """(N,) steps since each car's reset."""
        self.times = np.zeros(n)
        """(N,) seconds since each car's reset (a car that does not step keeps its time)."""
        self.next_scan = np.zeros(n)
        """(N,) seconds at which each car's next scan is due."""

    def reset(self) -> None:
        """Every car back to time 0 with a scan due now."""
        self.steps[:] = 0
        self.times[:] = 0.0
        self.next_scan[:] = 0.0

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
