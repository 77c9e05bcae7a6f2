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


def _bridges(**settings) -> OdometryScaleParams:
    """The scale learned between poses the scan confirms (``source="map"``), the learner these
    tests drive; the default learns from the scans (tests/filter/test_scan_scale.py)."""
    return OdometryScaleParams(source="map", **settings)


def _drive(
    scale: OdometryScale,
    true_over_reported: float,
    estimate_follows: str,
    steps: int,
    speed: float = 2.0,
    omega: float = 0.0,
    dt: float = 0.025,
    spread: float = 0.05,
    fit: float = 1.0,
    start: np.ndarray | None = None,
):
    """Drive straight (or on a circle) with wheels that report 1 / true_over_reported of the
    speed, a scan every step; the estimate is the truth ("truth": the scan pins the car) or the
    scaled odometry ("odometry": the scan says nothing along the path), with the scan fit ``fit``
    there. Returns the scale and the truth's final pose."""
    truth = np.zeros(3) if start is None else start.copy()
    dead = truth.copy()
    for _ in range(steps):
        reported = np.array([speed / true_over_reported, 0.0, omega])
        scale.observe(reported, dt)
        used = scale.scaled(reported)
        for pose, v in ((truth, speed), (dead, used[0])):
            pose[2] += omega * dt
            pose[0] += v * math.cos(pose[2]) * dt
            pose[1] += v * math.sin(pose[2]) * dt
        estimate = truth if estimate_follows == "truth" else dead
        scale.confirm(estimate.copy(), spread, fit)
    return scale, truth


@settings(deadline=None, max_examples=10)
@given(k=st.floats(0.85, 1.2))
def test_the_scale_converges_to_the_wheels_error_where_the_scan_pins_the_car(k):
    scale, _ = _drive(OdometryScale(_bridges()), k, "truth", steps=4000)  # 200 m
    assert scale.scale == pytest.approx(k, abs=0.01)
    assert scale.bridges_used > 50


@settings(deadline=None, max_examples=10)
@given(k=st.floats(0.85, 1.2))
def test_on_a_circle_the_scale_converges_as_on_a_straight(k):
    # the odometry is integrated along the estimate's heading: turning does not mix heading and
    # speed errors (radius 2 m at 2 m/s true speed)
    scale, _ = _drive(OdometryScale(_bridges()), k, "truth", steps=4000, omega=1.0)
    assert scale.scale == pytest.approx(k, abs=0.01)
    assert scale.bridges_used > 50


@settings(deadline=None, max_examples=10)
@given(k=st.floats(0.85, 1.2))
def test_where_the_scan_says_nothing_the_scale_keeps_what_it_learned(k):
    scale, _ = _drive(OdometryScale(_bridges()), k, "truth", steps=4000)
    learned = scale.scale
    scale.restart()
    _drive(scale, k, "odometry", steps=4000)  # a long featureless corridor
    assert scale.scale == pytest.approx(learned, abs=1e-9)


@settings(deadline=None, max_examples=10)
@given(k=st.floats(1.03, 1.15), drag=st.floats(0.7, 0.95))
def test_a_drag_the_scan_does_not_confirm_does_not_move_the_scale(k, drag):
    # the honest world's failure: where the map is out of date the scan holds the estimate back
    # (it moves ``drag`` of the odometry) and fits poorly; the estimate catches up where the
    # scan confirms the car again. The scale ends at the wheels' error, not at the drag's.
    scale, truth = _drive(OdometryScale(_bridges()), k, "truth", steps=2000)
    before = scale.scale
    held = OdometryScale(_bridges())
    held.take(scale)
    # the drag: 20 m along which the estimate moves ``drag`` x the scaled odometry, fit 0.6
    estimate = truth.copy()
    for _ in range(400):
        reported = np.array([2.0 / k, 0.0, 0.0])
        scale.observe(reported, 0.025)
        truth[0] += 2.0 * 0.025
        estimate[0] += drag * scale.scaled(reported)[0] * 0.025
        scale.confirm(estimate.copy(), 0.05, 0.6)
    assert scale.scale == before  # nothing confirmed: nothing learned
    _drive(scale, k, "truth", steps=400, start=truth)  # caught up, confirmed again
    assert scale.scale == pytest.approx(k, abs=0.01)


def test_an_untrusted_cloud_or_a_poor_fit_teaches_nothing():
    spread, _ = _drive(OdometryScale(_bridges()), 1.1, "truth", steps=2000, spread=1.0)
    assert spread.scale == 1.0 and spread.bridges_used == 0
    poor, _ = _drive(OdometryScale(_bridges()), 1.1, "truth", steps=2000, fit=0.8)
    assert poor.scale == 1.0 and poor.bridges_used == 0
    unknown, _ = _drive(OdometryScale(_bridges()), 1.1, "truth", steps=2000,
                        fit=math.nan)  # fmt: skip
    assert unknown.scale == 1.0 and unknown.bridges_used == 0


