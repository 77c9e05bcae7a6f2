"""The car's turn measured by matching its scans to each other (mcl.filter.scan_turn.match_turn),
and the turn check that turns a cloud whose estimate did not turn with the car (TurnCheck)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.motion_model import twist_to_odometry
from mcl.filter.params import ParticleFilterParams
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.scan_continuity import compose
from mcl.filter.scan_turn import TurnCheck, TurnCheckParams, match_turn
from tests.filter.loop_scans import DT, ENV, LIDAR, MAX_RANGE, MOUNT, free_pose

P = TurnCheckParams()


def _drive(start: np.ndarray, twist: np.ndarray, steps: int) -> np.ndarray:
    end = start
    for _ in range(steps):
        end = compose(end, twist_to_odometry(twist, DT))
    return end


def _match(seed: int, omega: float, odometry_turn_error: float, forward_share: float = 1.0):
    """Two exact scans a quarter of a second apart; the odometry turns ``odometry_turn_error``
    radians more than the car did, and reads ``1 / forward_share`` of its forward travel."""
    start = free_pose(seed)
    twist = np.array([1.2, 0.0, omega])
    end = _drive(start, twist, 10)
    odometry = np.array(twist_to_odometry(twist / [forward_share, 1.0, 1.0], 10 * DT))
    odometry[2] += odometry_turn_error
    idx = np.unique(np.rint(np.linspace(0, LIDAR.angles.size - 1, P.beams)).astype(np.int64))
    turn, score = match_turn(
        LIDAR.true_ranges(start)[idx], LIDAR.angles[idx], LIDAR.true_ranges(end), LIDAR.angles,
        odometry, MOUNT, MAX_RANGE, P.turn_range, P.lateral, P.tolerance, P.tolerance_per_m,
    )  # fmt: skip
    true_turn = float(np.arctan2(np.sin(end[2] - start[2]), np.cos(end[2] - start[2])))
    return turn, score, true_turn


def test_two_scans_tell_the_turn_the_odometry_has_wrong() -> None:
    """20 places of the bundled loop, the car turning at 1 rad/s, the odometry's turn 0.3 rad too
    large: the matched turn is the car's within 0.01 rad in most places."""
    errors = []
    for seed in range(20):
        turn, score, truth = _match(seed, 1.0, 0.3)
        if math.isfinite(turn):
            assert 0.0 <= score <= 1.0
            errors.append(abs(turn - truth))
    assert len(errors) >= 15
    assert np.mean(np.array(errors) <= 0.01) >= 0.8


def test_a_pinned_car_turns_as_its_scans_say() -> None:
    """The car stands while its wheels report 1 m/s and a 0.35 rad turn: matched with the
    forward share 0, the turn is the car's (0) within 0.01 rad."""
    start = free_pose(3)
    odometry = np.array(twist_to_odometry(np.array([1.0, 0.0, 1.4]), 10 * DT))
    idx = np.unique(np.rint(np.linspace(0, LIDAR.angles.size - 1, P.beams)).astype(np.int64))
    scan = LIDAR.true_ranges(start)
    turn, score = match_turn(scan[idx], LIDAR.angles[idx], scan, LIDAR.angles, odometry, MOUNT,
                             MAX_RANGE, P.turn_range, P.lateral, P.tolerance, P.tolerance_per_m)  # fmt: skip
    assert abs(turn) <= 0.01 and score >= 0.9


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.floats(-1.5, 1.5), st.floats(-0.45, 0.45), st.floats(0.85, 1.15))
def test_the_match_is_a_turn_within_the_range_or_nothing(seed, omega, error, share) -> None:
    """Whatever the place, the turn, the odometry's turn error and its forward reading: a turn
    within ``turn_range`` (plus the fine grid's reach) of the odometry's with a score in [0, 1],
    or NaNs; a counted match (score at least ``min_score``) is the car's turn within 0.05 rad
    wherever the scans see enough walls to tell it."""
    turn, score, truth = _match(seed, omega, error, share)
    if math.isnan(turn):
        assert math.isnan(score)
        return
    odometry_turn = omega * 10 * DT + error
    assert abs(turn - odometry_turn) <= P.turn_range + 0.03
    assert 0.0 <= score <= 1.0
    if score >= P.min_score:
        assert abs(turn - truth) <= 0.05


def _feed(check: TurnCheck, twist: np.ndarray, seconds: float, car: np.ndarray,
          true_turn_rate: float, estimate_heading: float, estimate_rate: float):  # fmt: skip
    """Drive ``check`` for ``seconds``: the car turns at ``true_turn_rate`` (exact scans, 40 a
    second), the odometry reads ``twist``, the estimate turns at ``estimate_rate``; returns the
    corrections asked for, the car's pose and the estimate's heading at the end."""
    idx_angles = LIDAR.angles
    corrections = []
    for _ in range(int(round(seconds / DT))):
        car = compose(car, twist_to_odometry(np.array([0.0, 0.0, true_turn_rate]), DT))
        check.advance(twist, DT)
        estimate_heading += estimate_rate * DT
        if check.due():
            turn = check.observe(LIDAR.true_ranges(car), idx_angles, MOUNT, MAX_RANGE, estimate_heading)
            if turn != 0.0:
                corrections.append(turn)
                estimate_heading += turn
        else:
            check.skip_scan()
    return corrections, car, estimate_heading


