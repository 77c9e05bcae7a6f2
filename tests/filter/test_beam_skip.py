"""Beam skipping (amcl's do_beamskip in the beam model): which beams it leaves out, and that it
leaves the plain model's numbers alone whenever it leaves nothing out."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mcl.filter.beam_skip import beam_skip_mask, cloud_converged
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from mcl.wrappers.localization import LocalizationConfig, as_localization_config
from racecar_sim.raycast import RayCaster
from racecar_sim.settings.config import LidarParams

LIDAR = LidarParams()
POSE = np.array([6.0, 1.0, 0.3])  # rear axle, free in the room fixture (world frame)


@pytest.fixture(scope="module")
def models(room) -> tuple[SensorModel, SensorModel]:
    """(plain, beam skipping) on the room, the default lidar's beams and mount."""
    base = SensorModelParams(mount_offset=LIDAR.mount_offset, parallel=False)
    plain = SensorModel(room, base, beam_angles=LIDAR.angles)
    skip = SensorModel(
        room, SensorModelParams(**{**base.__dict__, "beam_skip": True}), beam_angles=LIDAR.angles
    )
    return plain, skip


def _true_scan(room, pose: np.ndarray) -> np.ndarray:
    x, y, th = pose
    mount = np.array([x + LIDAR.mount_offset * np.cos(th), y + LIDAR.mount_offset * np.sin(th), th])
    return RayCaster(room, LIDAR.max_range, method="exact").cast(mount, LIDAR.angles)[0]


def _cloud(rng: np.random.Generator, n: int, sd: float) -> np.ndarray:
    return POSE + rng.standard_normal((n, 3)) * np.array([sd, sd, 0.01])


# ---------------------------------------------------------------------- the mask kernel
@settings(max_examples=60)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 60),
    k=st.integers(1, 40),
    threshold=st.floats(0.0, 1.0),
    error_threshold=st.floats(0.0, 1.0),
    short_only=st.booleans(),
)
def test_mask_keeps_beams_explained_by_more_than_the_threshold(
    seed: int, n: int, k: int, threshold: float, error_threshold: float, short_only: bool
) -> None:
    rng = np.random.default_rng(seed)
    expected = rng.uniform(0.0, 12.0, size=(n, k))
    z_px = rng.integers(0, 201, size=k)
    keep = np.empty(k, dtype=np.bool_)
    px_per_m, distance_px = 20.0, 10.0
    unexplained = beam_skip_mask(
        expected, z_px, px_per_m, 200.0, distance_px, threshold, error_threshold, keep, short_only
    )
    d = np.clip(expected * px_per_m, 0.0, 200.0)
    near = np.abs(z_px[None, :] - d) < distance_px
    beyond = z_px[None, :] > d  # a long return: never an occluder's
    explained = (near | (beyond & short_only)).sum(axis=0)
    wanted = explained > threshold * n
    assert unexplained == int((~wanted).sum())
    if unexplained >= error_threshold * k:
        assert keep.all()  # too many unexplained: the cloud may be wrong, every beam is used
    else:
        np.testing.assert_array_equal(keep, wanted)


@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 200), sd=st.floats(0.0, 2.0))
def test_converged_means_every_particle_near_the_mean(seed: int, n: int, sd: float) -> None:
    rng = np.random.default_rng(seed)
    particles = _cloud(rng, n, sd)
    off = np.abs(particles[:, :2] - particles[:, :2].mean(axis=0))
    assert cloud_converged(particles, 0.5) == bool((off <= 0.5).all())


# ---------------------------------------------------------------------- the sensor model
@settings(max_examples=15)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(20, 300), sd=st.floats(0.6, 3.0))
def test_not_converged_scores_as_the_plain_model(
    room, models, seed: int, n: int, sd: float
) -> None:
    plain, skip = models
    rng = np.random.default_rng(seed)
    particles = _cloud(rng, n, sd)
    if cloud_converged(particles, 0.5):
        particles[0, 0] += 2.0  # spread it for sure
    scan = _true_scan(room, POSE)
    scan[300:500] = 1.0  # an opponent
    np.testing.assert_array_equal(
        skip.log_evaluate(particles, scan), plain.log_evaluate(particles, scan)
    )
    assert not skip.last_beam_skip.converged and skip.last_beam_skip.skipped == 0


