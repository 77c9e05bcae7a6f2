"""Tests of racecar_sim.sensors.lidar: beam noise statistics, lidar geometry, odometry noise.

Statistical tests compare sample statistics with the model's analytic values; every bound is
``Z`` standard errors computed from the sample size, so a correct model fails about once in 1.7
million runs per check and the seeds are fixed anyway.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from racecar_sim.maps import OccupancyMap
from racecar_sim.sensors.lidar import Lidar
from racecar_sim.sensors.odometry import Odometry
from racecar_sim.settings.config import LidarParams, OdometryNoise

Z = 5.0  # standard errors allowed in statistical checks
N = 200_000  # beams per statistical sample

NOISE_FREE = {"sigma": 0.0, "p_short": 0.0, "p_max": 0.0, "p_rand": 0.0}


def room(width: float = 10.0, height: float = 8.0, res: float = 0.05) -> OccupancyMap:
    """An empty rectangular room with one-cell walls; world origin at its lower-left corner."""
    rows, cols = round(height / res), round(width / res)
    occ = np.zeros((rows, cols), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return OccupancyMap(occupied=occ, resolution=res, origin=(0.0, 0.0, 0.0), name="room")


@pytest.fixture(scope="module")
def grid() -> OccupancyMap:
    return room()


def lidar_with(grid: OccupancyMap, **kw: float) -> Lidar:
    return Lidar(grid, LidarParams(**kw))


def binomial_ok(k: int, n: int, p: float) -> bool:
    """Whether a count ``k`` of ``n`` trials is within Z standard errors of probability ``p``."""
    return abs(k - n * p) <= Z * math.sqrt(n * p * (1 - p)) + 1


def truncated_exp_mean(rate: float, upper: float) -> float:
    """Mean of an exponential with ``rate`` truncated to [0, upper]."""
    return 1.0 / rate - upper / math.expm1(rate * upper)


def truncated_exp_cdf(x: float, rate: float, upper: float) -> float:
    return math.expm1(-rate * x) / math.expm1(-rate * upper)


# ---------------------------------------------------------------------- beam noise
def test_gaussian_noise_sigma_matches(grid: OccupancyMap) -> None:
    sigma = 0.05
    lidar = lidar_with(grid, **{**NOISE_FREE, "sigma": sigma})
    rng = np.random.default_rng(1)
    truth = rng.uniform(1.0, 9.0, N)
    err = lidar.add_noise(truth, rng).astype(np.float64) - truth
    # The sample standard deviation has standard error sigma / sqrt(2 (n - 1)).
    assert abs(err.std(ddof=1) - sigma) <= Z * sigma / math.sqrt(2 * (N - 1))
    assert abs(err.mean()) <= Z * sigma / math.sqrt(N)


def test_part_rates_match_probabilities(grid: OccupancyMap) -> None:
    """With sigma = 0 and every true range at r, each part leaves a distinct signature."""
    p_rand, p_max, p_short, max_range, r = 0.04, 0.03, 0.08, 10.0, 4.0
    lidar = lidar_with(
        grid, sigma=0.0, p_rand=p_rand, p_max=p_max, p_short=p_short, max_range=max_range
    )
    out = lidar.add_noise(np.full(N, r), np.random.default_rng(2)).astype(np.float64)
    exact = np.count_nonzero(out == np.float32(r))
    drop = np.count_nonzero(out == max_range)
    above = np.count_nonzero((out > r) & (out < max_range))  # random returns beyond r only
    below = np.count_nonzero(out < r)  # short returns and random returns below r
    assert exact + drop + above + below == N
    assert binomial_ok(drop, N, p_max)
    assert binomial_ok(above, N, p_rand * (1 - r / max_range))
    assert binomial_ok(below, N, p_short + p_rand * r / max_range)
    assert binomial_ok(exact, N, 1 - p_rand - p_max - p_short)


def test_random_returns_are_uniform_over_the_range(grid: OccupancyMap) -> None:
    max_range = 10.0
    lidar = lidar_with(grid, **{**NOISE_FREE, "p_rand": 1.0, "max_range": max_range})
    out = lidar.add_noise(np.full(N, 3.0), np.random.default_rng(3)).astype(np.float64)
    assert out.min() >= 0.0 and out.max() <= max_range
    sd = max_range / math.sqrt(12)
    assert abs(out.mean() - max_range / 2) <= Z * sd / math.sqrt(N)
    for q in (0.1, 0.5, 0.9):
        assert binomial_ok(int(np.count_nonzero(out <= q * max_range)), N, q)


@pytest.mark.parametrize(("rate", "upper"), [(1.0, 4.0), (0.3, 2.0), (3.0, 8.0)])
def test_short_returns_follow_the_truncated_exponential(
    grid: OccupancyMap, rate: float, upper: float
) -> None:
    lidar = lidar_with(grid, **{**NOISE_FREE, "p_short": 1.0, "short_lambda": rate})
    out = lidar.add_noise(np.full(N, upper), np.random.default_rng(4)).astype(np.float64)
    assert out.min() >= 0.0
    assert out.max() <= np.float32(upper)
    assert abs(out.mean() - truncated_exp_mean(rate, upper)) <= Z * out.std() / math.sqrt(N)
    # Empirical CDF at a few points against the analytic CDF (binomial bounds).
    for x in (0.1 * upper, 0.3 * upper, 0.6 * upper):
        assert binomial_ok(int(np.count_nonzero(out <= x)), N, truncated_exp_cdf(x, rate, upper))


def test_short_returns_lie_below_each_beams_true_range(grid: OccupancyMap) -> None:
    lidar = lidar_with(grid, **{**NOISE_FREE, "p_short": 1.0, "short_lambda": 0.5})
    rng = np.random.default_rng(5)
    truth = rng.uniform(0.0, 10.0, N)
    out = lidar.add_noise(truth, rng)
    assert (out >= 0).all()
    assert (out <= truth.astype(np.float32)).all()


def test_no_return_beams_stay_at_max_range_unless_random(grid: OccupancyMap) -> None:
    p_rand, max_range = 0.1, 10.0
    lidar = lidar_with(grid, sigma=0.2, p_rand=p_rand, p_max=0.1, p_short=0.3, max_range=max_range)
    out = lidar.add_noise(np.full(N, max_range), np.random.default_rng(6))
    changed = np.count_nonzero(out != np.float32(max_range))
    assert binomial_ok(changed, N, p_rand)


@settings(max_examples=60, deadline=None)
@given(
    max_range=st.floats(0.1, 40.0),
    sigma=st.floats(0.0, 5.0),
    probs=st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1), st.floats(0, 1)),
    short_lambda=st.floats(0.01, 50.0),
    fractions=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=200),
    seed=st.integers(0, 2**32 - 1),
)
def test_ranges_stay_within_zero_and_max_range(
    grid: OccupancyMap,
    max_range: float,
    sigma: float,
    probs: tuple[float, float, float, float],
    short_lambda: float,
    fractions: list[float],
    seed: int,
) -> None:
    weights = np.asarray(probs) + 1e-9  # the fourth weight is the Gaussian part's share
    p_rand, p_max, p_short = (weights[:3] / weights.sum() * 0.999).tolist()
    lidar = lidar_with(
        grid,
        max_range=max_range,
        sigma=sigma,
        p_rand=p_rand,
        p_max=p_max,
        p_short=p_short,
        short_lambda=short_lambda,
    )
    truth = np.minimum(np.asarray(fractions) * max_range, max_range)
    out = lidar.add_noise(truth, np.random.default_rng(seed))
    assert out.dtype == np.float32
    assert out.shape == truth.shape
    assert np.isfinite(out).all()
    assert (out >= 0).all()
    assert (out <= np.float32(max_range)).all()


def test_add_noise_rejects_ranges_outside_the_sensor_range(grid: OccupancyMap) -> None:
    lidar = lidar_with(grid, max_range=10.0)
    rng = np.random.default_rng(0)
    for bad in ([1.0, np.nan], [-0.5], [10.5]):
        with pytest.raises(ValueError, match="ranges"):
            lidar.add_noise(np.asarray(bad), rng)


# ---------------------------------------------------------------------- scans
def test_noise_free_params_give_exactly_the_true_ranges(grid: OccupancyMap) -> None:
    lidar = lidar_with(grid, **NOISE_FREE)
    pose = np.array([3.0, 2.5, 0.7])
    scan = lidar.measure(pose, np.random.default_rng(0))
    assert scan.dtype == np.float32
    assert scan.shape == (lidar.params.n_beams,)
    np.testing.assert_array_equal(scan, lidar.true_ranges(pose).astype(np.float32))


def test_same_seed_gives_the_same_scan_and_another_seed_does_not(grid: OccupancyMap) -> None:
    lidar = Lidar(grid)
    pose = np.array([5.0, 4.0, -2.0])
    a = lidar.measure(pose, np.random.default_rng(42))
    b = lidar.measure(pose, np.random.default_rng(42))
    c = lidar.measure(pose, np.random.default_rng(43))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_angles_period_and_mount_pose(grid: OccupancyMap) -> None:
    params = LidarParams(n_beams=361, fov=math.pi, rate=25.0, mount_offset=0.3)
    lidar = Lidar(grid, params)
    np.testing.assert_allclose(lidar.angles, params.angles)
    assert lidar.angles[0] == pytest.approx(-math.pi / 2)
    assert lidar.angles[-1] == pytest.approx(math.pi / 2)
    assert lidar.period == pytest.approx(1 / 25.0)
    np.testing.assert_allclose(lidar.mount_pose([1.0, 2.0, math.pi / 2]), [1.0, 2.3, math.pi / 2])


def test_beams_see_the_walls_of_a_known_room(grid: OccupancyMap) -> None:
    """Facing +x from (3, 4) in a 10 x 8 m room whose walls are one 0.05 m cell thick."""
    lidar = lidar_with(grid, n_beams=5, fov=math.pi, mount_offset=0.0, **NOISE_FREE)
    ranges = lidar.true_ranges([3.0, 4.0, 0.0])  # beams at -90, -45, 0, 45, 90 degrees
    inner = (0.05, 10.0 - 0.05, 0.05, 8.0 - 0.05)  # x_min, x_max, y_min, y_max of the free space
    assert ranges[2] == pytest.approx(inner[1] - 3.0, abs=1e-9)
    assert ranges[0] == pytest.approx(4.0 - inner[2], abs=1e-9)
    assert ranges[4] == pytest.approx(inner[3] - 4.0, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(1.5, 8.5),
    y=st.floats(1.5, 6.5),
    theta=st.floats(-math.pi, math.pi),
    offset=st.floats(-0.5, 0.5),
)
def test_mount_offset_moves_the_origin_of_the_beams(
    grid: OccupancyMap, x: float, y: float, theta: float, offset: float
) -> None:
    mounted = lidar_with(grid, n_beams=90, mount_offset=offset, **NOISE_FREE)
    at_axle = lidar_with(grid, n_beams=90, mount_offset=0.0, **NOISE_FREE)
    shifted = [x + offset * math.cos(theta), y + offset * math.sin(theta), theta]
    np.testing.assert_allclose(
        mounted.true_ranges([x, y, theta]), at_axle.true_ranges(shifted), atol=1e-9
    )


def test_mount_offset_shortens_the_forward_beam(grid: OccupancyMap) -> None:
    front = {"n_beams": 1, "fov": 0.1, **NOISE_FREE}
    ahead = lidar_with(grid, mount_offset=0.4, **front).true_ranges([3.0, 4.0, 0.0])[0]
    axle = lidar_with(grid, mount_offset=0.0, **front).true_ranges([3.0, 4.0, 0.0])[0]
    assert axle - ahead == pytest.approx(0.4, abs=1e-9)


@pytest.mark.parametrize(
    "pose", [[np.nan, 1.0, 0.0], [1.0, 2.0, np.inf], [1.0, 2.0], [[1.0, 2.0, 0.0]]]
)
def test_bad_pose_raises_value_error_naming_it(grid: OccupancyMap, pose: list) -> None:
    lidar = Lidar(grid)
    with pytest.raises(ValueError, match="pose"):
        lidar.measure(np.asarray(pose, dtype=np.float64), np.random.default_rng(0))
    with pytest.raises(ValueError, match="pose"):
        lidar.mount_pose(np.asarray(pose, dtype=np.float64))


def test_lidar_rejects_params_of_the_wrong_type(grid: OccupancyMap) -> None:
    with pytest.raises(TypeError, match="LidarParams"):
        Lidar(grid, {"n_beams": 10})  # type: ignore[arg-type]


def test_scan_on_the_real_stata_map_is_within_range(stata_map: OccupancyMap) -> None:
    lidar = Lidar(stata_map)
    rng = np.random.default_rng(7)
    poses = stata_map.sample_free_poses(rng, 20, clearance=0.5)
    for pose in poses:
        scan = lidar.measure(pose, rng)
        assert scan.min() >= 0 and scan.max() <= lidar.params.max_range
        # A car in a corridor sees walls: most beams return before max range.
        assert np.mean(scan < lidar.params.max_range) > 0.5


def test_scans_on_the_real_stata_map_are_the_exact_casters_ranges(stata_map: OccupancyMap) -> None:
    """f1tenth_gym's lidar (1080 beams, 4.7 rad, 30 m): the scan kernel's ranges are the exact
    caster's doubles, from poses anywhere on the map (long corridors, rooms, next to walls)."""
    lidar = lidar_with(stata_map, n_beams=1080, fov=4.7, max_range=30.0)
    rng = np.random.default_rng(11)
    poses = np.concatenate(
        [stata_map.sample_free_poses(rng, 30, clearance=0.5),
         stata_map.sample_free_poses(rng, 10, clearance=0.0)]
    )  # fmt: skip
    for pose in poses:
        lidar.measure(pose, rng)
        np.testing.assert_array_equal(lidar.last_ranges, lidar.true_ranges(pose))


