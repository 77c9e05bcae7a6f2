"""The particle filter without a known start: global initialisation, KLD-sampling, augmented MCL,
scan spacing and the uncertainty report (small in-memory maps, static car, exact casting)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.filter.angles import wrap_angle
from mcl.filter.augmented import AugmentedParams
from mcl.filter.kld import KLDParams
from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.maps import OccupancyMap
from racecar_sim.sensors.lidar import Lidar

TRUTH = np.array([6.0, 0.0, 0.4])  # free, 1.95 m from the nearest wall of the room map
ELSEWHERE = np.array([3.0, 3.5, -2.0])  # another free pose of the room map
AUGMENTED = AugmentedParams(alpha_slow=0.01, alpha_fast=0.3)


@pytest.fixture(scope="module")
def sensor(room) -> SensorModel:
    return SensorModel(room, SensorModelParams(raycast_method="exact", parallel=False))


def _pf(room, sensor, seed: int = 0, **params) -> ParticleFilter:
    return ParticleFilter(
        room, sensor_model=sensor, params=ParticleFilterParams(**params), rng=seed
    )


def _scans(room, pose, n: int, seed: int = 5) -> list[np.ndarray]:
    lidar, rng = Lidar(room), np.random.default_rng(seed)
    return [lidar.measure(pose, rng) for _ in range(n)]


# ---------------------------------------------------------------------- global start
def test_global_start_covers_free_space_only_and_is_sized_from_the_area(default_map) -> None:
    pf = ParticleFilter(default_map, params=ParticleFilterParams(n_particles=100), rng=3)
    pf.initialize_global()
    p = pf.particles
    assert p.shape[0] == math.ceil(20.0 * default_map.free_area)  # the default 20 per m²
    assert np.all(default_map.is_free(p[:, :2]))  # no particle in a wall or off the map
    assert np.all((p[:, 2] >= -math.pi) & (p[:, 2] < math.pi))
    # Spread by area: the share in each quarter of the map matches its share of free cells.
    rc = default_map.world_to_grid(p[:, :2])
    free = default_map.free
    h, w = free.shape
    for rows in (slice(0, h // 2), slice(h // 2, h)):
        for cols in (slice(0, w // 2), slice(w // 2, w)):
            share = free[rows, cols].sum() / free.sum()
            inside = (
                (rc[:, 0] >= (rows.start or 0)) & (rc[:, 0] < (rows.stop or h))
                & (rc[:, 1] >= (cols.start or 0)) & (rc[:, 1] < (cols.stop or w))
            )  # fmt: skip
            assert inside.mean() == pytest.approx(share, abs=0.02)


def test_global_count_follows_density_cap_and_explicit_count(room, sensor) -> None:
    area = room.free_area
    assert _pf(room, sensor, global_density=50.0, n_particles=10).global_particle_count() == (
        math.ceil(50.0 * area)
    )
    capped = _pf(room, sensor, global_density=50.0, global_max_particles=700, n_particles=10)
    assert capped.global_particle_count() == 700
    assert _pf(room, sensor, global_particles=123).global_particle_count() == 123
    pf = _pf(room, sensor, global_clearance=0.6)
    pf.initialize_global(2000)
    assert pf.n_particles == 2000
    assert np.all(room.distance_at(pf.particles[:, :2]) >= 0.6 - room.resolution)
    with pytest.raises(ValueError, match="n_particles"):
        pf.initialize_global(0)


# ---------------------------------------------------------------------- alphas 0 = plain filter
def _plain_correct(pf: ParticleFilter, scan: np.ndarray) -> None:
    """The filter's correction as it was before augmented MCL (weigh, with the wide hit while the
    cloud is spread, then resample if needed)."""
    pf.searching = pf.is_searching()
    pf.update_weights(pf.sensor_model.log_evaluate(pf.particles, scan, pf.searching))
    if pf.needs_resampling():
        pf.resample()


def _run(pf: ParticleFilter, scans, correct) -> None:
    pf.initialize(TRUTH, 0.3)
    for scan in scans:
        pf.predict(np.array([0.2, 0.0, 0.05]), 0.025)
        correct(pf, scan)


def test_with_alphas_at_zero_the_filter_is_exactly_the_plain_filter(room, sensor) -> None:
    scans = _scans(room, TRUTH, 6) + _scans(room, ELSEWHERE, 6)  # tracking, then kidnapped
    plain = _pf(room, sensor, seed=7, n_particles=300)
    _run(plain, scans, _plain_correct)
    zero = _pf(room, sensor, seed=7, n_particles=300, augmented=AugmentedParams(0.0, 0.0))
    _run(zero, scans, ParticleFilter.correct)
    np.testing.assert_array_equal(zero.particles, plain.particles)
    np.testing.assert_array_equal(zero.weights, plain.weights)
    assert zero.n_injected == 0
    # The comparison can fail: with the alphas on, the kidnap injects and the particles differ.
    on = _pf(room, sensor, seed=7, n_particles=300, augmented=AUGMENTED)
    _run(on, scans, ParticleFilter.correct)
    assert on.n_injected > 0
    assert on.particles.shape != plain.particles.shape or not np.array_equal(
        on.particles, plain.particles
    )


# ---------------------------------------------------------------------- recovery
def test_a_kidnapped_filter_injects_random_particles_and_finds_the_car(room, sensor) -> None:
    pf = _pf(room, sensor, seed=1, n_particles=1000, augmented=AUGMENTED)
    pf.initialize(TRUTH, 0.05)
    for scan in _scans(room, TRUTH, 10):
        pf.predict(np.zeros(3), 0.025)
        pf.correct(scan)
    assert pf.n_injected < 0.01 * 1000 * 10  # tracking well: next to nothing injected
    before = pf.n_injected
    errors = []
    for scan in _scans(room, ELSEWHERE, 60, seed=6):  # the car is elsewhere now
        pf.predict(np.zeros(3), 0.025)
        pf.correct(scan)
        est = pf.estimate()
        errors.append(math.dist(est[:2], ELSEWHERE[:2]))
    assert pf.n_injected - before > 1000
    assert errors[-1] < 0.15
    assert abs(wrap_angle(pf.estimate()[2] - ELSEWHERE[2])) < 0.1


def test_random_particles_join_at_the_next_correction(room, sensor) -> None:
    pf = _pf(room, sensor, seed=2, n_particles=500, augmented=AUGMENTED)
    pf.initialize(TRUTH, 0.05)
    for scan in _scans(room, TRUTH, 5):
        pf.correct(scan)
    pf.averages.w_fast = 0.5 * pf.averages.w_slow  # as if the scans had just got much worse
    size = pf.n_particles  # (a random particle or two may still wait from the last resampling)
    pf.resample()
    kept, pending = pf.n_particles, pf.pending_random
    assert pending > 100 and kept + pending == size
    # Until the next scan the estimate is the belief's, not dragged by random poses.
    assert math.dist(pf.estimate()[:2], TRUTH[:2]) < 0.1
    pf.correct(_scans(room, TRUTH, 1, seed=11)[0])
    assert pf.last_injected == pending
    assert math.dist(pf.estimate()[:2], TRUTH[:2]) < 0.1  # the scan weighed them first


# ---------------------------------------------------------------------- KLD-sampling
def test_kld_shrinks_the_set_after_convergence_and_grows_it_when_spread(room, sensor) -> None:
    kld = KLDParams(enabled=True, min_particles=200, max_particles=20000)
    pf = _pf(room, sensor, seed=4, kld=kld, global_particles=20000)
    pf.initialize_global()
    assert pf.n_particles == 20000
    for scan in _scans(room, TRUTH, 15):
        pf.predict(np.zeros(3), 0.025)
        pf.correct(scan)
    assert math.dist(pf.estimate()[:2], TRUTH[:2]) < 0.3
    assert 200 <= pf.n_particles < 1000
    pf.set_particles(pf.random_free_poses(5000))  # a spread-out belief needs many
    pf.resample()
    assert pf.n_particles > 5000


# ---------------------------------------------------------------------- scan spacing
def test_scans_are_skipped_until_the_car_has_moved(room, sensor) -> None:
    pf = _pf(room, sensor, n_particles=100, update_min_distance=0.2, update_min_angle=0.5)
    pf.initialize(TRUTH, 0.1)
    scan = _scans(room, TRUTH, 1)[0]
    pf.correct(scan)  # the first scan after initialising is always used
    assert (pf.n_updates, pf.n_skipped) == (1, 0)
    pf.move(np.array([0.1, 0.0, 0.1]))
    pf.correct(scan)
    assert (pf.n_updates, pf.n_skipped) == (1, 1)
    pf.move(np.array([0.1, 0.0, 0.1]))  # 0.2 m in all
    pf.correct(scan)
    pf.move(np.array([0.0, 0.0, 0.6]))  # turning is enough too
    pf.correct(scan)
    assert (pf.n_updates, pf.n_skipped) == (3, 1)


# ---------------------------------------------------------------------- uncertainty
def test_uncertainty_is_honest_in_a_symmetric_room_and_sure_in_an_asymmetric_one(room) -> None:
    occ = np.zeros((80, 160), dtype=bool)  # an empty 8 m x 4 m box: symmetric under 180 deg
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    box = OccupancyMap(occupied=occ, resolution=0.05, origin=(0.0, 0.0, 0.0), name="box")
    # Tempered (squash 0.1, the experiment uses 0.05): with the lab's 1/2.2 ten scans from one
    # spot already collapse the cloud onto one of the two equally good modes.
    box_sensor = SensorModel(
        box, SensorModelParams(raycast_method="exact", parallel=False, squash_exponent=0.1)
    )
    truth = np.array([2.5, 1.5, 0.3])
    for grid, model, pose in (
        (box, box_sensor, truth),
        (room, SensorModel(room, SensorModelParams(raycast_method="exact")), TRUTH),
    ):
        pf = ParticleFilter(grid, sensor_model=model, params=ParticleFilterParams(), rng=8)
        pf.initialize_global(8000)
        for scan in _scans(grid, pose, 10):
            pf.predict(np.zeros(3), 0.025)
            pf.correct(scan)
        u = pf.uncertainty()
        np.testing.assert_allclose(u.covariance, pf.covariance())
        if grid is box:
            assert u.ambiguous and u.n_clusters >= 2
        else:
            assert not u.ambiguous and u.n_clusters == 1 and u.top_weight > 0.9
