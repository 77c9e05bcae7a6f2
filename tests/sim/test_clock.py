"""The cars' clocks and lidar schedule: one car's in plain floats, N cars' on arrays, the same
numbers."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from racecar_sim.car.clock import CarClocks


def scan_steps(dt: float, period: float, n_steps: int) -> list[int]:
    """The steps (0 = the reset) at whose end a scan is taken, of one car (its own path) and of
    the same car among others on arrays (which must agree)."""
    one, many = CarClocks(1, dt, period), CarClocks(3, dt, period)
    one.reset()
    one.scanned_one(0)
    many.scanned(np.arange(3))
    steps = [0]
    for k in range(1, n_steps + 1):
        due = many.tick(np.array([1]))
        many.scanned(due)
        if one.tick_one(0):
            one.scanned_one(0)
            steps.append(k)
        assert due.tolist() == ([1] if steps[-1] == k else [])
    return steps


def test_a_40_hz_lidar_at_dt_0_01_scans_at_the_first_step_past_each_period() -> None:
    # due at 0.025, 0.05, 0.075, 0.1 s: the steps ending at 0.03, 0.05, 0.08, 0.1 s
    assert scan_steps(0.01, 1 / 40, 10) == [0, 3, 5, 8, 10]


def test_a_lidar_faster_than_the_steps_scans_every_step() -> None:
    assert scan_steps(0.01, 1 / 100, 5) == [0, 1, 2, 3, 4, 5]
    assert scan_steps(0.025, 1 / 100, 3) == [0, 1, 2, 3]


def test_time_is_steps_times_dt_not_a_running_sum() -> None:
    clocks = CarClocks(2, 0.1, 0.1)
    for _ in range(30):
        clocks.tick_one(0)
        clocks.tick(np.array([1]))
    assert clocks.times.tolist() == [30 * 0.1] * 2 and clocks.steps.tolist() == [30] * 2


@given(
    dt=st.sampled_from([0.005, 0.01, 0.02, 0.025, 0.05]),
    rate=st.sampled_from([10.0, 20.0, 30.0, 40.0, 100.0]),
    moves=st.lists(st.lists(st.booleans(), min_size=3, max_size=3), min_size=1, max_size=60),
)
def test_n_cars_on_arrays_equal_each_car_in_plain_floats(dt: float, rate: float, moves) -> None:
    n = 3
    single = CarClocks(n, dt, 1 / rate)  # stepped car by car (the single env's path)
    many = CarClocks(n, dt, 1 / rate)
    many.scanned(np.arange(n))
    for i in range(n):
        single.scanned_one(i)
    for active in moves:
        cars = np.flatnonzero(active)
        due = many.tick(cars)
        many.scanned(due)
        expected = []
        for i in cars.tolist():
            if single.tick_one(i):
                single.scanned_one(i)
                expected.append(i)
        assert due.tolist() == expected
        assert many.times.tolist() == single.times.tolist()  # the same doubles
        assert many.next_scan.tolist() == single.next_scan.tolist()
        assert many.steps.tolist() == single.steps.tolist()
