"""Particle filter: initialisation, prediction, weights, resampling policy, estimate, recovery."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mcl.filter.angles import wrap_angle
from mcl.filter.motion_model import MotionModel, MotionModelParams, compose, twist_to_odometry
from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.sensors.lidar import Lidar
from racecar_sim.sensors.odometry import Odometry
from racecar_sim.settings.config import from_mapping

TRUTH = np.array([6.0, 0.0, 0.4])  # free, 1.95 m from the nearest wall of the room map


@pytest.fixture(scope="module")
def sensor(room) -> SensorModel:
    return SensorModel(room, SensorModelParams(raycast_method="exact"))


def _pf(room, sensor, n: int = 300, seed: int = 0, **params) -> ParticleFilter:
    return ParticleFilter(
        room, n, sensor_model=sensor, params=ParticleFilterParams(**params), rng=seed
    )


# ---------------------------------------------------------------------------------- set-up
def test_initialize_gaussian_around_pose(room, sensor) -> None:
    pf = _pf(room, sensor, n=20000)
    pf.initialize(np.array([2.0, 1.0, math.pi - 0.05]), spread=(0.3, 0.1, 0.2))
    p = pf.particles
    assert p.shape == (20000, 3)
    np.testing.assert_allclose(p[:, :2].mean(axis=0), [2.0, 1.0], atol=0.01)
    np.testing.assert_allclose(p[:, :2].std(axis=0), [0.3, 0.1], rtol=0.03)
    assert np.all(p[:, 2] >= -math.pi) and np.all(p[:, 2] < math.pi)
    assert np.any(p[:, 2] < 0)  # the heading cloud straddles +-pi
    np.testing.assert_allclose(pf.weights, 1 / 20000)
    assert abs(wrap_angle(pf.estimate()[2] - (math.pi - 0.05))) < 0.01


def test_initialize_global_is_over_free_space(room, sensor) -> None:
    pf = _pf(room, sensor, n=2000)
    pf.initialize_global()
    assert np.all(room.is_free(pf.particles[:, :2]))
    # spread over the room, not bunched: both halves of the room get particles
    assert np.mean(pf.particles[:, 0] < 7.0) == pytest.approx(0.5, abs=0.1)


def test_use_before_initialize_raises(room, sensor) -> None:
    pf = _pf(room, sensor)
    with pytest.raises(RuntimeError, match="initialize"):
        pf.predict(np.zeros(3), 0.1)
    with pytest.raises(RuntimeError, match="initialize"):
        pf.estimate()


# ---------------------------------------------------------------------------------- predict
def test_predict_moves_forward_along_heading(room, sensor) -> None:
    pf = ParticleFilter(
        room, 4, motion_model=MotionModel(MotionModelParams(scheme="none")), sensor_model=sensor
    )
    pf.set_particles(np.array([[2.0, 1.0, math.pi / 2]] * 4))
    pf.predict(np.array([2.0, 0.0, 0.0]), 0.5)  # 1 m forward at theta = pi/2 -> +y
    np.testing.assert_allclose(pf.particles, [[2.0, 2.0, math.pi / 2]] * 4, atol=1e-12)


def test_predict_rejects_bad_input(room, sensor) -> None:
    pf = _pf(room, sensor)
    pf.initialize(TRUTH)
    with pytest.raises(ValueError, match="twist"):
        pf.predict(np.array([1.0, np.nan, 0.0]), 0.1)
    with pytest.raises(ValueError, match="dt"):
        pf.predict(np.zeros(3), -0.1)


# ---------------------------------------------------------------------------------- weights
@settings(max_examples=50, deadline=None)
@given(
    arrays(
        np.float64,
        50,
        elements=st.one_of(
            st.floats(-1e4, 0.0), st.just(-math.inf), st.just(math.nan), st.just(math.inf)
        ),
    )
)
def test_weights_sum_to_one_after_any_update(small_filter, log_lik: np.ndarray) -> None:
    pf = small_filter
    pf.initialize(TRUTH, 0.1)
    pf.update_weights(log_lik)
    w = pf.weights
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    assert math.isclose(w.sum(), 1.0, rel_tol=1e-12)
    assert np.all(np.isfinite(pf.estimate()))
    assert 1.0 - 1e-9 <= pf.effective_sample_size <= 50 * (1 + 1e-9)
    assert pf.effective_sample_size == pytest.approx(1.0 / np.dot(w, w), rel=1e-12)
    usable = np.isfinite(log_lik)
    if usable.any():
        assert np.all(w[~usable] == 0.0)  # NaN, +inf and -inf count as impossible
        assert w[np.nanargmax(np.where(usable, log_lik, -np.inf))] == w.max()


@pytest.fixture(scope="module")
def small_filter(room) -> ParticleFilter:
    """One 50-particle filter shared by the property test (hypothesis reuses it across examples)."""
    return ParticleFilter(
        room, 50, sensor_model=SensorModel(room, SensorModelParams(raycast_method="exact"))
    )


def test_weights_multiply_across_corrections_without_resampling(room, sensor) -> None:
    pf = _pf(room, sensor, n=3, resample_threshold="never")
    pf.set_particles(np.array([TRUTH] * 3))
    pf.update_weights(np.log([1.0, 2.0, 1.0]))
    pf.update_weights(np.array([math.log(3.0), 0.0, -math.inf]))
    np.testing.assert_allclose(pf.weights, [3 / 5, 2 / 5, 0.0])
    # weighted mean likelihood of the second update under the first's weights: (3 + 2 + 0) / 4
    assert pf.last_log_mean_likelihood == pytest.approx(math.log(5 / 4))


@pytest.mark.parametrize("policy", ["keep", "global"])
def test_all_zero_weights_recover(room, sensor, policy: str) -> None:
    pf = _pf(room, sensor, n=200, on_degenerate=policy)
    pf.initialize(TRUTH, 0.1)
    before = pf.particles.copy()
    pf.update_weights(np.full(200, -math.inf))
    assert pf.n_degenerate == 1
    np.testing.assert_allclose(pf.weights, 1 / 200)
    if policy == "keep":
        np.testing.assert_array_equal(pf.particles, before)
    else:
        assert np.linalg.norm(pf.particles[:, :2] - TRUTH[:2], axis=1).max() > 2.0
    pf.update_weights(np.full(200, math.nan))
    assert pf.n_degenerate == 2
    assert np.all(np.isfinite(pf.estimate()))


def test_resampling_policies(room, sensor) -> None:
    lidar = Lidar(room)
    scan = lidar.measure(TRUTH, np.random.default_rng(0))
    counts = {}
    for policy in ("always", "never", 0.5):
        pf = _pf(room, sensor, n=300, resample_threshold=policy)
        pf.initialize(TRUTH, 0.3)
        for _ in range(3):
            pf.correct(scan)
        counts[policy] = pf.n_resamples
    assert counts["always"] == 3
    assert counts["never"] == 0
    assert 1 <= counts[0.5] <= 3  # a 0.3 m cloud is mostly unlikely: the first correction resamples


def test_effective_sample_size_follows_the_weights_that_stand(room, sensor) -> None:
    """The update's own sum of squares serves while its weights stand, never after them."""
    pf = _pf(room, sensor, n=4, resample_threshold="never")
    pf.set_particles(np.array([TRUTH] * 4))
    pf.update_weights(np.log([1.0, 1.0, 2.0, 4.0]))
    assert pf.effective_sample_size == pytest.approx(64 / 22, rel=1e-12)
    assert pf.effective_sample_size == pf.last_effective_sample_size
    pf.set_particles(pf.particles, [1.0, 0.0, 0.0, 1.0])
    assert pf.effective_sample_size == pytest.approx(2.0, rel=1e-12)
    pf.resample()
    assert pf.effective_sample_size == pytest.approx(4.0, rel=1e-12)
    assert pf.last_effective_sample_size == pytest.approx(64 / 22, rel=1e-12)


