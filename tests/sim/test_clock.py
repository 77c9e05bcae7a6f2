"""The car's clock and lidar schedule: one car's in floats, N cars' on arrays, the same numbers."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from racecar_sim.car.clock import CarClock, CarClocks


def scan_steps(clock: CarClock, n_steps: int) -> list[int]:
    """The steps (0 = the reset) at whose end a scan is taken."""
    clock.reset()
    clock.scanned()
    steps = [0]
    for k in range(1, n_steps + 1):
        if clock.tick():
            clock.scanned()
            steps.append(k)
    return steps


def test_a_40_hz_lidar_at_dt_0_01_scans_at_the_first_step_past_each_period() -> None:
    # due at 0.025, 0.05, 0.075, 0.1 s: the steps ending at 0.03, 0.05, 0.08, 0.1 s
    assert scan_steps(CarClock(0.01, 1 / 40), 10) == [0, 3, 5, 8, 10]


def test_a_lidar_faster_than_the_steps_scans_every_step() -> None:
    assert scan_steps(CarClock(0.01, 1 / 100), 5) == [0, 1, 2, 3, 4, 5]
    assert scan_steps(CarClock(0.025, 1 / 100), 3) == [0, 1, 2, 3]


def test_time_is_steps_times_dt_not_a_running_sum() -> None:
    clock = CarClock(0.1, 0.1)
    for _ in range(30):
        clock.tick()
    assert clock.time == 30 * 0.1 and clock.steps == 30


@given(
    dt=st.sampled_from([0.005, 0.01, 0.02, 0.025, 0.05]),
    rate=st.sampled_from([10.0, 20.0, 30.0, 40.0, 100.0]),
    moves=st.lists(st.lists(st.booleans(), min_size=3, max_size=3), min_size=1, max_size=60),
)
def test_n_cars_on_arrays_equal_n_single_clocks(dt: float, rate: float, moves) -> None:
    n = 3
    single = [CarClock(dt, 1 / rate) for _ in range(n)]
    many = CarClocks(n, dt, 1 / rate)
    many.scanned(np.arange(n))
    for c in single:
        c.scanned()
    for active in moves:
        cars = np.flatnonzero(active)
        due = many.tick(cars)
        many.scanned(due)
        expected = []
        for i in cars.tolist():
            if single[i].tick():
                single[i].scanned()
                expected.append(i)
        assert due.tolist() == expected
        assert many.times.tolist() == [c.time for c in single]  # the same doubles
        assert many.next_scan.tolist() == [c.next_scan for c in single]
        assert many.steps.tolist() == [c.steps for c in single]
