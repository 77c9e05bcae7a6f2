"""Scan continuity: consecutive scans agree with the odometry between them unless the car jumped."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from mcl.filter.lost_params import LostParams
from mcl.filter.motion_model import twist_to_odometry
from mcl.filter.scan_continuity import (
    ScanContinuity,
    compose,
    invert,
    scan_continuity,
)
from racecar_sim.env import RacecarEnv

ENV = RacecarEnv("basement_loop")  # corridors that look alike: the honest case for a jump check
LIDAR = ENV.lidar
MOUNT = np.array([ENV.lidar_params.mount_offset, 0.0, 0.0])
MAX_RANGE = ENV.lidar_params.max_range
DT = 0.025


def _continuity(pose: np.ndarray, twist: np.ndarray, after: np.ndarray, odometry=None) -> float:
    """Continuity of the exact scan at ``after`` with the exact scan at ``pose``, the odometry
    (default ``twist``) fed for one step of DT seconds."""
    checker = ScanContinuity(MOUNT, MAX_RANGE)
    checker.observe(LIDAR.true_ranges(pose), LIDAR.angles)
    checker.advance(twist if odometry is None else odometry, DT)
    return checker.observe(LIDAR.true_ranges(after), LIDAR.angles)


def _free_pose(seed: int) -> np.ndarray:
    ENV.reset(seed=seed)
    return ENV.pose


poses_a = st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-math.pi, math.pi))


@given(poses_a, poses_a)
def test_compose_with_the_inverse_is_the_identity(a, b) -> None:
    a, b = np.array(a), np.array(b)
    back = compose(compose(a, b), invert(b))
    assert np.allclose(back[:2], a[:2], atol=1e-9)
    assert math.isclose(math.remainder(back[2] - a[2], 2 * math.pi), 0.0, abs_tol=1e-9)


def test_the_odometry_between_scans_is_an_arc() -> None:
    # a quarter circle of radius 2 m: 90 degrees left, 2 m ahead and 2 m to the left
    speed, radius = 1.5, 2.0
    dt = (math.pi / 2) * radius / speed
    motion = twist_to_odometry(np.array([speed, 0.0, speed / radius]), dt)
    assert np.allclose(motion, [radius, radius, math.pi / 2], atol=1e-12)
    assert np.allclose(twist_to_odometry(np.array([2.0, 0.5, 0.0]), 0.5), [1.0, 0.25, 0.0])


@given(
    st.integers(0, 10_000),
    st.floats(-1.0, 3.0),
    st.floats(-2.0, 2.0),
)
def test_a_scan_continues_the_last_one_where_the_odometry_moved_the_car(seed, speed, omega) -> None:
    pose = _free_pose(seed)
    twist = np.array([speed, 0.0, omega])
    after = compose(pose, twist_to_odometry(twist, DT))
    assert _continuity(pose, twist, after) > 0.9


def test_a_scan_from_elsewhere_mostly_does_not_continue_the_last_one() -> None:
    # kidnaps of 2 m or more to random free poses: most are jumps for the lost flag's default
    # threshold; a few land where the corridor looks the same from both places, none looks
    # continuous
    found = []
    for seed in range(60):
        pose, elsewhere = _free_pose(seed), _free_pose(seed + 1000)
        if math.hypot(*(elsewhere[:2] - pose[:2])) >= 2.0:
            found.append(_continuity(pose, np.array([1.0, 0.0, 0.0]), elsewhere))
    found = np.array(found)
    assert found.size >= 50 and np.isfinite(found).all()
    assert np.mean(found < LostParams().jump_below) >= 0.9
    assert found.max() < 0.8


def test_odometry_that_disagrees_with_the_motion_breaks_the_continuity() -> None:
    pose = _free_pose(3)
    twist = np.array([1.0, 0.0, 0.0])
    after = compose(pose, twist_to_odometry(twist, DT))
    assert _continuity(pose, twist, after) > 0.95
    # the wheels say the car turned 40 degrees in one step: the scan did not
    assert _continuity(pose, twist, after, odometry=np.array([1.0, 0.0, 0.7 / DT])) < 0.5


def test_too_few_points_give_nan_and_the_first_scan_has_no_continuity() -> None:
    checker = ScanContinuity(MOUNT, MAX_RANGE)
    assert math.isnan(checker.observe(LIDAR.true_ranges(_free_pose(1)), LIDAR.angles))
    far = np.full(LIDAR.angles.size, MAX_RANGE)  # no returns at all
    assert math.isnan(
        scan_continuity(far, LIDAR.angles, far, LIDAR.angles, np.zeros(3), MAX_RANGE, 0.1, 0.03)
    )


def _long_gap(seed: int) -> tuple[float, float] | None:
    """Continuity after 0.5 s (0.6 m, 43 degrees) between two scans from the free pose of
    ``seed``, with the odometry fed and without it; None when the arc ends in a wall."""
    pose = _free_pose(seed)
    twist = np.array([1.2, 0.0, 1.5])  # 0.6 m and 0.75 rad over 0.5 s
    after = pose
    for _ in range(20):
        after = compose(after, twist_to_odometry(twist, DT))
    if not ENV.unwrapped.physics.pose_is_free(after):
        return None
    fed, unfed = ScanContinuity(MOUNT, MAX_RANGE), ScanContinuity(MOUNT, MAX_RANGE)
    for checker in (fed, unfed):
        checker.observe(LIDAR.true_ranges(pose), LIDAR.angles)
    for _ in range(20):
        fed.advance(twist, DT)
    return (
        fed.observe(LIDAR.true_ranges(after), LIDAR.angles),
        unfed.observe(LIDAR.true_ranges(after), LIDAR.angles),
    )


@given(st.integers(0, 10_000))
def test_a_long_gap_between_scans_is_bridged_by_the_odometry(seed) -> None:
    # all 8104 free arcs of this domain, run through on 2026-12-03: 0.863 the lowest (seed 8240,
    # a corner that hides part of the room after 43 degrees), 0.99 the median
    found = _long_gap(seed)
    if found is not None:
        assert found[0] > 0.85


def test_without_the_odometry_a_long_gap_reads_as_a_jump() -> None:
    # Not an invariant pose by pose: a room that looks alike turned by 43 degrees keeps up to
    # about 0.6 of the points (hypothesis found 0.51 at seed 2715 and 0.63 at 852); over many
    # poses the unexplained motion falls mostly under the jump threshold, and never above the fed.
    found = np.array([g for g in map(_long_gap, range(0, 1400, 7)) if g is not None])
    fed, unfed = found[:, 0], found[:, 1]
    assert found.shape[0] >= 100
    assert np.mean(unfed < LostParams().jump_below) >= 0.95
    assert np.median(unfed) < 0.25
    assert np.all(fed - unfed > 0.3)
    for seed in (852, 2715):  # the look-alike cases: still below what the odometry keeps
        with_odometry, without = _long_gap(seed)
        assert with_odometry - without > 0.3