# ---------------------------------------------------------------------- odometry
def test_odometry_noise_sigma_matches() -> None:
    noise = OdometryNoise(proportional=(0.05, 0.02, 0.1), additive=(0.01, 0.03, 0.02))
    odom = Odometry(noise)
    twist = np.array([2.0, -0.3, 0.8])
    rng = np.random.default_rng(8)
    n = 50_000
    samples = np.array([odom.measure(twist, rng) for _ in range(n)], dtype=np.float64)
    expected = np.hypot(twist * np.asarray(noise.proportional), np.asarray(noise.additive))
    sd = samples.std(axis=0, ddof=1)
    assert np.all(np.abs(sd - expected) <= Z * expected / math.sqrt(2 * (n - 1)))
    assert np.all(np.abs(samples.mean(axis=0) - twist) <= Z * expected / math.sqrt(n))


def test_odometry_without_noise_is_exact_and_float32() -> None:
    odom = Odometry(OdometryNoise(proportional=(0, 0, 0), additive=(0, 0, 0)))
    out = odom.measure(np.array([1.5, 0.0, -0.25]), np.random.default_rng(0))
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, np.float32([1.5, 0.0, -0.25]))


def test_odometry_same_seed_same_reading() -> None:
    odom = Odometry()
    a = odom.measure([1.0, 0.0, 0.3], np.random.default_rng(9))
    b = odom.measure([1.0, 0.0, 0.3], np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("twist", [[np.nan, 0.0, 0.0], [1.0, 0.0], [0.0, 0.0, np.inf]])
def test_odometry_rejects_bad_twist(twist: list) -> None:
    with pytest.raises(ValueError, match="twist"):
        Odometry().measure(np.asarray(twist), np.random.default_rng(0))


# ---------------------------------------------------------------------- one-call scan
@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    yaw=st.floats(-math.pi, math.pi),
    max_range=st.floats(0.5, 40.0),
    mount=st.floats(-0.3, 0.5),
)
def test_measure_is_true_ranges_plus_add_noise_exactly(
    seed: int, yaw: float, max_range: float, mount: float
) -> None:
    """measure() (one kernel call) gives the same doubles and floats as the two-step path."""
    rng = np.random.default_rng(seed)
    occ = rng.random((60, 80)) < 0.04
    occ[[0, -1], :] = True
    grid = OccupancyMap(occupied=occ, resolution=0.05, origin=(-1.0, 2.0, yaw))
    lidar = lidar_with(
        grid, n_beams=257, fov=4.7, max_range=max_range, mount_offset=mount, p_short=0.1,
        p_max=0.05, p_rand=0.05,
    )  # fmt: skip
    w, h = grid.extent
    for _ in range(10):  # poses on and off the map, in free and occupied cells
        uv = rng.uniform(-0.1, 1.1, 2) * (w, h)
        pose = np.array([*grid.map_to_world(uv), rng.uniform(-4, 4)])
        ranges = lidar.true_ranges(pose)
        expected = lidar.add_noise(ranges, np.random.default_rng(seed + 1))
        scan = lidar.measure(pose, np.random.default_rng(seed + 1))
        np.testing.assert_array_equal(lidar.last_ranges, ranges)
        np.testing.assert_array_equal(scan, expected)


