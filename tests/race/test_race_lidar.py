"""The race's cast against its definition: every beam the nearer of the full wall cast and every
other car's box, bit for bit, whatever the culling (sectors, cars hidden behind nearer ones, beams
cast only to just behind the car they hit)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from race_helpers import hall_map

from racecar_sim.race.lidar import race_scans_serial
from racecar_sim.race.world import RaceWorld
from racecar_sim.raycast.scan import exact_one
from racecar_sim.settings.config import EnvConfig
from racecar_sim.world.obstacles import ray_segment

# A narrow hall (3 m wide) so that walls are often nearer than a car a beam would hit.
WORLD = RaceWorld(8, EnvConfig(map=hall_map(12.0, 3.0), n_beams=541, max_range=30.0))


@nb.njit(cache=True)
def _brute_force(field, poses, geometry, cos_a, sin_a, boxes, ranges):
    """Every beam cast to max_range on the walls, then cut by every other car's four edges."""
    for k in range(poses.shape[0]):
        x, y, th = poses[k, 0], poses[k, 1], poses[k, 2]
        exact_one(field, x, y, th, geometry, cos_a, sin_a, None, ranges[k])
        mx = x + geometry[6] * math.cos(th)
        my = y + geometry[6] * math.sin(th)
        ct, st_ = math.cos(th), math.sin(th)
        for c in range(boxes.shape[0]):
            if c == k:
                continue
            for i in range(cos_a.shape[0]):
                bx = ct * cos_a[i] - st_ * sin_a[i]
                by = st_ * cos_a[i] + ct * sin_a[i]
                best = ranges[k, i]
                for e in range(4):
                    f = (e + 1) % 4
                    best = ray_segment(mx, my, bx, by, boxes[c, e, 0], boxes[c, e, 1],
                                       boxes[c, f, 0], boxes[c, f, 1], best)  # fmt: skip
                ranges[k, i] = best


def _race_ranges(world: RaceWorld, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n, m = len(poses), world.lidar_params.n_beams
    ranges = np.empty((n, m))
    out = np.empty((n, m), dtype=np.float32)
    status = np.zeros(n, dtype=np.int64)
    race_scans_serial(
        world._field, poses, np.arange(n), world._geometry, world._cos_a, world._sin_a,
        world._angle0, world._step, world.boxes(poses), world.radius,
        np.arange(n, dtype=np.int64), world._noise, ranges, out, status,
    )  # fmt: skip
    assert not status.any()
    return ranges, out


def _reference(world: RaceWorld, poses: np.ndarray) -> np.ndarray:
    ranges = np.empty((len(poses), world.lidar_params.n_beams))
    _brute_force(world._field, poses, world._geometry, world._cos_a, world._sin_a,
                 world.boxes(poses), ranges)  # fmt: skip
    return ranges


_pose = st.tuples(st.floats(0.4, 11.6), st.floats(0.3, 2.7), st.floats(-math.pi, math.pi))


@settings(max_examples=60)
@given(st.lists(_pose, min_size=8, max_size=8))
def test_race_scans_are_the_full_cast_cut_by_every_car(poses):
    arr = np.array(poses)
    ranges, _ = _race_ranges(WORLD, arr)
    np.testing.assert_array_equal(ranges, _reference(WORLD, arr))


def test_a_column_of_cars_is_the_full_cast_and_cars_are_seen():
    # The benchmark's case: cars one behind the other, each sees only the one ahead's rear.
    arr = np.array([[10.5 - 1.2 * i, 1.5, 0.0] for i in range(8)])
    ranges, _ = _race_ranges(WORLD, arr)
    np.testing.assert_array_equal(ranges, _reference(WORLD, arr))
    alone = np.empty_like(ranges)
    _brute_force(WORLD._field, arr, WORLD._geometry, WORLD._cos_a, WORLD._sin_a,
                 WORLD.boxes(arr) + 1e4, alone)  # fmt: skip
    cut = ranges < alone
    assert not cut[0].any()  # the leader sees no car
    assert cut[1:].sum(axis=1).min() > 10  # every other car sees the one ahead


def test_a_lidar_inside_another_car_sees_its_box_from_within():
    # Car 1's box around car 0's lidar: every beam leaves through car 1's edges (or its walls).
    arr = np.array([[5.0, 1.5, 0.0], [5.0, 1.5, 0.2], [8.0, 1.5, math.pi]])
    ranges, _ = _race_ranges(WORLD, arr)
    np.testing.assert_array_equal(ranges, _reference(WORLD, arr))
    assert ranges[0].max() < 0.5
