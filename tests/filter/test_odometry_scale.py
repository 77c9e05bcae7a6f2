"""The learned odometry speed scale (mcl.filter.odometry_scale) and its place in the particle filter."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.motion_model import MotionModel, MotionModelParams
from mcl.filter.odometry_scale import OdometryScale, OdometryScaleParams
from mcl.filter.params import ParticleFilterParams
from mcl.filter.particle_filter import ParticleFilter
from racecar_sim.maps import OccupancyMap
from racecar_sim.settings.config import from_mapping


def _drive(
    scale: OdometryScale,
    true_over_reported: float,
    estimate_follows: str,
    steps: int,
    speed: float = 2.0,
    omega: float = 0.0,
    dt: float = 0.025,
    spread: float = 0.05,
):
    """Drive straight (or on a circle) with wheels that report 1 / true_over_reported of the
    speed; the estimate is the truth ("truth": the scan pins the car) or the scaled odometry
    ("odometry": the scan says nothing along the path)."""
    truth = np.zeros(3)
    dead = np.zeros(3)
    for _ in range(steps):
        reported = np.array([speed / true_over_reported, 0.0, omega])
        estimate = truth if estimate_follows == "truth" else dead
        if scale.needs_estimate():
            scale.observe(reported, dt, estimate.copy(), spread)
        else:
            scale.observe(reported, dt)
        used = scale.scaled(reported)
        for pose, v in ((truth, speed), (dead, used[0])):
            pose[2] += omega * dt
            pose[0] += v * math.cos(pose[2]) * dt
            pose[1] += v * math.sin(pose[2]) * dt
    return scale


@settings(deadline=None, max_examples=10)
@given(k=st.floats(0.85, 1.2))
def test_the_scale_converges_to_the_wheels_error_where_the_scan_pins_the_car(k):
    scale = _drive(OdometryScale(OdometryScaleParams()), k, "truth", steps=4000)  # 200 m
    assert scale.scale == pytest.approx(k, abs=0.01)
    assert scale.windows_used > 50


@settings(deadline=None, max_examples=10)
@given(k=st.floats(0.85, 1.2))
def test_where_the_scan_says_nothing_the_scale_keeps_what_it_learned(k):
    scale = _drive(OdometryScale(OdometryScaleParams()), k, "truth", steps=4000)
    learned = scale.scale
    scale.restart()  # the estimate below starts at its own origin
    _drive(scale, k, "odometry", steps=4000)  # a long featureless corridor
    assert scale.scale == pytest.approx(learned, abs=1e-9)


def test_an_untrusted_cloud_or_a_turn_teaches_nothing():
    spread = _drive(OdometryScale(OdometryScaleParams()), 1.1, "truth", steps=2000, spread=1.0)
    assert spread.scale == 1.0 and spread.windows_used == 0
    turning = _drive(OdometryScale(OdometryScaleParams()), 1.1, "truth", steps=2000, omega=1.5)
    assert turning.scale == 1.0 and turning.windows_used == 0


def test_the_scale_is_bounded():
    scale = _drive(OdometryScale(OdometryScaleParams(high=1.1)), 1.5, "truth", steps=4000)
    assert scale.scale == pytest.approx(1.1)
    off = _drive(OdometryScale(OdometryScaleParams(enabled=False)), 1.2, "truth", steps=2000)
    assert off.scale == 1.0
    assert np.array_equal(off.scaled(np.array([1.0, 0.0, 0.0])), [1.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("gain", 0.0, "gain"),
        ("gain", 1.5, "gain"),
        ("low", 1.2, "low"),
        ("high", 0.9, "high"),
        ("window", -1.0, "window"),
        ("max_spread", 0.0, "max_spread"),
        ("min_straightness", 2.0, "min_straightness"),
        ("enabled", "yes", "enabled"),
        ("learn", 1, "learn"),
        ("initial", 1.3, "initial"),
        ("initial", 0.7, "initial"),
        ("initial", math.inf, "initial"),
        ("window", math.nan, "window"),
    ],
)
def test_bad_settings_are_named(field, value, message):
    with pytest.raises(ValueError, match=message):
        OdometryScaleParams(**{field: value})


def test_the_filter_loads_the_setting_from_a_mapping_and_applies_it():
    params = from_mapping(ParticleFilterParams, {"odometry_scale": {"gain": 0.5}})
    assert params.odometry_scale.gain == 0.5
    occupied = np.zeros((200, 200), dtype=bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    grid = OccupancyMap(occupied, resolution=0.1)
    pf = ParticleFilter(
        grid,
        motion_model=MotionModel(MotionModelParams(scheme="none")),
        params=ParticleFilterParams(n_particles=50),
        rng=0,
    )
    pf.initialize(np.array([5.0, 10.0, 0.0]), (0.0, 0.0, 0.0))
    pf.odometry_scale.scale = 1.1
    before = pf.particles.copy()
    pf.predict(np.array([2.0, 0.0, 0.0]), 1.0)
    assert np.allclose(pf.particles[:, 0] - before[:, 0], 2.2)


@settings(deadline=None, max_examples=20)
@given(k=st.floats(0.3, 3.0))
def test_one_window_moves_the_scale_a_fifth_of_the_way_even_the_first(k):
    # a first window taken where the estimate lagged (k < 1) or ran ahead must not set the scale
    # on its own: it moves gain = 0.2 of the way to the window's ratio, within [low, high]
    steps = int(40 * k) + 3  # one window of 2 m of reported travel (2 / k m/s, 25 ms steps)
    scale = _drive(OdometryScale(OdometryScaleParams()), k, "truth", steps=steps)
    assert scale.windows_used == 1
    assert scale.scale == pytest.approx(min(1.25, max(0.8, 1.0 + 0.2 * (k - 1.0))), abs=0.01)


@settings(deadline=None, max_examples=10)
@given(k=st.floats(0.85, 1.2), initial=st.floats(0.9, 1.15))
def test_a_calibrated_scale_is_held_where_the_learner_would_move_it(k, initial):
    # wheels that read 1 / k of the speed, the scan pinning the car: the learner goes to k; a
    # calibrated car given its scale with learning off keeps exactly that scale and uses it
    held = _drive(OdometryScale(OdometryScaleParams(initial=initial, learn=False)), k, "truth",
                  steps=2000)  # fmt: skip
    assert held.scale == initial and held.windows_used == 0
    assert held.scaled(np.array([2.0, 0.1, 0.3]))[0] == pytest.approx(2.0 * initial)
    learned = _drive(OdometryScale(OdometryScaleParams(initial=initial)), k, "truth", steps=4000)
    assert learned.scale == pytest.approx(k, abs=0.01)


def test_a_filter_starts_from_the_initial_scale_given_in_a_mapping():
    params = from_mapping(
        ParticleFilterParams, {"odometry_scale": {"initial": 1.056, "learn": False}}
    )
    occupied = np.zeros((200, 200), dtype=bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    pf = ParticleFilter(
        OccupancyMap(occupied, resolution=0.1),
        motion_model=MotionModel(MotionModelParams(scheme="none")),
        params=ParticleFilterParams(n_particles=50, odometry_scale=params.odometry_scale),
        rng=0,
    )
    pf.initialize(np.array([5.0, 10.0, 0.0]), (0.0, 0.0, 0.0))
    before = pf.particles.copy()
    pf.predict(np.array([2.0, 0.0, 0.0]), 1.0)  # 2 m reported: 2.112 m moved
    assert np.allclose(pf.particles[:, 0] - before[:, 0], 2.112)


@settings(deadline=None, max_examples=20)
@given(
    scale=st.tuples(*[st.floats(-0.3, 0.3)] * 3),
    offset=st.tuples(*[st.floats(-0.2, 0.2)] * 3),
    true=st.tuples(st.floats(-3, 3), st.floats(-0.5, 0.5), st.floats(-2, 2)),
)
def test_a_calibrated_bias_is_undone_before_the_filter_moves(scale, offset, true):
    # odometry that reads true x (1 + scale) + offset (the simulator's OdometryBias) moves a
    # filter given that calibration exactly as the true twist moves a filter given none
    from racecar_sim.sensors.scan_effects import OdometryBias

    bias = OdometryBias(scale=scale, offset=offset)
    reported = bias.apply(np.array(true)).astype(np.float64)
    assert np.allclose(bias.unbiased(reported), true, atol=1e-5)
    occupied = np.zeros((200, 200), dtype=bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    grid = OccupancyMap(occupied, resolution=0.1)
    moved = []
    for given_bias, twist in ((bias, reported), (OdometryBias(), np.array(true))):
        params = ParticleFilterParams(
            n_particles=20, odometry_bias=given_bias, odometry_scale=OdometryScaleParams(learn=False)
        )
        pf = ParticleFilter(grid, motion_model=MotionModel(MotionModelParams(scheme="none")),
                            params=params, rng=0)  # fmt: skip
        pf.initialize(np.array([10.0, 10.0, 0.3]), (0.0, 0.0, 0.0))
        pf.predict(twist, 0.5)
        moved.append(pf.particles.copy())
    assert np.allclose(moved[0], moved[1], atol=1e-4)


def test_a_calibration_loads_from_a_mapping_and_nonsense_is_named():
    params = from_mapping(ParticleFilterParams, {"odometry_bias": {
        "scale": [-0.0529, 0.0, 0.1013], "offset": [-0.0287, -0.0131, 0.0432]}})  # fmt: skip
    assert params.odometry_bias.scale == (-0.0529, 0.0, 0.1013)
    assert ParticleFilterParams().odometry_bias.is_zero
    with pytest.raises(ValueError, match=r"odometry_bias\.scale"):
        ParticleFilterParams(odometry_bias={"scale": [-0.95, 0.0, 0.0]})
    with pytest.raises(ValueError, match="odometry_bias"):
        from_mapping(ParticleFilterParams, {"odometry_bias": {"offset": [1, 2]}})