def test_measure_rejects_a_bad_pose_naming_it(grid: OccupancyMap) -> None:
    lidar = Lidar(grid)
    for bad in ([1.0, math.nan, 0.0], [1.0, 2.0]):
        with pytest.raises(ValueError, match="pose"):
            lidar.measure(np.array(bad), np.random.default_rng(0))


@pytest.mark.parametrize("parallel", [False, True])
def test_scans_of_many_cars_equal_one_scan_each(grid: OccupancyMap, parallel: bool) -> None:
    """scans_with_noise (threads sharing the cars, or one thread) gives each car the scan
    scan_with_noise gives it alone, noise included."""
    from racecar_sim.raycast.scan import scan_with_noise, scans_with_noise

    lidar = Lidar(grid)
    rng = np.random.default_rng(4)
    poses = grid.sample_free_poses(rng, 12, clearance=0.3)
    seeds = rng.integers(0, 2**62, size=12)
    m = lidar.angles.size
    field, geometry, cos_a, sin_a, noise = lidar.kernel_inputs
    args = (field, poses, geometry, cos_a, sin_a, seeds, noise)
    ranges, out = np.empty((12, m)), np.empty((12, m), dtype=np.float32)
    status = scans_with_noise(*args, ranges, out, parallel)
    assert not status.any()
    for k in range(12):
        one_r, one = np.empty(m), np.empty(m, dtype=np.float32)
        assert scan_with_noise(args[0], poses[k], args[2], args[3], args[4], int(seeds[k]),
                               args[6], one_r, one) == 0  # fmt: skip
        np.testing.assert_array_equal(out[k], one)
        np.testing.assert_array_equal(ranges[k], one_r)


@pytest.mark.parametrize("theta", [5e-324, -5e-324, 1e-310, math.pi / 2 + 1e-17])
def test_a_heading_whose_beam_is_subnormal_off_an_axis_scans_as_the_caster_does(
    grid: OccupancyMap, theta: float
) -> None:
    # The straight-ahead beam's other component is subnormal: 1 / it overflows to inf, which
    # the scan kernel's branch-free walk must not turn into NaN.
    lidar = lidar_with(grid, n_beams=541, fov=4.7, max_range=30.0)
    w, h = grid.extent
    for fx, fy in ((0.3, 0.4), (0.5, 0.5), (0.71, 0.23)):
        pose = np.array([*grid.map_to_world(np.array([fx * w, fy * h])), theta])
        ranges = lidar.true_ranges(pose)
        lidar.measure(pose, np.random.default_rng(0))
        assert np.isfinite(lidar.last_ranges).all()
        np.testing.assert_array_equal(lidar.last_ranges, ranges)
