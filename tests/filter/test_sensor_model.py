"""Sensor model: the beam table by hand, scan treatment, particle scoring, mount offset."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.sensor_model import SensorModel, SensorModelParams, beam_table
from racecar_sim.raycast import RayCaster
from racecar_sim.settings.config import LidarParams, from_mapping, from_yaml

P = SensorModelParams()
LIDAR = LidarParams()
TRUTH = np.array([6.0, 0.0, 0.4])  # a free pose in the room map (world frame, rear axle)


@pytest.fixture(scope="module")
def model(room) -> SensorModel:
    # The exact caster keeps these tests about the model, not about an approximate caster.
    return SensorModel(room, SensorModelParams(raycast_method="exact"))


@pytest.fixture(scope="module")
def scan(room, mount_pose) -> np.ndarray:
    """Noise-free 1080-beam scan from the lidar of a car at TRUTH (exact caster, 10 m)."""
    caster = RayCaster(room, LIDAR.max_range, method="exact")
    return caster.cast(mount_pose(TRUTH, LIDAR.mount_offset), LIDAR.angles)[0]


# ---------------------------------------------------------------------------------- table
def _column_sum(p: SensorModelParams, d: int) -> float:
    """Sum over z of the unnormalised mixture in column d, by hand.

    p_hit sums to 1; sum_{z=0..d} (2/d)(1 - z/d) = 2(d+1)/d - (d+1)/d = (d+1)/d;
    p_max sums to 1; p_rand sums to (z_max + 1) / z_max.
    """
    z_max = p.table_width - 1
    short = (d + 1) / d if d > 0 else 0.0
    return p.alpha_hit + p.alpha_short * short + p.alpha_max + p.alpha_rand * (z_max + 1) / z_max


def test_table_shape_and_columns_sum_to_one() -> None:
    t = beam_table(P)
    assert t.shape == (201, 201)
    np.testing.assert_allclose(t.sum(axis=0), 1.0, atol=1e-12)
    assert np.all(t > 0)


def test_table_zmax_row_by_hand() -> None:
    t = beam_table(P)
    z_max, s = 200, P.sigma_hit
    for d in (0, 1, 50, 199, 200):
        g = np.exp(-0.5 * ((np.arange(201) - d) / s) ** 2)
        hit = g[z_max] / g.sum()
        # p_short(z_max, d) = 0 for every d: z_max > d, or z = d where (1 - z/d) = 0.
        expected = (P.alpha_hit * hit + P.alpha_max * 1.0 + P.alpha_rand / z_max) / _column_sum(
            P, d
        )
        assert t[z_max, d] == pytest.approx(expected, rel=1e-12)


def test_table_d0_column_by_hand() -> None:
    t = beam_table(P)
    z = np.arange(201)
    g = np.exp(-0.5 * (z / P.sigma_hit) ** 2)
    expected = P.alpha_hit * g / g.sum() + P.alpha_rand / 200 + P.alpha_max * (z == 200)
    np.testing.assert_allclose(t[:, 0], expected / _column_sum(P, 0), rtol=1e-12)


def test_tiny_table_by_hand() -> None:
    # width 3 (z_max = 2), only short and random returns, alpha 1/2 each.
    p = SensorModelParams(
        alpha_hit=0.0, alpha_short=0.5, alpha_max=0.0, alpha_rand=0.5, table_width=3
    )
    t = beam_table(p)
    # d = 2: short [1, 1/2, 0], rand [1/2] * 3 -> mix [3/4, 1/2, 1/4] / (3/2)
    np.testing.assert_allclose(t[:, 2], [1 / 2, 1 / 3, 1 / 6])
    # d = 1: short [2, 0, 0] -> mix [5/4, 1/4, 1/4] / (7/4)
    np.testing.assert_allclose(t[:, 1], [5 / 7, 1 / 7, 1 / 7])
    # d = 0: no short returns, random only
    np.testing.assert_allclose(t[:, 0], [1 / 3, 1 / 3, 1 / 3])


@settings(max_examples=25, deadline=None)
@given(
    st.floats(0, 1),
    st.floats(0, 1),
    st.floats(0, 1),
    st.floats(0.01, 1),
    st.floats(0.5, 30),
    st.integers(2, 120),
)
def test_table_columns_sum_to_one_for_any_mixture(h, s, m, r, sigma, width) -> None:
    p = SensorModelParams(
        alpha_hit=h, alpha_short=s, alpha_max=m, alpha_rand=r, sigma_hit=sigma, table_width=width
    )
    t = beam_table(p)
    np.testing.assert_allclose(t.sum(axis=0), 1.0, atol=1e-12)
    assert np.all(t > 0)
    assert np.all(t[:, 0] == t[0, 0]) or h > 0 or m > 0  # d = 0 without hit/max: flat


def test_hit_peak_on_the_diagonal() -> None:
    t = beam_table(SensorModelParams(alpha_short=0.0, alpha_max=0.0))
    for d in (10, 100, 190):
        assert np.argmax(t[:, d]) == d


# ---------------------------------------------------------------------------------- scoring
def test_true_pose_outweighs_displaced_poses(model: SensorModel, scan: np.ndarray) -> None:
    displaced = TRUTH + np.array(
        [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, -0.3, 0.0], [0.0, 0.0, 0.15], [0.1, 0.1, -0.05]]
    )
    ll = model.log_evaluate(displaced, scan)
    assert np.argmax(ll) == 0
    assert np.all(ll[1:] < ll[0] - 1.0)
    lik = model.evaluate(displaced, scan)
    np.testing.assert_allclose(lik, np.exp(ll))
    assert np.argmax(lik) == 0


def test_log_likelihood_matches_a_plain_numpy_sum(
    room, model: SensorModel, scan, mount_pose
) -> None:
    rng = np.random.default_rng(5)
    particles = TRUTH + rng.normal(0.0, [0.3, 0.3, 0.2], size=(64, 3))
    idx = np.round(np.linspace(0, 1079, 100)).astype(int)
    angles = LIDAR.angles[idx]
    mounts = np.array([mount_pose(p, LIDAR.mount_offset) for p in particles])
    expected = RayCaster(room, 200 * room.resolution, method="exact").cast(mounts, angles)
    to_px = 1.0 / room.resolution
    d = np.floor(np.clip(expected * to_px, 0, 200) + 0.5).astype(int)
    z = np.floor(np.clip(scan[idx] * to_px, 0, 200) + 0.5).astype(int)
    manual = np.log(np.prod(beam_table(P)[z[None, :], d], axis=1) ** P.squash_exponent)
    np.testing.assert_allclose(model.log_evaluate(particles, scan), manual, rtol=1e-9)


def test_mount_offset_moves_the_best_pose(room, scan: np.ndarray) -> None:
    # The scan came from 0.275 m ahead of TRUTH. A model that knows the offset prefers TRUTH; one
    # that casts from the rear axle prefers the pose whose rear axle sits where the lidar was.
    forward = TRUTH + LIDAR.mount_offset * np.array([math.cos(TRUTH[2]), math.sin(TRUTH[2]), 0.0])
    candidates = np.stack([TRUTH, forward])
    with_offset = SensorModel(room, SensorModelParams(raycast_method="exact"))
    without = SensorModel(room, SensorModelParams(raycast_method="exact", mount_offset=0.0))
    assert np.argmax(with_offset.log_evaluate(candidates, scan)) == 0
    assert np.argmax(without.log_evaluate(candidates, scan)) == 1


def test_log_space_keeps_order_where_products_underflow(room) -> None:
    p = SensorModelParams(raycast_method="exact", num_beams_per_particle=1000, squash_exponent=1.0)
    m = SensorModel(room, p)
    bad_scan = np.zeros(1000)  # every beam says 0 m: very unlikely from any free pose
    poses = np.array([[6.0, 0.0, 0.4], [2.5, 0.3, 0.0]])
    ll = m.log_evaluate(poses, bad_scan)
    assert np.all(np.isfinite(ll)) and np.all(ll < -745)  # exp() of these is 0.0 in float64
    assert np.all(m.evaluate(poses, bad_scan) == 0.0)
    assert ll[0] != ll[1]


def test_downsampling_picks_evenly_spaced_beams(model: SensorModel) -> None:
    angles, z = model.observe(np.full(1080, 2.0))
    assert angles.shape == z.shape == (100,)
    assert angles[0] == pytest.approx(-LIDAR.fov / 2)
    assert angles[-1] == pytest.approx(LIDAR.fov / 2)
    # 1079 gaps shared by 99 intervals: every interval is 10 or 11 beam gaps (evenly spaced)
    gaps = np.diff(angles) / (LIDAR.fov / 1079)
    np.testing.assert_allclose(gaps, np.round(gaps), atol=1e-9)
    assert set(np.round(gaps).astype(int)) == {10, 11}
    assert np.all(z == round(2.0 / 0.05))
    few, _ = model.observe(np.full(30, 2.0))  # fewer beams than asked: all of them
    assert few.shape == (30,)


def test_ranges_to_pixels_clip_and_round(model: SensorModel) -> None:
    _, z = model.observe(np.array([0.0, 0.012, 0.013, 0.051, 9.99, 10.0, 25.0]))
    # 0.05 m per pixel: 0.24 -> 0, 0.26 -> 1, 1.02 -> 1, 199.8 -> 200, beyond z_max -> 200
    np.testing.assert_array_equal(z, [0, 0, 0, 1, 200, 200, 200])
    assert model.max_range == pytest.approx(200 * 0.05)


def test_lidar_scale_divides_ranges(room) -> None:
    m = SensorModel(room, SensorModelParams(raycast_method="exact", lidar_scale_to_map_scale=2.0))
    _, z = m.observe(np.array([1.0, 4.0]))
    np.testing.assert_array_equal(z, [10, 40])
    assert m.max_range == pytest.approx(200 * 0.05 * 2.0)


def test_nan_and_inf_beams_are_dropped(model: SensorModel, scan: np.ndarray) -> None:
    particles = TRUTH + np.random.default_rng(2).normal(0.0, 0.2, size=(20, 3))
    idx = np.round(np.linspace(0, 1079, 100)).astype(int)
    bad = scan.copy()
    bad[idx[[3, 40]]] = np.nan
    bad[idx[70]] = np.inf
    keep = np.setdiff1d(np.arange(100), [3, 40, 70])
    angles, z = model.observe(bad)
    assert angles.shape == (97,)
    full_angles, full_z = model.observe(scan)
    np.testing.assert_array_equal(angles, full_angles[keep])
    np.testing.assert_array_equal(z, full_z[keep])
    expected = model.score(model.expected_ranges(particles, full_angles[keep]), full_z[keep])
    ll = model.log_evaluate(particles, bad)
    assert np.all(np.isfinite(ll))
    np.testing.assert_allclose(ll, expected)
    everything_bad = np.full(1080, np.nan)
    np.testing.assert_array_equal(model.log_evaluate(particles, everything_bad), 0.0)


def test_bad_scans_raise(room, model: SensorModel) -> None:
    particles = TRUTH[None, :]
    with pytest.raises(ValueError, match="negative"):
        model.log_evaluate(particles, np.array([1.0, -0.5, 2.0]))
    with pytest.raises(ValueError, match="1-D"):
        model.log_evaluate(particles, np.ones((2, 540)))
    with pytest.raises(ValueError, match="1-D"):
        model.log_evaluate(particles, np.array([]))
    fixed = SensorModel(room, SensorModelParams(raycast_method="exact"), beam_angles=LIDAR.angles)
    with pytest.raises(ValueError, match="1080 beam angles"):
        fixed.log_evaluate(particles, np.ones(1000))
    with pytest.raises(ValueError, match="particles"):
        model.log_evaluate(np.zeros((3, 2)), np.ones(1080))


def test_given_beam_angles_are_used(room, scan: np.ndarray) -> None:
    reversed_angles = SensorModel(
        room, SensorModelParams(raycast_method="exact"), beam_angles=-LIDAR.angles
    )
    normal = SensorModel(room, SensorModelParams(raycast_method="exact"), beam_angles=LIDAR.angles)
    poses = TRUTH[None, :]
    assert normal.log_evaluate(poses, scan)[0] > reversed_angles.log_evaluate(poses, scan)[0] + 1.0


def test_default_method_is_the_lookup_table(room) -> None:
    assert SensorModel(room).caster.method == "lut"
    with pytest.raises(ValueError, match="method"):
        SensorModel(room, SensorModelParams(raycast_method="magic"))


def test_params_validation_and_yaml(tmp_path) -> None:
    assert P.z_max == 200
    with pytest.raises(ValueError, match="sigma_hit"):
        SensorModelParams(sigma_hit=0.0)
    with pytest.raises(ValueError, match="alpha_short"):
        SensorModelParams(alpha_short=-0.1)
    with pytest.raises(ValueError, match="table_width"):
        SensorModelParams(table_width=1)
    with pytest.raises(ValueError, match="num_beams_per_particle"):
        SensorModelParams(num_beams_per_particle=2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="parallel"):
        SensorModelParams(parallel="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="must not all be zero"):
        SensorModelParams(alpha_hit=0.0, alpha_max=0.0, alpha_rand=0.0)
    assert from_mapping(SensorModelParams, {"sigma_hit": 4.0}).sigma_hit == 4.0
    path = tmp_path / "mcl.yaml"
    path.write_text("sensor_model:\n  num_beams_per_particle: 60\n  raycast_method: exact\n")
    p = from_yaml(SensorModelParams, path, section="sensor_model")
    assert p.num_beams_per_particle == 60 and p.raycast_method == "exact"


def test_parallel_and_serial_scoring_agree(room, model: SensorModel) -> None:
    from mcl.filter.sensor_model import PARALLEL_MIN_LOOKUPS

    rng = np.random.default_rng(8)
    n = PARALLEL_MIN_LOOKUPS // 50 + 1
    expected = rng.uniform(-1.0, 12.0, size=(n, 50))  # out-of-range values get clipped
    z = rng.integers(0, 201, size=50)
    big = model.score(expected, z)  # one call over the threshold: parallel kernel
    parts = np.concatenate([model.score(expected[i : i + 1000], z) for i in range(0, n, 1000)])
    np.testing.assert_array_equal(big, parts)
    forced = SensorModel(room, SensorModelParams(raycast_method="exact", parallel=True))
    np.testing.assert_array_equal(forced.score(expected[:100], z), big[:100])
    single = SensorModel(room, SensorModelParams(raycast_method="exact", parallel=False))
    np.testing.assert_array_equal(single.score(expected, z), big)
    assert single.caster.parallel is False
    d = np.floor(np.clip(expected / 0.05, 0, 200) + 0.5).astype(int)
    manual = P.squash_exponent * np.log(beam_table(P))[z[None, :], d].sum(axis=1)
    np.testing.assert_allclose(big, manual, rtol=1e-9)


def test_max_range_in_metres_scales_the_table(room):
    lab = SensorModel(room, SensorModelParams(raycast_method="exact"))
    assert lab.max_range == pytest.approx(200 * room.resolution)  # z_max cells of the map
    long = SensorModel(room, SensorModelParams(max_range=30.0, raycast_method="exact"))
    assert long.max_range == pytest.approx(30.0) and long.table.shape == (201, 201)
    # a 12 m return: the lab's model puts it in the max cell, the 30 m one does not
    assert lab.observe(np.full(5, 12.0))[1].max() == 200
    assert long.observe(np.full(5, 12.0))[1].max() == round(12.0 / 0.15)
    with pytest.raises(ValueError, match="max_range"):
        SensorModelParams(max_range=0.0)