def test_resampling_makes_weights_uniform_and_keeps_heavy_particles(room, sensor) -> None:
    pf = _pf(room, sensor, n=4, resampling="systematic")
    pf.set_particles(np.array([[1.0, 1.0, 0.0], [2.0, 2.0, 0.0], [3.0, 3.0, 0.0], [4.0, 4.0, 0.0]]))
    pf.update_weights(np.array([-math.inf, 0.0, -math.inf, 0.0]))
    idx = pf.resample()
    assert sorted(idx.tolist()) == [1, 1, 3, 3]  # systematic: exactly n w_i copies
    np.testing.assert_allclose(pf.weights, 0.25)
    assert pf.n_resamples == 1


# ---------------------------------------------------------------------------------- estimate
def test_estimate_circular_mean_near_pi(room, sensor) -> None:
    pf = _pf(room, sensor)
    pf.set_particles(
        np.array(
            [[0.0, 0.0, math.pi - 0.2], [2.0, 0.0, -math.pi + 0.2], [1.0, 3.0, math.pi - 0.1]]
        ),
        weights=np.array([1.0, 1.0, 2.0]),
    )
    x, y, th = pf.estimate()
    assert (x, y) == pytest.approx((1.0, 1.5))
    assert abs(wrap_angle(th - math.pi)) < 0.06


def test_covariance_by_hand(room, sensor) -> None:
    pf = _pf(room, sensor)
    pf.set_particles(np.array([[0.0, 0.0, math.pi - 0.1], [2.0, 2.0, -math.pi + 0.1]]))
    cov = pf.covariance()
    # mean (1, 1, pi); deviations (-1, -1, -0.1) and (1, 1, 0.1) with weights 1/2 each
    expected = np.array([[1.0, 1.0, 0.1], [1.0, 1.0, 0.1], [0.1, 0.1, 0.01]])
    np.testing.assert_allclose(cov, expected, atol=1e-12)


