"""The lut caster's one-pass cast-and-score equals casting, then scoring, number for number (but
for a beam whose expected range lies exactly on a half pixel)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.raycast import RayCaster
from racecar_sim.settings.config import LidarParams

LIDAR = LidarParams()


@pytest.fixture(scope="module")
def lut_model(room) -> SensorModel:
    return SensorModel(room, SensorModelParams(raycast_method="lut", parallel=False))


def _scan(room, pose: np.ndarray) -> np.ndarray:
    return RayCaster(room, LIDAR.max_range, method="exact").cast(pose, LIDAR.angles)[0]


def _particles(room, rng: np.random.Generator, n: int) -> np.ndarray:
    """Poses over the whole map and beyond it: free, occupied and off-map positions."""
    (w, h) = room.extent
    lo = np.array([room.origin[0] - 1.0, room.origin[1] - 1.0, -np.pi])
    hi = np.array([room.origin[0] + w + 1.0, room.origin[1] + h + 1.0, np.pi])
    return rng.uniform(lo, hi, size=(n, 3))


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 300))
@example(seed=118399, n=112)  # one beam on a half pixel (CI, 2026-12-03)
def test_fused_equals_cast_then_score(room, lut_model, seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    particles = _particles(room, rng, n)
    scan = _scan(room, room.sample_free_poses(rng, 1, clearance=0.3)[0])
    angles, z_px = lut_model.observe(scan)
    expected = lut_model.expected_ranges(particles, angles)
    two_pass = lut_model.score(expected, z_px)
    fused = lut_model.log_evaluate(particles, scan)
    # number for number, but for a beam whose expected range falls on a half pixel exactly (5.425 m
    # at 0.05 m per pixel): the fused kernel scales it in another order (fast-math), and one ulp
    # rounds it to the neighbouring table column (seed 118399, n 112: one beam, 0.004 of 300)
    px = expected / lut_model.m_per_px
    on_a_tie = (np.abs(px - np.floor(px) - 0.5) < 1e-9).any(axis=1)
    np.testing.assert_array_equal(fused[~on_a_tie], two_pass[~on_a_tie])
    np.testing.assert_allclose(fused[on_a_tie], two_pass[on_a_tie], rtol=0, atol=0.1)


def test_fused_parallel_equals_serial(room) -> None:
    rng = np.random.default_rng(3)
    particles = _particles(room, rng, 2000)
    scan = _scan(room, room.sample_free_poses(rng, 1, clearance=0.3)[0])
    serial = SensorModel(room, SensorModelParams(parallel=False)).log_evaluate(particles, scan)
    threads = SensorModel(room, SensorModelParams(parallel=True)).log_evaluate(particles, scan)
    np.testing.assert_array_equal(serial, threads)


def test_cast_score_exact_method_matches_table_lookup(room) -> None:
    """The other methods' cast_score (cast, then look up) agrees with a hand-written lookup."""
    rng = np.random.default_rng(5)
    caster = RayCaster(room, 10.0, method="exact")
    poses = room.sample_free_poses(rng, 50, clearance=0.2)
    angles = np.linspace(-2.0, 2.0, 7)
    rows = rng.normal(size=(7, 41))
    ranges = caster.cast(poses, angles)
    cols = np.floor(np.clip(ranges * 4.0, 0, 40) + 0.5).astype(int)
    by_hand = np.array([sum(rows[b, cols[i, b]] for b in range(7)) for i in range(50)])
    np.testing.assert_allclose(caster.cast_score(poses, angles, rows, 4.0), by_hand)
    lut = RayCaster(room, 10.0, method="lut")
    lut_ranges = lut.cast(poses, angles)
    lut_cols = np.floor(np.clip(lut_ranges * 4.0, 0, 40) + 0.5).astype(int)
    lut_hand = np.array([sum(rows[b, lut_cols[i, b]] for b in range(7)) for i in range(50)])
    np.testing.assert_array_equal(lut.cast_score(poses, angles, rows, 4.0), lut_hand)


