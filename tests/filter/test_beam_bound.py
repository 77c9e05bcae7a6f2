"""The bound on each beam's say, decided over the cloud (`mcl.filter.beam_bound`): the kernel
against a plain numpy reading of its rule, its invariants, and the sensor model's use of it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.beam_bound import bounded_scores
from mcl.filter.sensor_model import SensorModel, SensorModelParams, beam_table
from racecar_sim.raycast import RayCaster
from racecar_sim.settings.config import LidarParams

LIDAR = LidarParams()
POSE = np.array([6.0, 1.0, 0.3])  # rear axle, free in the room fixture (world frame)
TABLE = np.log(beam_table(SensorModelParams())) / 2.2  # the default squashed log table
PX_PER_M = 20.0


def _terms(expected: np.ndarray, z_px: np.ndarray) -> np.ndarray:
    """(N, K) table terms, the pixel rounding written out (half up, clipped to [0, 200])."""
    d = np.floor(np.clip(expected * PX_PER_M, 0.0, 200.0) + 0.5).astype(np.int64)
    return TABLE[z_px[None, :], d]


def _run(expected: np.ndarray, z_px: np.ndarray, bound: float) -> tuple[np.ndarray, np.ndarray]:
    """(plain sums, bounded sums) of the table terms."""
    terms = np.ascontiguousarray(_terms(expected, z_px))
    bounded = np.empty(expected.shape[0])
    bounded_scores(terms, bound, bounded)
    return terms.sum(axis=1), bounded


cases = st.tuples(st.integers(0, 2**32 - 1), st.integers(1, 50), st.integers(1, 30))


@settings(max_examples=60)
@given(case=cases, bound=st.floats(0.0, 5.0))
def test_each_beam_falls_at_most_bound_under_the_clouds_best(case, bound: float) -> None:
    seed, n, k = case
    rng = np.random.default_rng(seed)
    expected = rng.uniform(-0.5, 12.0, size=(n, k))
    z_px = rng.integers(0, 201, size=k)
    plain, bounded = _run(expected, z_px, bound)
    terms = _terms(expected, z_px)
    floor = terms.max(axis=0) - bound
    np.testing.assert_allclose(bounded, np.maximum(terms, floor).sum(axis=1), rtol=0, atol=1e-9)
    assert (bounded >= plain - 1e-9).all()
    # two particles differ by at most bound per beam
    assert bounded.max() - bounded.min() <= k * bound + 1e-9


@settings(max_examples=30)
@given(case=cases)
def test_no_bound_is_the_plain_sum_and_a_zero_bound_says_nothing(case) -> None:
    seed, n, k = case
    rng = np.random.default_rng(seed)
    expected = rng.uniform(0.0, 12.0, size=(n, k))
    z_px = rng.integers(0, 201, size=k)
    plain, unbounded = _run(expected, z_px, math.inf)
    np.testing.assert_allclose(unbounded, plain, rtol=0, atol=1e-9)
    _, silent = _run(expected, z_px, 0.0)
    np.testing.assert_allclose(silent, silent[0], rtol=0, atol=1e-9)


def test_a_beam_one_particle_explains_separates_them_by_the_bound_at_most() -> None:
    """Two particles; beam 0 ends on a wall for both (one a pixel off), beam 1 ends where
    particle 0 expects it and 2 m short of particle 1's wall (a chair the map lacks, or a
    wall the map draws too far): the plain model separates them by beam 1's full difference,
    the bound 0.5 by at most that (beam 0's small difference counts in full)."""
    expected = np.array([[5.0, 2.0], [5.05, 4.0]])
    z_px = np.array([100, 40])  # beam 1 measured 2 m
    _, bounded = _run(expected, z_px, 0.5)
    terms = _terms(expected, z_px)
    assert terms[0, 1] - terms[1, 1] > 1.0  # the plain model reads beam 1 as strong evidence
    assert abs(terms[0, 0] - terms[1, 0]) < 0.5
    np.testing.assert_allclose(bounded[0] - bounded[1], terms[0, 0] - terms[1, 0] + 0.5)


# ---------------------------------------------------------------------- the sensor model
def _true_scan(room, pose: np.ndarray) -> np.ndarray:
    x, y, th = pose
    mount = np.array([x + LIDAR.mount_offset * np.cos(th), y + LIDAR.mount_offset * np.sin(th), th])
    return RayCaster(room, LIDAR.max_range, method="exact").cast(mount, LIDAR.angles)[0]


@pytest.fixture(scope="module")
def bounded_and_plain(room) -> tuple[SensorModel, SensorModel]:
    base = SensorModelParams(mount_offset=LIDAR.mount_offset, parallel=False)  # no bound: default
    bounded = SensorModel(room, SensorModelParams(**{**base.__dict__, "beam_bound": 0.5}),
                          beam_angles=LIDAR.angles)  # fmt: skip
    return bounded, SensorModel(room, base, beam_angles=LIDAR.angles)


def test_weigh_bounds_only_a_tracking_cloud(room, bounded_and_plain) -> None:
    bounded, plain = bounded_and_plain
    rng = np.random.default_rng(3)
    particles = POSE + rng.standard_normal((200, 3)) * np.array([0.2, 0.2, 0.05])
    scan = _true_scan(room, POSE)
    scan[200:420] = np.maximum(scan[200:420] + 3.0, 0.0)  # a stretch seen through a wall
    own, weighing = bounded.weigh(particles, scan, searching=False)
    np.testing.assert_array_equal(own, plain.log_evaluate(particles, scan))
    assert not np.array_equal(weighing, own)
    n_beams = bounded.observe(scan)[1].size
    assert np.ptp(weighing) <= n_beams * bounded.params.beam_bound + 1e-9
    assert np.ptp(weighing) < np.ptp(own)
    # searching: the wide hit weighs, unbounded; the plain model never bounds
    _, weighing_s = bounded.weigh(particles, scan, searching=True)
    np.testing.assert_array_equal(weighing_s, bounded.log_evaluate(particles, scan, True))
    own_p, weighing_p = plain.weigh(particles, scan, searching=False)
    assert weighing_p is own_p


@pytest.mark.parametrize("value", [-0.1, math.nan, math.inf, True, "0.5"])
def test_a_bad_bound_is_refused_by_name(value) -> None:
    with pytest.raises(ValueError, match="beam_bound"):
        SensorModelParams(beam_bound=value)


def test_the_bound_and_beam_skipping_are_not_combined() -> None:
    with pytest.raises(ValueError, match=r"beam_bound.*beam_skip"):
        SensorModelParams(beam_bound=0.5, beam_skip=True)
    assert SensorModelParams(beam_bound=None, beam_skip=True).beam_skip
