"""The race benchmark's workload: a column of cars on a straight, no crashes (peer not run)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from race_helpers import hall_map

from mcl.bench.peer_race import column_poses, column_start, compare_race


def test_column_start_finds_a_clear_straight_and_refuses_a_long_one():
    hall = hall_map()
    start = column_start(hall, 20.0)
    ahead = start[:2] + np.linspace(0, 20, 50)[:, None] * np.array(
        [math.cos(start[2]), math.sin(start[2])]
    )
    assert (hall.distance_at(ahead) >= 0.6).all()
    with pytest.raises(ValueError, match=r"no straight line of 40\.0 m"):
        column_start(hall, 40.0)


def test_column_poses_put_car_0_in_front():
    poses = column_poses(np.array([1.0, 2.0, 0.0]), 3, 1.5)
    np.testing.assert_allclose(poses[:, 0], [4.0, 2.5, 1.0])


def test_the_race_workload_runs_without_crashes(capsys):
    out = compare_race(hall_map(), None, None, None, sizes=(2, 3), max_cars=4, steps=20, runs=1)
    text = capsys.readouterr().out
    assert "f1tenth_gym: not measured" in text
    assert set(out) == {2, 3, 4} and all(v["ours"] > 0 for v in out.values())
    assert "| 3 | nan, nan |" in text and "| 0, 0 |" in text  # no peer, no collisions