@pytest.mark.parametrize("seed", [0, 5])
def test_an_estimate_that_did_not_turn_is_turned_by_what_the_scans_saw(seed) -> None:
    """The car turns in place at 0.8 rad/s for 3 s, its odometry says so (10 % high), the
    estimate stays put: the check asks once for the turn the estimate missed (within 0.1 rad of
    the car's turn over the window), and the estimate ends within 0.2 rad of the car."""
    check = TurnCheck()
    car = free_pose(seed)
    corrections, car, heading = _feed(check, np.array([0.0, 0.0, 0.88]), 3.0, car, 0.8, 0.0, 0.0)
    assert corrections, "no correction asked"
    assert abs(corrections[0] - 0.8 * P.window_s) <= 0.4
    turned_by_car = 0.8 * 3.0
    assert abs(heading - turned_by_car) <= 0.2 + 0.8 * (3.0 - P.window_s)


def test_an_estimate_that_turns_with_the_car_is_left_alone() -> None:
    """The same turn, the estimate turning with the car: no correction."""
    check = TurnCheck()
    corrections, _, _ = _feed(check, np.array([0.0, 0.0, 0.88]), 4.0, free_pose(0), 0.8, 0.0, 0.8)
    assert corrections == [] and check.counted > 5


def test_an_estimate_turned_once_and_then_turning_with_the_car_is_turned_once() -> None:
    """The estimate misses 2 s of the car's turn, is turned, then turns with the car: one
    correction, not a second one that takes the first back (the keyframe after a correction
    holds the heading the cloud was given). What stays missed is the turn before the first full
    window (the first keyframe's quarter second and the window's slack: 0.4 rad here)."""
    check = TurnCheck()
    car = free_pose(0)
    corrections, car, heading = _feed(check, np.array([0.0, 0.0, 0.88]), 2.5, car, 0.8, 0.0, 0.0)
    assert len(corrections) == 1
    more, car, heading = _feed(check, np.array([0.0, 0.0, 0.88]), 4.0, car, 0.8, heading, 0.8)
    assert more == []
    assert abs(_wrapped(heading - (car[2] - free_pose(0)[2]))) <= 0.45


def test_an_estimate_that_mends_its_own_heading_is_left_alone() -> None:
    """The car drives straight; the estimate starts 0.6 rad off and turns back within half a
    second (its scans mending it): that is no missed turn, and nothing is corrected."""
    check = TurnCheck()
    car = free_pose(0)
    corrections, car, heading = _feed(check, np.zeros(3), 1.0, car, 0.0, 0.6, 0.0)
    more, _, _ = _feed(check, np.zeros(3), 0.5, car, 0.0, heading, -1.2)
    rest, _, _ = _feed(check, np.zeros(3), 3.0, car, 0.0, heading - 0.6, 0.0)
    assert corrections == more == rest == []


def test_a_keyframe_that_cannot_be_matched_does_not_restart_the_window() -> None:
    """The same missed turn with one keyframe's scan blank (no returns: nothing to match) 1.25 s
    in: the window judges the keyframes that matched, so the correction still comes within
    2.5 s (a window started again after the blank one would not be full before 3 s)."""
    check = TurnCheck()
    car = free_pose(0)
    twist = np.array([0.0, 0.0, 0.88])
    blank = np.full(LIDAR.angles.size, MAX_RANGE)
    corrections = []
    for step in range(100):  # 2.5 s
        car = compose(car, twist_to_odometry(np.array([0.0, 0.0, 0.8]), DT))
        check.advance(twist, DT)
        if check.due():
            scan = blank if 48 <= step < 52 else LIDAR.true_ranges(car)
            if turn := check.observe(scan, LIDAR.angles, MOUNT, MAX_RANGE, 0.0):
                corrections.append(turn)
        else:
            check.skip_scan()
    assert check.matches - check.counted >= 1
    assert corrections, "the blank keyframe delayed the correction past 2.5 s"


def test_wheels_that_turn_a_pinned_car_do_not_turn_the_estimate() -> None:
    """The car stands, its wheels report a turn at 0.8 rad/s, the estimate (held by its scans)
    stays: the scans and the odometry disagree, so nothing is corrected."""
    check = TurnCheck()
    corrections, _, _ = _feed(check, np.array([0.0, 0.0, 0.8]), 4.0, free_pose(0), 0.0, 0.0, 0.0)
    assert corrections == []


def test_the_filter_turns_its_cloud_when_the_check_says_so() -> None:
    """The car turns in place and its odometry says so, but the cloud is put back unturned after
    every predict (as an old map's pull would hold it): by 2 s it lies 1.6 rad behind the car,
    and the filter's own turn check turns it, its estimate then within 0.25 rad of the car."""
    pose = free_pose(0)
    pf = ParticleFilter(ENV.map, n_particles=300, params=ParticleFilterParams(), rng=1)
    pf.initialize(pose, spread=(0.02, 0.02, 0.01))
    twist = np.array([0.0, 0.0, 0.8])
    car, errors = pose, []
    for _ in range(120):  # 3 s turning in place
        car = compose(car, twist_to_odometry(twist, DT))
        before = pf.particles.copy()
        pf.predict(twist, DT)
        pf.set_particles(before, pf.weights)  # the old map's pull: the cloud does not turn
        corrections = pf.turn_check.corrections
        pf.correct(LIDAR.true_ranges(car))
        if pf.turn_check.corrections > corrections:
            errors.append((abs(_wrapped(before[:, 2].mean() - car[2])),
                           abs(_wrapped(pf.estimate()[2] - car[2]))))  # fmt: skip
    assert errors, "the check never turned the cloud"
    missed, left = errors[0]
    assert missed >= 1.0 and left <= 0.25


def _wrapped(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


def test_settings_refuse_nonsense() -> None:
    with pytest.raises(ValueError, match=r"TurnCheckParams\.bound"):
        TurnCheckParams(bound=0.0)
    with pytest.raises(ValueError, match=r"TurnCheckParams\.keyframe_scans"):
        TurnCheckParams(keyframe_scans=0)
    with pytest.raises(ValueError, match=r"TurnCheckParams\.min_score"):
        TurnCheckParams(min_score=1.5)
