"""The odometry's forward scale measured by matching scans to each other, no map involved
(mcl.filter.scan_scale), and the filter learning its scale that way (odometry_scale.source)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mcl.filter.motion_model import twist_to_odometry
from mcl.filter.odometry_scale import OdometryScaleParams
from mcl.filter.params import ParticleFilterParams
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.scan_continuity import compose
from mcl.filter.scan_scale import ScanScale, ScanScaleParams, match_forward_scale
from tests.filter.loop_scans import DT, ENV, LIDAR, MAX_RANGE, MOUNT, free_pose

P = ScanScaleParams()


def _match(seed: int, true_scale: float, omega: float, heading_error: float = 0.0):
    """Two exact scans 0.6 m apart; the odometry reads ``1 / true_scale`` of the forward motion
    and turns ``heading_error`` radians more than the car did."""
    start = free_pose(seed)
    twist = np.array([1.5, 0.0, omega])
    end = start
    for _ in range(16):  # 0.6 m at 1.5 m/s
        end = compose(end, twist_to_odometry(twist, DT))
    read = twist / [true_scale, 1.0, 1.0]  # the wheels' forward speed reads short
    odometry = np.array(twist_to_odometry(read, 16 * DT))
    odometry[2] += heading_error
    idx = np.unique(np.rint(np.linspace(0, LIDAR.angles.size - 1, P.beams)).astype(np.int64))
    before = LIDAR.true_ranges(start)
    return match_forward_scale(
        before[idx], LIDAR.angles[idx], LIDAR.true_ranges(end), LIDAR.angles, odometry, MOUNT,
        MAX_RANGE, P.low, P.high, P.heading, P.lateral, P.tolerance, P.tolerance_per_m,
    )  # fmt: skip


def test_two_scans_tell_how_much_the_wheels_under_read() -> None:
    """20 places of the bundled loop, the wheels reading 8 % short: the matched scale is the true
    one (1 / 0.92) within 0.02 in most places, and its median within 0.01."""
    truth = 1 / 0.92
    scales = np.array([_match(seed, truth, 0.2)[0] for seed in range(20)])
    found = scales[np.isfinite(scales)]
    assert found.size >= 15
    assert abs(np.median(found) - truth) <= 0.01
    assert np.mean(np.abs(found - truth) <= 0.02) >= 0.8


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.9, 1.2), st.floats(-0.05, 0.05))
@example(623, 0.9375, 0.0)  # the coarse grid matched, the fine one had too few points: NaNs
@example(508, 1.0296382314224526, 0.0)  # the fine grid's best on the range's lower end
def test_the_match_is_a_scale_on_the_grid_or_nothing(seed, true_scale, heading_error) -> None:
    """Whatever the place, the scale, or a turn the odometry has wrong: a scale within the range
    tried (the coarse grid's ends give NaNs, the fine grid around its second point may reach
    them) with a score and sharpness in [0, 1], or NaNs."""
    scale, score, sharpness = _match(seed, true_scale, 0.3, heading_error)
    if np.isnan(scale):
        assert np.isnan(score) and np.isnan(sharpness)
    else:
        assert P.low <= scale <= P.high
        assert 0.0 <= score <= 1.0 and 0.0 <= sharpness <= 1.0


def test_a_pinned_car_whose_wheels_spin_teaches_nothing() -> None:
    """The scans do not move while the odometry drives 0.6 m: no motion on the grid matches
    (the best lies on its edge), no pair counts and the scale stays the prior."""
    pose = free_pose(3)
    learner = ScanScale(ScanScaleParams(prior_metres=0.0))
    scan = LIDAR.true_ranges(pose)
    learner.observe_scan(scan, LIDAR.angles, MOUNT, MAX_RANGE)
    for _ in range(3):
        for _ in range(16):
            learner.observe(np.array([1.5, 0.0, 0.0]), DT)
        learner.observe_scan(scan, LIDAR.angles, MOUNT, MAX_RANGE)
    assert learner.pairs_matched == 3
    assert learner.pairs_used == 0 and learner.scale == 1.0


def _learn(params: ScanScaleParams, pairs: int, seed: int = 0, read: float = 0.92) -> ScanScale:
    """``pairs`` pairs of exact scans 0.6 m apart on the bundled loop, the wheels reading
    ``read`` of the forward speed."""
    here = free_pose(seed)
    twist = np.array([1.5, 0.0, 0.2])
    learner = ScanScale(params)
    learner.observe_scan(LIDAR.true_ranges(here), LIDAR.angles, MOUNT, MAX_RANGE)
    for _ in range(pairs):
        for _ in range(16):
            here = compose(here, twist_to_odometry(twist, DT))
            learner.observe(twist * [read, 1.0, 1.0], DT)
        learner.observe_scan(LIDAR.true_ranges(here), LIDAR.angles, MOUNT, MAX_RANGE)
    return learner


def test_the_scale_is_the_matched_travel_over_the_odometry_s_with_the_prior() -> None:
    """Three pairs, the wheels reading 0.92 of 0.6 m each: with no prior the scale is the true
    1 / 0.92 (within the fine grid's 0.01 step and a half); with the prior (1) counted as 2 m it is (3 x 0.6 + 2) / (3 x 0.552 + 2), the true
    travel plus the prior's over the odometry's plus the prior's."""
    alone = _learn(ScanScaleParams(prior_metres=0.0), 3)
    assert alone.pairs_used == 3 and abs(alone.scale - 1 / 0.92) <= 0.015
    with_prior = _learn(ScanScaleParams(prior_metres=2.0), 3)
    assert abs(with_prior.scale - (3 * 0.6 + 2.0) / (3 * 0.6 * 0.92 + 2.0)) <= 0.01


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.85, 1.1), st.integers(1, 4), st.floats(0.0, 5.0),
       st.floats(0.1, 5.0))  # fmt: skip
