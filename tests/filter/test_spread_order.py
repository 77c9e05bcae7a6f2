"""A filter whose caster casts spread clouds in Z-order gives the same particles and weights."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.sensors.lidar import Lidar

TRUTH = np.array([6.0, 0.0, 0.4])  # a free pose of the room map


def _run(room, sort_extent: float) -> tuple[ParticleFilter, SensorModel]:
    sm = SensorModel(room, SensorModelParams(raycast_method="lut", parallel=False))
    assert sm.caster is not None
    sm.caster.lut_params = dataclasses.replace(sm.caster.lut_params, sort_extent=sort_extent)
    pf = ParticleFilter(
        room,
        3000,
        sensor_model=sm,
        rng=11,
    )
    pf.initialize_global(3000)
    lidar, rng = Lidar(room), np.random.default_rng(4)
    for k in range(4):
        if k:
            pf.resample()
        pf.predict(np.array([0.5, 0.0, 0.1]), 0.05)
        pf.update_weights(sm.log_evaluate(pf.particles, lidar.measure(TRUTH, rng)))
    return pf, sm


def test_same_seeded_filter_same_particles_and_weights_with_and_without_the_sort(room) -> None:
    # 0.5 m: the room's global cloud (12 m x 8 m) and its converging clouds are all sorted
    with_sort, sm = _run(room, 0.5)
    without, _ = _run(room, math.inf)
    assert np.array_equal(with_sort.particles, without.particles)
    assert np.array_equal(with_sort.weights, without.weights)
    assert with_sort.weights.max() > 10 * with_sort.weights.min()  # weighed, not uniform
    first = room.sample_free_poses(np.random.default_rng(0), 3000)
    scan = Lidar(room).measure(TRUTH, np.random.default_rng(1))
    plain = SensorModel(room, SensorModelParams(raycast_method="lut", parallel=False))
    plain.caster.lut_params = dataclasses.replace(plain.caster.lut_params, sort_extent=math.inf)
    assert np.array_equal(sm.log_evaluate(first, scan), plain.log_evaluate(first, scan))
