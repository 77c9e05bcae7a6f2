"""Likelihood-field sensor model: scores by hand, the true pose above shifted ones, skipped beams."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.raycast import RayCaster
from racecar_sim.settings.config import LidarParams

LIDAR = LidarParams()
TRUTH = np.array([6.0, 0.0, 0.4])  # a free pose in the room map (world frame, rear axle)
LF = SensorModelParams(model="likelihood_field", num_beams_per_particle=1080, parallel=False)


@pytest.fixture(scope="module")
def model(room) -> SensorModel:
    return SensorModel(room, LF)


@pytest.fixture(scope="module")
def scan(room) -> np.ndarray:
    """Noise-free 1080-beam scan from the lidar of a car at TRUTH (exact caster)."""
    caster = RayCaster(room, LIDAR.max_range, method="exact")
    off = LIDAR.mount_offset
    lidar = TRUTH + off * np.array([math.cos(TRUTH[2]), math.sin(TRUTH[2]), 0.0])
    return caster.cast(lidar, LIDAR.angles)[0]


def test_known_pose_scores_above_shifted_poses(model, scan) -> None:
    shifts = np.array(
        [[dx, dy, 0.0] for dx in (-0.2, 0.0, 0.2) for dy in (-0.2, 0.0, 0.2) if dx or dy]
        + [[0.0, 0.0, -0.08], [0.0, 0.0, 0.08], [0.1, 0.0, 0.05]]
    )
    scores = model.log_evaluate(np.vstack([TRUTH, TRUTH + shifts]), scan)
    assert np.all(scores[0] > scores[1:])


def test_one_beam_by_hand(room) -> None:
    """log p of one end point = squash * log(z_hit exp(-d^2 / 2 sigma^2) + z_rand / max_range),
    d from the map's distance field at the end point (clipped)."""
    p = SensorModelParams(model="likelihood_field", mount_offset=0.0, parallel=False)
    m = SensorModel(room, p, beam_angles=np.array([0.3]))
    rng = np.random.default_rng(1)
    poses = room.sample_free_poses(rng, 40, clearance=0.1)
    z = 1.7
    got = m.log_evaluate(poses, np.array([z]))
    ends = poses[:, :2] + z * np.column_stack(
        [np.cos(poses[:, 2] + 0.3), np.sin(poses[:, 2] + 0.3)]
    )
    d = np.minimum(room.distance_at(ends), p.likelihood_max_distance)
    inside = room.in_bounds(room.world_to_grid(ends))
    d[~inside] = p.likelihood_max_distance
    pz = p.likelihood_z_hit * np.exp(-0.5 * (d / p.likelihood_sigma) ** 2)
    floor = p.likelihood_z_rand / p.likelihood_max_range
    want = p.squash_exponent * np.log(pz + floor)
    # The table stores log p in 65 536 steps between its extremes: half a step of rounding.
    half_step = 0.5 * (math.log(p.likelihood_z_hit + floor) - math.log(floor)) / 65535
    np.testing.assert_allclose(got, want, rtol=0, atol=p.squash_exponent * half_step * 1.001)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.integers(0, 1079), min_size=1, max_size=200))
def test_max_range_and_nan_beams_are_skipped(model, scan, lost: list[int]) -> None:
    rng = np.random.default_rng(len(lost))
    particles = TRUTH + rng.normal(0.0, [0.2, 0.2, 0.05], size=(30, 3))
    damaged = scan.copy()
    damaged[lost[: len(lost) // 2]] = LIDAR.max_range
    damaged[lost[len(lost) // 2 :]] = np.nan
    keep = np.ones(scan.size, dtype=bool)
    keep[lost] = False
    keep &= scan < LIDAR.max_range
    subset = SensorModel(model.map, LF, beam_angles=LIDAR.angles[keep])
    np.testing.assert_allclose(
        model.log_evaluate(particles, damaged),
        subset.log_evaluate(particles, scan[keep]),
        rtol=1e-12,
    )


def test_all_beams_lost_scores_zero(model) -> None:
    scores = model.log_evaluate(np.tile(TRUTH, (3, 1)), np.full(1080, LIDAR.max_range))
    np.testing.assert_array_equal(scores, 0.0)


def test_parallel_equals_serial(room, scan) -> None:
    rng = np.random.default_rng(2)
    particles = room.sample_free_poses(rng, 500, clearance=0.0)
    threads = SensorModel(room, SensorModelParams(**{**LF.__dict__, "parallel": True}))
    np.testing.assert_allclose(
        SensorModel(room, LF).log_evaluate(particles, scan), threads.log_evaluate(particles, scan)
    )


def test_casts_nothing(model) -> None:
    assert model.caster is None
    with pytest.raises(ValueError, match="casts no rays"):
        model.expected_ranges(np.zeros((1, 3)), np.zeros(3))


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("model", "likelihood"),
        ("likelihood_sigma", 0.0),
        ("likelihood_z_hit", -1.0),
        ("likelihood_z_rand", -0.1),
        ("likelihood_max_range", math.inf),
    ],
)
def test_bad_parameters_name_the_field(field: str, value) -> None:
    with pytest.raises(ValueError, match=f"SensorModelParams.{field}"):
        SensorModelParams(**{field: value})