def test_more_weight_on_the_prior_pulls_the_scale_towards_it(seed, read, pairs, prior, more) -> None:
    """A weighted mean of the prior (1) and the pairs' matches, whatever they matched (a pair in
    a place that looks alike along the path may match a wrong scale): the same pairs with the
    prior counted as more metres give a scale on the same side of 1 and no farther from it; with
    no pair counted the scale is the prior."""
    light = _learn(ScanScaleParams(prior_metres=prior), pairs, seed, read)
    heavy = _learn(ScanScaleParams(prior_metres=prior + more), pairs, seed, read)
    assert light.pairs_used == heavy.pairs_used
    if light.pairs_used == 0:
        assert light.scale == heavy.scale == 1.0
    else:
        assert (heavy.scale - 1.0) * (light.scale - 1.0) >= 0.0
        assert abs(heavy.scale - 1.0) <= abs(light.scale - 1.0) + 1e-12
        if light.scale != 1.0:
            assert abs(heavy.scale - 1.0) < abs(light.scale - 1.0)


def test_the_filter_learns_its_scale_from_its_scans() -> None:
    """A filter whose odometry reads 8 % short, on the bundled loop with exact scans: with
    ``source="scans"`` its scale reaches 1 / 0.92 within 0.03 after 15 m; with the scale off it
    stays 1."""
    start = free_pose(0)

    def drive(source: str, enabled: bool = True) -> ParticleFilter:
        params = ParticleFilterParams(
            n_particles=300,
            odometry_scale=OdometryScaleParams(source=source, enabled=enabled),
        )
        pf = ParticleFilter(ENV.map, params=params, rng=0)
        pf.initialize(start, spread=(0.05, 0.05, 0.02))
        here = start
        twist = np.array([1.5, 0.0, 0.1])
        for _ in range(400):  # 10 s, 15 m
            here = compose(here, twist_to_odometry(twist, DT))
            pf.predict(twist * [0.92, 1.0, 1.0], DT)
            pf.correct(LIDAR.true_ranges(here))
        return pf

    assert abs(drive("scans").odometry_scale.scale - 1 / 0.92) <= 0.03
    assert drive("scans", enabled=False).odometry_scale.scale == 1.0


@pytest.mark.parametrize(
    ("field", "value"),
    [("spacing", 0.0), ("beams", 5), ("low", -1.0), ("high", 0.81), ("prior_metres", -1.0),
     ("tolerance", float("nan")), ("min_sharpness", -0.1), ("heading", True)],
)  # fmt: skip
def test_bad_settings_are_refused_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"ScanScaleParams.{field}"):
        ScanScaleParams(**{field: value})


def test_an_unknown_source_is_refused_naming_the_choices() -> None:
    with pytest.raises(ValueError, match=r"OdometryScaleParams\.source.*map.*scans"):
        OdometryScaleParams(source="lidar")
    params = OdometryScaleParams(source="scans", scans={"spacing": 1.0})
    assert params.scans.spacing == 1.0
