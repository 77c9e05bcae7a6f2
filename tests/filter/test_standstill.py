"""Wheels that turn while the car stands: the filter stops following an odometry its scans
contradict, and only then (mcl.filter.standstill)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.experiments.recorded import RecordedDrive, localize_recorded
from mcl.filter.motion_model import twist_to_odometry
from mcl.filter.params import ParticleFilterParams
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.scan_continuity import compose
from mcl.filter.standstill import Standstill, StandstillParams
from tests.filter.loop_scans import DT, ENV, LIDAR, MAX_RANGE, MOUNT, free_pose


def _run(poses: list[np.ndarray], twist: np.ndarray) -> Standstill:
    """The check fed the exact scan at each pose, ``twist`` as the odometry between them."""
    check = Standstill()
    check.observe(LIDAR.true_ranges(poses[0]), LIDAR.angles, MOUNT, MAX_RANGE)
    for pose in poses[1:]:
        check.advance(twist, DT)
        check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE)
    return check


@settings(max_examples=40)
@given(st.integers(0, 10_000), st.floats(0.5, 2.0), st.floats(-1.0, 1.0))
def test_a_car_that_drives_as_its_odometry_says_never_stands(seed, speed, omega) -> None:
    twist = np.array([speed, 0.0, omega])
    poses = [free_pose(seed)]
    for _ in range(40):  # 1 s: several comparisons of 0.2 m or 0.2 rad
        poses.append(compose(poses[-1], twist_to_odometry(twist, DT)))
    check = _run(poses, twist)
    assert not check.standing and check.n_standing == 0


@pytest.mark.parametrize("seed", [0, 3, 7])
def test_a_pinned_car_stands_after_three_comparisons(seed) -> None:
    pose = free_pose(seed)
    twist = np.array([1.0, 0.0, -0.5])  # the wheels push on and the steering is turned
    check = Standstill()
    check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE)
    driven, steps = np.zeros(3), 0
    while not check.standing:
        steps += 1
        assert steps < 200, "never found standing"
        check.advance(twist, DT)
        driven = compose(driven, twist_to_odometry(twist, DT))
        check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE)
    # three comparisons of 0.2 m each: the odometry said the car drove about 0.6 m
    assert 0.55 < math.hypot(driven[0], driven[1]) < 0.7
    assert check.n_standing == 1


def test_the_check_lets_go_when_the_car_moves_again() -> None:
    pose = free_pose(5)
    twist = np.array([1.0, 0.0, 0.0])
    poses = [pose] * 30 + [compose(pose, twist_to_odometry(twist, DT * k)) for k in range(1, 30)]
    check = Standstill()
    check.observe(LIDAR.true_ranges(poses[0]), LIDAR.angles, MOUNT, MAX_RANGE)
    states = []
    for p in poses[1:]:
        check.advance(twist, DT)
        check.observe(LIDAR.true_ranges(p), LIDAR.angles, MOUNT, MAX_RANGE)
        states.append(check.standing)
    assert any(states[:29]) and not states[-1]


def test_standstill_params_are_checked() -> None:
    with pytest.raises(ValueError, match="in_a_row"):
        StandstillParams(in_a_row=0)
    with pytest.raises(ValueError, match="still_above"):
        StandstillParams(still_above=1.5)
    with pytest.raises(ValueError, match="enabled"):
        StandstillParams(enabled="yes")
    with pytest.raises(ValueError, match="take_back"):
        StandstillParams(take_back=1)
    with pytest.raises(ValueError, match="hold_still"):
        StandstillParams(hold_still="no")
    with pytest.raises(ValueError, match="hold_searching"):
        StandstillParams(hold_searching=0)


def _pinned_drive(seed: int, seconds: float) -> RecordedDrive:
    """A car that stands at a free pose for ``seconds`` with its wheels reporting 1 m/s."""
    pose = free_pose(seed)
    n = int(round(seconds / DT)) + 1
    scan = LIDAR.true_ranges(pose).astype(np.float32)
    odom = np.tile(np.array([1.0, 0.0, 0.3], dtype=np.float32), (n, 1))
    odom[0] = 0.0
    return RecordedDrive(
        time=np.arange(n) * DT, dt_steps=np.r_[0.0, np.full(n - 1, DT)],
        truth=np.tile(pose, (n, 1)), odom=odom, fresh=np.ones(n, dtype=bool),
        scans=np.tile(scan, (n, 1)), beam_angles=np.asarray(LIDAR.angles, dtype=np.float64),
        mount_offset=float(MOUNT[0]), max_range=float(MAX_RANGE), dt=DT,
        world_map="basement_loop",
    )  # fmt: skip


@pytest.mark.parametrize("seed", [1, 4])
def test_the_filter_stays_with_a_car_whose_wheels_spin(seed) -> None:
    drive = _pinned_drive(seed, 4.0)
    held = localize_recorded(drive).position_error
    followed = localize_recorded(drive, {"filter": {"standstill": {"enabled": False}}})
    assert followed.position_error[-1] > 1.0  # following the wheels drives the estimate away
    assert held[-1] < 0.2 and held.max() < 0.5


@pytest.mark.parametrize("seed", [2, 4])
def test_the_motion_predicted_before_the_car_was_found_standing_is_taken_back(seed) -> None:
    # three comparisons of 0.2 m find the car standing: the filter has followed its wheels for
    # about 0.6 m by then; the scan would pull it back, but the default holds a standing cloud
    drive = _pinned_drive(seed, 2.0)
    taken_back = localize_recorded(drive).position_error
    kept = localize_recorded(drive, {"filter": {"standstill": {"take_back": False}}})
    assert kept.position_error[20:].max() > 0.3  # before the check found it, it followed
    assert kept.position_error[-1] > 0.3  # ... and a cloud held still stays there
    assert taken_back[-1] < 0.02 and taken_back[40:].max() < 0.02


SPINNING = np.array([1.0, 0.0, 0.4])  # the wheels' twist while the car stands


def _standing_filter(still: StandstillParams) -> ParticleFilter:
    """A filter on a car that stands while its wheels spin, once the check has found it."""
    pose = free_pose(6)
    pf = ParticleFilter(ENV.map, 200, params=ParticleFilterParams(standstill=still), rng=4)
    pf.initialize(pose, spread=(0.05, 0.05, 0.02))
    for _ in range(100):
        pf.predict(SPINNING, DT)
        pf.correct(LIDAR.true_ranges(pose))
        if pf.standstill.standing:
            break
    assert pf.standstill.standing
    return pf


@pytest.mark.parametrize("hold_still", [True, False])
def test_a_standing_car_s_cloud_is_not_spread_by_the_motion_noise(hold_still) -> None:
    pf = _standing_filter(StandstillParams(hold_still=hold_still))
    before = pf.particles.copy()
    for _ in range(10):
        pf.predict(SPINNING, DT)
    moved = np.abs(pf.particles - before).max()
    assert (moved == 0.0) if hold_still else (moved > 0.0)  # only the noise moves them


@pytest.mark.parametrize("hold_searching", [True, False])
def test_a_searching_cloud_keeps_its_motion_noise_while_the_car_stands(hold_searching) -> None:
    # after a kidnap the cloud is spread over look-alike places: a car that stands gives its
    # poses no motion to refine them by, so (hold_searching False) the noise still moves them
    pf = _standing_filter(StandstillParams(hold_searching=hold_searching))
    assert not pf.searching
    before = pf.particles.copy()
    pf.predict(SPINNING, DT)
    assert np.abs(pf.particles - before).max() == 0.0  # a tracking cloud is held either way
    pf.searching = True  # as a correction sets it once the cloud spreads (a search)
    pf.predict(SPINNING, DT)
    moved = np.abs(pf.particles - before)
    assert (moved.max() == 0.0) if hold_searching else (moved[:, :2].max() < 0.2)
    if not hold_searching:  # the search's noise, not the wheels: nowhere near 1 m/s x DT ahead
        assert moved.max() > 0.0
        step = pf.particles[:, :2] - before[:, :2]
        ahead = step[:, 0] * np.cos(before[:, 2]) + step[:, 1] * np.sin(before[:, 2])
        assert abs(float(ahead.mean())) < 0.01  # the wheels would say 0.025 m


def test_take_back_is_given_once_and_only_when_asked_for() -> None:
    pose = free_pose(6)
    twist = np.array([1.0, 0.0, 0.4])
    for params, wanted in ((StandstillParams(), True), (StandstillParams(take_back=False), False)):
        check = Standstill(params)
        check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE, pose)
        given = []
        for _ in range(100):
            check.advance(twist, DT)
            check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE, pose)
            given.append(check.take_back() is not None)
        assert check.standing and sum(given) == int(wanted)


def test_nothing_is_taken_back_to_an_estimate_from_before_the_cloud_was_replaced() -> None:
    pose = free_pose(6)
    twist = np.array([1.0, 0.0, 0.4])
    check = Standstill()
    check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE, pose)
    given, replaced = [], False
    while not check.standing:
        check.advance(twist, DT)
        if check.due() and not replaced:  # the first comparison: a burst replaced the cloud
            check.cloud_replaced()
            replaced = True
        check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE, pose)
        given.append(check.take_back() is not None)
    assert replaced and not any(given)


def test_take_back_returns_the_estimate_where_the_comparisons_began() -> None:
    pose = free_pose(8)
    twist = np.array([1.0, 0.0, -0.5])
    check = Standstill()
    estimate = pose.copy()
    check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE, estimate)
    starts = [estimate.copy()]
    while not check.standing:
        check.advance(twist, DT)
        estimate = compose(estimate, twist_to_odometry(twist, DT))  # a filter that follows
        was = check.due()
        check.observe(LIDAR.true_ranges(pose), LIDAR.angles, MOUNT, MAX_RANGE, estimate)
        if was:
            starts.append(estimate.copy())
    # the estimate at the reference scan of the first of the three comparisons that found it
    np.testing.assert_allclose(check.take_back(), starts[-4], atol=1e-12)
    assert np.allclose(starts[-4], pose)  # here the car stood from the start
    assert np.hypot(*(estimate[:2] - pose[:2])) > 0.5


def _pivoting_drive(seed: int, seconds: float, rate: float = 0.12) -> RecordedDrive:
    """A car pinned at one corner that pivots on the spot at ``rate`` rad/s while its wheels
    report 0.6 m/s backwards and 0.8 rad/s (cluttered seed 18 of the honest world at 18-22 s:
    0.12 rad/s)."""
    pose = free_pose(seed)
    n = int(round(seconds / DT)) + 1
    truth = np.tile(pose, (n, 1))
    truth[:, 2] = pose[2] + rate * DT * np.arange(n)
    scans = np.stack([LIDAR.true_ranges(p) for p in truth]).astype(np.float32)
    odom = np.tile(np.array([-0.6, 0.0, 0.8], dtype=np.float32), (n, 1))
    odom[0] = 0.0
    return RecordedDrive(
        time=np.arange(n) * DT, dt_steps=np.r_[0.0, np.full(n - 1, DT)], truth=truth, odom=odom,
        fresh=np.ones(n, dtype=bool), scans=scans,
        beam_angles=np.asarray(LIDAR.angles, dtype=np.float64), mount_offset=float(MOUNT[0]),
        max_range=float(MAX_RANGE), dt=DT, world_map="basement_loop",
    )  # fmt: skip


@pytest.mark.parametrize("seed", [2, 6])
def test_a_pivoting_car_moves_a_share_of_what_its_wheels_say(seed) -> None:
    drive = _pivoting_drive(seed, 2.0)
    check = Standstill()
    check.observe(drive.scans[0], LIDAR.angles, MOUNT, MAX_RANGE)
    shares = []
    for k in range(1, len(drive.time)):
        check.advance(drive.odom[k].astype(np.float64), DT)
        check.observe(drive.scans[k], LIDAR.angles, MOUNT, MAX_RANGE)
        shares.append(check.motion_shares.copy())
    late = np.array(shares[len(shares) // 2 :])
    assert np.all(late[:, 0] == 0.0)  # it does not drive
    assert np.all((late[:, 1] > 0.0) & (late[:, 1] <= 0.25))  # it turns, far less than 0.8 rad/s


@pytest.mark.parametrize("seed", [1, 3, 7])
def test_the_filter_turns_with_a_pivoting_car_not_with_its_wheels(seed) -> None:
    # pivoting at 0.3 rad/s: neither following the wheels nor standing still holds the car
    drive = _pivoting_drive(seed, 4.0, rate=0.3)
    held = localize_recorded(drive)
    standing_only = localize_recorded(drive, {"filter": {"standstill": {"shares": [0.0]}}})
    followed = localize_recorded(drive, {"filter": {"standstill": {"enabled": False}}})
    assert followed.position_error[-1] > 0.4 and standing_only.position_error[-1] > 0.4
    assert held.position_error.max() < 0.25 and held.position_error[-1] < 0.05
    heading_error = math.remainder(held.estimate[-1, 2] - drive.truth[-1, 2], 2 * math.pi)
    assert abs(heading_error) < math.radians(1.0)


def test_slip_shares_are_checked() -> None:
    with pytest.raises(ValueError, match="shares"):
        StandstillParams(shares=(0.25, 0.5))  # standing must be one
    with pytest.raises(ValueError, match="shares"):
        StandstillParams(shares=(0.0, 1.0))  # the odometry itself is not a share
    assert StandstillParams(shares=[0, 0.5]).shares == (0.0, 0.5)