def test_the_scale_is_bounded():
    scale, _ = _drive(OdometryScale(_bridges(high=1.1)), 1.5, "truth", steps=4000)
    assert scale.scale == pytest.approx(1.1)
    off, _ = _drive(OdometryScale(_bridges(enabled=False)), 1.2, "truth", steps=2000)
    assert off.scale == 1.0
    assert np.array_equal(off.scaled(np.array([1.0, 0.0, 0.0])), [1.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("low", 1.2, "low"),
        ("high", 0.9, "high"),
        ("window", -1.0, "window"),
        ("max_bridge", 1.0, "max_bridge"),
        ("prior_metres", 0.0, "prior_metres"),
        ("settle_bridges", -1, "settle_bridges"),
        ("settle_bridges", 1.5, "settle_bridges"),
        ("fit_gate", 1.5, "fit_gate"),
        ("fit_scans", 0, "fit_scans"),
        ("fit_beams", True, "fit_beams"),
        ("fit_tolerance", 0.0, "fit_tolerance"),
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
    params = from_mapping(ParticleFilterParams, {"odometry_scale": {"fit_gate": 0.5}})
    assert params.odometry_scale.fit_gate == 0.5
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
def test_the_first_bridge_after_a_start_is_not_used_and_one_bridge_moves_little(k):
    # the first bridge (the cloud settling) teaches nothing; one more, taken where the estimate
    # lagged (k < 1) or ran ahead, counts as 2 m against the initial scale's 5 m
    steps = int(40 * k) + 3  # one bridge of 2 m of reported travel (2 / k m/s, 25 ms steps)
    scale, _ = _drive(OdometryScale(_bridges()), k, "truth", steps=steps)
    assert scale.bridges_used == 0 and scale.scale == 1.0
    scale, _ = _drive(OdometryScale(_bridges()), k, "truth", steps=2 * steps)
    assert scale.bridges_used == 1
    assert scale.scale == pytest.approx(min(1.25, max(0.8, (5.0 + 2.0 * k) / 7.0)), abs=0.02)


def test_a_filter_learns_the_scale_from_its_own_scans():
    # a filter in a corridor with posts every 3 m along one wall (the scan pins the car along
    # it), driven by wheels that read 1 / 1.1 of the speed: the scale it learns nears 1.1
    from mcl.filter.sensor_model import SensorModel, SensorModelParams
    from racecar_sim.raycast import RayCaster

    occupied = np.zeros((60, 600), dtype=bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    occupied[:15, ::30] = True  # posts 1.5 m long along one wall, every 3 m
    grid = OccupancyMap(occupied, resolution=0.1)
    angles = np.linspace(-2.3, 2.3, 270)
    sensor = SensorModel(grid, SensorModelParams(parallel=False), beam_angles=angles)
    truth_caster = RayCaster(grid, float(sensor.max_range), method="exact")
    pf = ParticleFilter(grid, motion_model=MotionModel(MotionModelParams()), sensor_model=sensor,
                        params=ParticleFilterParams(n_particles=300, odometry_scale=_bridges()),
                        rng=1)  # fmt: skip
    truth = np.array([2.0, 3.0, 0.0])
    pf.initialize(truth, (0.05, 0.05, 0.01))
    for _ in range(800):  # 1.5 m/s, 40 Hz: 30 m
        pf.predict(np.array([1.5 / 1.1, 0.0, 0.0]), 0.025)
        truth[0] += 1.5 * 0.025
        pf.correct(truth_caster.cast(sensor.lidar_poses(truth[None, :])[0], angles)[0])
    assert pf.odometry_scale.bridges_used >= 5
    assert pf.odometry_scale.scale == pytest.approx(1.1, abs=0.03)
    assert abs(pf.estimate()[0] - truth[0]) < 0.3


@settings(deadline=None, max_examples=10)
@given(k=st.floats(0.85, 1.2), initial=st.floats(0.9, 1.15))
def test_a_calibrated_scale_is_held_where_the_learner_would_move_it(k, initial):
    # wheels that read 1 / k of the speed, the scan pinning the car: the learner goes to k; a
    # calibrated car given its scale with learning off keeps exactly that scale and uses it
    held, _ = _drive(OdometryScale(_bridges(initial=initial, learn=False)), k,
                     "truth", steps=2000)  # fmt: skip
    assert held.scale == initial and held.bridges_used == 0
    assert held.scaled(np.array([2.0, 0.1, 0.3]))[0] == pytest.approx(2.0 * initial)
    learned, _ = _drive(OdometryScale(_bridges(initial=initial)), k, "truth",
                        steps=4000)  # fmt: skip
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