@pytest.mark.parametrize("method", ["lut", "exact"])
@pytest.mark.parametrize("sort_extent", [10.0, 0.0])  # 0: the lut casts in Z-order, scatters back
def test_cast_score_terms_are_each_ray_s_lookup(room, method: str, sort_extent: float) -> None:
    """The per-ray terms (what the beam bound reads) are each ray's table lookup by hand, in the
    caller's pose order, and sum to the scores; off-map and in-wall poses included."""
    from racecar_sim.raycast import LutParams

    rng = np.random.default_rng(11)
    caster = RayCaster(room, 10.0, method=method, lut=LutParams(sort_extent=sort_extent))
    poses = _particles(room, rng, 120)
    angles = np.linspace(-2.0, 2.0, 7)
    rows = rng.normal(size=(7, 41))
    terms = np.full((120, 7), np.nan)
    scores = caster.cast_score(poses, angles, rows, 4.0, terms=terms)
    cols = np.floor(np.clip(caster.cast(poses, angles) * 4.0, 0, 40) + 0.5).astype(int)
    np.testing.assert_array_equal(terms, rows[np.arange(7)[None, :], cols])
    np.testing.assert_allclose(terms.sum(axis=1), scores, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="terms must be"):
        caster.cast_score(poses, angles, rows, 4.0, terms=np.empty((120, 6)))


@pytest.mark.parametrize("method", ["lut", "exact"])
def test_cast_score_rejects_bad_input(room, method: str) -> None:
    caster = RayCaster(room, 10.0, method=method)
    with pytest.raises(ValueError, match="rows must have shape"):
        caster.cast_score(np.zeros(3), np.zeros(4), np.zeros((3, 10)), 1.0)
    with pytest.raises(ValueError, match="poses must have shape"):
        caster.cast_score(np.zeros((5, 2)), np.zeros(4), np.zeros((4, 10)), 1.0)
    with pytest.raises(ValueError, match="offset"):
        caster.cast_score(np.zeros((5, 3)), np.zeros(4), np.zeros((4, 10)), 1.0, offset=np.nan)


def test_cast_score_offset_is_a_cast_from_the_point_ahead(room) -> None:
    """Both paths: scoring with a mount offset equals scoring poses moved that far ahead."""
    rng = np.random.default_rng(8)
    poses = room.sample_free_poses(rng, 40, clearance=0.5)
    ahead = poses + np.column_stack(
        [0.3 * np.cos(poses[:, 2]), 0.3 * np.sin(poses[:, 2]), 0 * poses[:, 2]]
    )
    angles = np.linspace(-2.0, 2.0, 9)
    rows = rng.normal(size=(9, 41))
    for method in ("exact", "lut"):
        caster = RayCaster(room, 10.0, method=method)
        np.testing.assert_allclose(
            caster.cast_score(poses, angles, rows, 4.0, offset=0.3),
            caster.cast_score(ahead, angles, rows, 4.0),
            rtol=0, atol=1e-9,
        )  # fmt: skip


@pytest.mark.slow
def test_fused_lut_scores_match_exact_on_stata(stata_map) -> None:
    """On the full Stata basement, the fast path's ranges (what it scores) stay within the lut's
    stated error of the exact caster (p99 0.056 m, mean 0.008 m in the README; bounds with
    margin), for a converged cloud and for poses over the whole map."""
    rng = np.random.default_rng(11)
    model = SensorModel(stata_map, SensorModelParams(parallel=False))
    exact = RayCaster(stata_map, model.max_range, method="exact")
    truth = stata_map.sample_free_poses(rng, 1, clearance=1.0)[0]
    cloud = truth + rng.normal(0.0, [0.3, 0.3, 0.1], size=(1500, 3))
    uniform = stata_map.sample_free_poses(rng, 1500, clearance=0.0)
    angles = np.linspace(-np.pi, np.pi, 100, endpoint=False)
    for poses in (cloud, uniform):
        err = np.abs(
            model.expected_ranges(poses, angles) - exact.cast(model.lidar_poses(poses), angles)
        )
        assert np.quantile(err, 0.99) <= 0.065
        assert err.mean() <= 0.015
        # and the one-pass scores are those of these ranges
        rows = rng.normal(size=(angles.size, model.z_max + 1))
        lidar = model.lidar_poses(poses)
        ranges = model.caster.cast(lidar, angles)
        cols = np.floor(np.clip(ranges / model.m_per_px, 0, model.z_max) + 0.5).astype(int)
        want = rows[np.arange(angles.size)[None, :], cols].sum(axis=1)
        np.testing.assert_allclose(
            # a different column would be off by O(1); sums of 100 terms differ in order by ~1e-14
            model.caster.cast_score(lidar, angles, rows, 1.0 / model.m_per_px),
            want,
            rtol=1e-12,
            atol=1e-9,
        )