@settings(max_examples=15)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(20, 300))
@example(seed=519584, n=20)  # one beam on a half pixel (CI, 2026-12-06)
def test_nothing_unexplained_scores_as_the_plain_model(room, models, seed: int, n: int) -> None:
    plain, skip = models
    rng = np.random.default_rng(seed)
    particles = _cloud(rng, n, 0.003)  # a few mm: every particle explains every beam
    scan = _true_scan(room, POSE)
    got = skip.log_evaluate(particles, scan)
    assert skip.last_beam_skip.converged and skip.last_beam_skip.skipped == 0
    angles, z_px = plain.observe(scan)
    expected = plain.expected_ranges(particles, angles)
    np.testing.assert_array_equal(got, plain.score(expected, z_px))
    # the plain model's fused cast-and-score gives the same numbers but for a beam whose expected
    # range falls on a half pixel exactly, which one ulp rounds to the neighbouring table column
    # (tests/filter/test_fused_scoring.py; seed 519584, n 20: one particle, 0.057 nats)
    fused = plain.log_evaluate(particles, scan)
    px = expected / plain.m_per_px
    on_a_tie = (np.abs(px - np.floor(px) - 0.5) < 1e-9).any(axis=1)
    np.testing.assert_array_equal(got[~on_a_tie], fused[~on_a_tie])
    np.testing.assert_allclose(got[on_a_tie], fused[on_a_tie], rtol=0, atol=0.1)


def test_an_opponent_sector_is_left_out(room, models) -> None:
    plain, skip = models
    rng = np.random.default_rng(3)
    particles = _cloud(rng, 500, 0.02)
    scan = _true_scan(room, POSE)
    scan[480:600] = 0.9  # a car 0.9 m ahead blocks the beams in front
    got = skip.log_evaluate(particles, scan)
    decision = skip.last_beam_skip
    angles, z_px = plain.observe(scan)
    expected = plain.expected_ranges(particles, angles)
    d = np.clip(expected / plain.m_per_px, 0, plain.z_max)
    explained = (np.abs(z_px[None, :] - d) < 0.5 / plain.m_per_px).mean(axis=0) > 0.3
    idx, _ = plain.beams_used(scan.size)
    blocked = (idx >= 480) & (idx < 600)
    assert not explained[blocked].any()  # every blocked beam is left out
    assert decision.converged and not decision.forced
    assert decision.skipped == int((~explained).sum()) >= int(blocked.sum())
    # the kept beams, scored by the plain model, are exactly the skipping model's score
    kept = plain.score(np.ascontiguousarray(expected[:, explained]), z_px[explained])
    np.testing.assert_array_equal(got, kept)
    # and the opponent no longer pulls the cloud: the plain model's weights differ
    assert not np.array_equal(got, plain.log_evaluate(particles, scan))


def test_short_only_keeps_long_returns(room, models) -> None:
    params = SensorModelParams(
        mount_offset=LIDAR.mount_offset, parallel=False, beam_skip=True, beam_skip_short_only=True
    )
    model = SensorModel(room, params, beam_angles=LIDAR.angles)
    particles = _cloud(np.random.default_rng(5), 300, 0.02)
    scan = _true_scan(room, POSE)
    scan[100:200] = LIDAR.max_range  # drop-outs: long returns
    scan[480:600] = 0.9  # an opponent: short returns
    model.log_evaluate(particles, scan)
    idx, _ = model.beams_used(scan.size)
    short = int(((idx >= 480) & (idx < 600)).sum())
    long_ = int(((idx >= 100) & (idx < 200)).sum())
    skipped = model.last_beam_skip.skipped
    assert short <= skipped < short + long_  # the opponent's beams go, the drop-outs stay
    models[1].log_evaluate(particles, scan)  # amcl's rule skips both
    assert models[1].last_beam_skip.skipped >= short + long_ > skipped


def test_a_scan_nothing_explains_uses_every_beam(room, models) -> None:
    plain, skip = models
    particles = _cloud(np.random.default_rng(4), 200, 0.02)
    scan = np.full(LIDAR.n_beams, 0.35)  # boxed in: no beam matches the map
    got = skip.log_evaluate(particles, scan)
    assert skip.last_beam_skip.forced and skip.last_beam_skip.skipped == 0
    angles, z_px = plain.observe(scan)
    np.testing.assert_array_equal(got, plain.score(plain.expected_ranges(particles, angles), z_px))


def test_settings_are_validated_and_load_from_a_mapping() -> None:
    config = as_localization_config(
        {"sensor": {"beam_skip": True, "beam_skip_threshold": 0.5, "beam_skip_distance": 0.3}}
    )
    assert isinstance(config, LocalizationConfig)
    assert config.sensor.beam_skip and config.sensor.beam_skip_threshold == 0.5
    assert SensorModelParams().beam_skip is False  # off by default: seeded results unchanged
    for bad, word in (
        ({"beam_skip": "yes"}, "beam_skip"),
        ({"beam_skip_threshold": 1.5}, "beam_skip_threshold"),
        ({"beam_skip_error_threshold": -0.1}, "beam_skip_error_threshold"),
        ({"beam_skip_distance": 0.0}, "beam_skip_distance"),
        ({"beam_skip_converged_distance": float("nan")}, "beam_skip_converged_distance"),
        ({"beam_skip": True, "model": "likelihood_field"}, "beam model only"),
    ):
        with pytest.raises(ValueError, match=word):
            SensorModelParams(**bad)