# ---------------------------------------------------------------------------------- scans
def test_bad_scans(room, sensor) -> None:
    pf = _pf(room, sensor, n=200)
    pf.initialize(TRUTH, 0.2)
    scan = Lidar(room).measure(TRUTH, np.random.default_rng(1)).astype(np.float64)
    with pytest.raises(ValueError, match="negative"):
        pf.correct(np.where(np.arange(1080) == 5, -1.0, scan))
    scan[::3] = np.nan
    scan[1::7] = np.inf
    pf.correct(scan)
    assert np.all(np.isfinite(pf.estimate()))
    fixed = SensorModel(
        room, SensorModelParams(raycast_method="exact"), beam_angles=Lidar(room).angles
    )
    pf2 = ParticleFilter(room, 50, sensor_model=fixed, rng=0)
    pf2.initialize(TRUTH)
    with pytest.raises(ValueError, match="1080 beam angles"):
        pf2.correct(np.ones(720))


def test_global_localization_from_a_few_scans_at_rest(room, sensor) -> None:
    pf = _pf(room, sensor, n=3000, seed=4)
    pf.initialize_global()
    lidar = Lidar(room)
    rng = np.random.default_rng(9)
    for _ in range(30):
        pf.predict(np.zeros(3), 0.025)
        pf.correct(lidar.measure(TRUTH, rng))
    est = pf.estimate()
    assert np.linalg.norm(est[:2] - TRUTH[:2]) < 0.15
    assert abs(wrap_angle(est[2] - TRUTH[2])) < 0.1
    assert np.sqrt(pf.covariance()[0, 0]) < 0.1  # and it knows it


def test_tracks_a_car_driving_a_circle(room, sensor) -> None:
    """Noisy odometry + noisy lidar, one lap of a 1.2 m circle at 1.5 m/s: error stays small."""
    rng = np.random.default_rng(21)
    lidar, odometry = Lidar(room), Odometry()
    dt, speed, radius = 0.025, 1.5, 1.2
    twist = np.array([speed, 0.0, speed / radius])
    truth = np.array([7.5, 1.5 - radius, 0.0])  # on the circle around (7.5, 1.5), heading +x
    pf = _pf(room, sensor, n=500, seed=22)
    pf.initialize(truth + np.array([0.3, -0.2, 0.1]), spread=(0.3, 0.3, 0.1))
    errors = []
    for _ in range(int(2 * math.pi * radius / speed / dt)):
        truth = compose(truth[None, :], twist_to_odometry(twist, dt))[0]
        pf.predict(odometry.measure(twist, rng), dt)
        pf.correct(lidar.measure(truth, rng))
        est = pf.estimate()
        errors.append((np.linalg.norm(est[:2] - truth[:2]), abs(wrap_angle(est[2] - truth[2]))))
    err = np.array(errors)
    settled = err[40:]  # after one second
    assert settled[:, 0].max() < 0.15
    assert settled[:, 1].max() < 0.1
    assert pf.n_degenerate == 0


# ---------------------------------------------------------------------------------- params
def test_params_validation_and_override(room, sensor) -> None:
    assert ParticleFilterParams(resample_threshold="always").resample_threshold == 1.0
    assert ParticleFilterParams(resample_threshold="never").resample_threshold == 0.0
    p = from_mapping(ParticleFilterParams, {"n_particles": 10, "init_spread": [0.1, 0.2, 0.3]})
    assert p.init_spread == (0.1, 0.2, 0.3)
    with pytest.raises(ValueError, match="resampling"):
        ParticleFilterParams(resampling="fancy")
    with pytest.raises(ValueError, match="resample_threshold"):
        ParticleFilterParams(resample_threshold=1.5)
    with pytest.raises(ValueError, match="n_particles"):
        ParticleFilterParams(n_particles=0)
    with pytest.raises(ValueError, match="on_degenerate"):
        ParticleFilterParams(on_degenerate="panic")
    pf = ParticleFilter(room, 123, sensor_model=sensor, params=p)
    pf.initialize(TRUTH)
    assert pf.n_particles == 123
    # a spread wider than any map (10 km, the config's bound) is refused: 1e300 made the
    # cloud's covariance NaN
    for wide in (1e300, (0.1, 0.1, 1e5)):
        with pytest.raises(
            ValueError, match=r"spread must be one or three numbers in \[0, 10000\]"
        ):
            pf.initialize(TRUTH, wide)
    with pytest.raises(ValueError):
        pf.particles[0, 0] = 1.0  # read-only view
