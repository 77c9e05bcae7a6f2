"""Motion model: SE(2) composition, noise schemes, variance matching, twist integration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mcl.filter.angles import circular_mean, wrap_angle
from mcl.filter.motion_model import (
    MotionModel,
    MotionModelParams,
    compose,
    gaussian_to_uniform,
    odometry_to_twist,
    twist_to_odometry,
    uniform_to_gaussian,
)
from racecar_sim.settings.config import from_mapping

TWISTS = (
    st.floats(-3, 3, allow_nan=False),  # vx, m/s
    st.floats(-1, 1, allow_nan=False),  # vy, m/s
    st.floats(-4, 4, allow_nan=False),  # omega, rad/s
)
"""Car-frame twists the integration properties draw."""

finite = st.floats(-50, 50, allow_nan=False, allow_infinity=False)
angle = st.floats(-10, 10, allow_nan=False, allow_infinity=False)
poses = arrays(np.float64, st.tuples(st.integers(1, 20), st.just(3)), elements=finite)


def _matrix(x: float, y: float, th: float) -> np.ndarray:
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])


def test_forward_at_half_pi_moves_plus_y() -> None:
    model = MotionModel(MotionModelParams(scheme="none"))
    out = model.evaluate(np.array([[2.0, 3.0, math.pi / 2]]), np.array([1.0, 0.0, 0.0]), None)  # type: ignore[arg-type]
    np.testing.assert_allclose(out[0], [2.0, 4.0, math.pi / 2], atol=1e-12)


def test_left_step_and_turn_by_hand() -> None:
    # Facing -x (theta = pi): a step to the car's left is -y in the world; then turn by +pi/2.
    out = compose(np.array([[0.0, 0.0, math.pi]]), np.array([0.0, 1.0, math.pi / 2]))
    np.testing.assert_allclose(out[0], [0.0, -1.0, -math.pi / 2], atol=1e-12)


@given(
    poses,
    st.tuples(st.floats(-2, 2, allow_nan=False), st.floats(-2, 2, allow_nan=False), angle),
)
def test_none_scheme_is_the_pose_matrix_product(particles: np.ndarray, odo: tuple) -> None:
    model = MotionModel(MotionModelParams(scheme="none"))
    out = model.evaluate(particles, np.array(odo), np.random.default_rng(0))
    for p, q in zip(particles, out, strict=True):
        m = _matrix(*p) @ _matrix(*odo)
        np.testing.assert_allclose(q[:2], m[:2, 2], atol=1e-9)
        assert abs(wrap_angle(q[2] - math.atan2(m[1, 0], m[0, 0]))) < 1e-9


@settings(deadline=None)  # the first call may compile the numba kernels
@given(poses, st.sampled_from(["uniform", "gaussian", "none"]), angle)
def test_headings_are_wrapped(particles: np.ndarray, scheme: str, dth: float) -> None:
    model = MotionModel(MotionModelParams(scheme=scheme, coefficients=0.5))
    out = model.evaluate(particles, np.array([0.1, 0.0, dth]), np.random.default_rng(1))
    assert np.all(out[:, 2] >= -math.pi) and np.all(out[:, 2] < math.pi)


@given(arrays(np.float64, st.integers(1, 50), elements=st.floats(-1e6, 1e6, allow_nan=False)))
def test_wrap_angle_range_and_equivalence(a: np.ndarray) -> None:
    w = wrap_angle(a)
    assert np.all(w >= -math.pi) and np.all(w < math.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-6)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-6)


def test_wrap_angle_boundaries() -> None:
    assert wrap_angle(math.pi) == -math.pi
    assert wrap_angle(-math.pi) == -math.pi
    assert wrap_angle(-1e-17 - math.pi) < math.pi


def test_circular_mean_around_pi() -> None:
    a = np.array([math.pi - 0.1, -math.pi + 0.1, math.pi - 0.05, -math.pi + 0.05])
    m = circular_mean(a)
    assert abs(wrap_angle(m - math.pi)) < 1e-9
    assert abs(np.mean(a)) < 1e-9  # the linear mean would say 0: the wrong way round
    # weighted towards the -pi side: the mean stays near pi, on that side
    mw = circular_mean(np.array([math.pi - 0.1, -math.pi + 0.1]), np.array([0.25, 0.75]))
    assert -math.pi < mw < -math.pi + 0.1


def _displacements(scheme: str, coefficients, n: int = 40000, seed: int = 3) -> np.ndarray:
    """Noise alone: particles at the origin heading 0, zero odometry -> the drawn perturbations."""
    model = MotionModel(MotionModelParams(scheme=scheme, coefficients=coefficients))
    out = model.evaluate(np.zeros((n, 3)), np.zeros(3), np.random.default_rng(seed))
    return out


def test_uniform_noise_bounds_and_variance_per_component() -> None:
    c = (0.1, 0.02, 0.3)
    d = _displacements("uniform", c)
    for k in range(3):
        assert np.all(np.abs(d[:, k]) <= c[k])
        # variance of U(-c, c) is c^2 / 3; standard error of a sample variance ~ var * sqrt(0.8 / n)
        assert np.var(d[:, k]) == pytest.approx(c[k] ** 2 / 3, rel=0.03)


def test_gaussian_noise_std_per_component() -> None:
    sigma = (0.05, 0.01, 0.2)
    d = _displacements("gaussian", sigma)
    np.testing.assert_allclose(d.std(axis=0), sigma, rtol=0.03)
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=0.01)


def test_noise_components_are_independent() -> None:
    d = _displacements("gaussian", 0.1)
    corr = np.corrcoef(d.T)
    assert np.all(np.abs(corr[np.triu_indices(3, 1)]) < 0.03)


def test_variance_matched_conversion() -> None:
    assert uniform_to_gaussian(math.sqrt(3.0)) == pytest.approx(1.0)
    assert gaussian_to_uniform(1.0) == pytest.approx(math.sqrt(3.0))
    np.testing.assert_allclose(
        gaussian_to_uniform(uniform_to_gaussian(np.array([0.3, 2.0]))), [0.3, 2.0]
    )
    uni = MotionModelParams(scheme="uniform", coefficients=(0.3, 0.1, 0.2))
    gauss = uni.with_scheme("gaussian")
    assert gauss.scheme == "gaussian"
    v_uni = _displacements("uniform", uni.coefficients).var(axis=0)
    v_gauss = _displacements("gaussian", gauss.coefficients, seed=4).var(axis=0)
    np.testing.assert_allclose(v_uni, v_gauss, rtol=0.05)
    assert gauss.with_scheme("uniform").coefficients == pytest.approx(uni.coefficients)


def test_same_seed_same_particles() -> None:
    model = MotionModel()
    p = np.random.default_rng(0).normal(size=(50, 3))
    a = model.evaluate(p, np.array([0.1, 0.0, 0.05]), np.random.default_rng(7))
    b = model.evaluate(p, np.array([0.1, 0.0, 0.05]), np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(
        a, model.evaluate(p, np.array([0.1, 0.0, 0.05]), np.random.default_rng(8))
    )


def test_twist_straight_and_quarter_circle() -> None:
    np.testing.assert_allclose(twist_to_odometry(np.array([2.0, 0.5, 0.0]), 0.1), [0.2, 0.05, 0.0])
    # vx = 1 m/s, omega = pi/2 rad/s for 1 s: a quarter of a circle of radius 2/pi, to the left.
    r = 2.0 / math.pi
    np.testing.assert_allclose(
        twist_to_odometry(np.array([1.0, 0.0, math.pi / 2]), 1.0), [r, r, math.pi / 2], atol=1e-12
    )


@settings(max_examples=30)
@given(
    *TWISTS,
    st.floats(0.0, 1.0, allow_nan=False),
)
def test_twist_integration_is_many_small_steps(vx: float, vy: float, om: float, dt: float) -> None:
    one = compose(np.zeros((1, 3)), twist_to_odometry(np.array([vx, vy, om]), dt))[0]
    steps = np.zeros((1, 3))
    small = twist_to_odometry(np.array([vx, vy, om]), dt / 64)
    for _ in range(64):
        steps = compose(steps, small)
    np.testing.assert_allclose(one[:2], steps[0, :2], atol=1e-9)
    assert abs(wrap_angle(one[2] - steps[0, 2])) < 1e-9


@settings(max_examples=60)
@given(
    *TWISTS,
    st.floats(0.001, 0.75, allow_nan=False),
)
def test_odometry_to_twist_undoes_twist_to_odometry(vx: float, vy: float, om: float, dt: float) -> None:
    """The twist held ``dt`` that gives a displacement is the one that made it (turns under 3 rad,
    where the arc is one to one), both ways round."""
    twist = np.array([vx, vy, om])
    back = odometry_to_twist(twist_to_odometry(twist, dt), dt)
    np.testing.assert_allclose(back, twist, atol=1e-9)
    moved = twist_to_odometry(twist, dt)
    np.testing.assert_allclose(twist_to_odometry(odometry_to_twist(moved, dt), dt), moved, atol=1e-12)


def test_odometry_to_twist_of_a_quarter_circle() -> None:
    """A quarter circle of radius 2 m to the left in 2 s: 1/4 of 2 pi r = pi metres at pi/4 rad/s."""
    twist = odometry_to_twist(np.array([2.0, 2.0, math.pi / 2]), 2.0)
    np.testing.assert_allclose(twist, [math.pi / 2, 0.0, math.pi / 4], atol=1e-12)
    with pytest.raises(ValueError, match="dt must be a positive number of seconds"):
        odometry_to_twist(np.zeros(3), 0.0)


def test_params_from_mapping_and_errors() -> None:
    p = from_mapping(MotionModelParams, {"scheme": "uniform", "coefficients": [0.1, 0.2, 0.3]})
    assert p.coefficients == (0.1, 0.2, 0.3)
    assert MotionModelParams(coefficients=0.5).coefficients == (0.5, 0.5, 0.5)
    with pytest.raises(ValueError, match="scheme"):
        MotionModelParams(scheme="laplace")
    with pytest.raises(ValueError, match="coefficients"):
        MotionModelParams(coefficients=(0.1, -0.2, 0.3))
    with pytest.raises(ValueError, match="coefficients"):
        MotionModelParams(coefficients=(0.1, 0.2))
    model = MotionModel()
    with pytest.raises(ValueError, match="odometry"):
        model.evaluate(np.zeros((2, 3)), np.array([0.0, math.nan, 0.0]), np.random.default_rng())
    with pytest.raises(ValueError, match="particles"):
        model.evaluate(np.zeros((2, 2)), np.zeros(3), np.random.default_rng())


@settings(max_examples=30, deadline=None)
@given(
    scheme=st.sampled_from(["uniform", "gaussian"]),
    seed=st.integers(0, 2**32),
    n=st.integers(1, 50),
    odo=st.tuples(*[st.floats(-1.0, 1.0)] * 3),
)
def test_evaluate_adds_exactly_the_noise_sample_noise_draws(scheme, seed, n, odo) -> None:
    """The fused numba pass equals compose(particles, odometry + sample_noise) for the same
    generator state, and the same state gives the same particles."""
    model = MotionModel(MotionModelParams(scheme=scheme, coefficients=(0.1, 0.05, 0.2)))
    particles = np.random.default_rng(seed).uniform(-5.0, 5.0, (n, 3))
    odo = np.array(odo)
    moved = model.evaluate(particles, odo, np.random.default_rng(seed))
    noise = model.sample_noise(n, np.random.default_rng(seed))
    np.testing.assert_allclose(moved, compose(particles, odo + noise), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(
        moved, model.evaluate(particles, odo, np.random.default_rng(seed))
    )
    assert not np.array_equal(
        moved, model.evaluate(particles, odo, np.random.default_rng(seed + 1))
    )


def test_new_params_take_effect_on_the_next_draw() -> None:
    """The coefficients array is kept per ``params`` object: replacing ``params`` changes the
    noise of the next evaluate (the same draws, scaled by the new coefficients)."""
    particles = np.zeros((5, 3))
    odo = np.array([0.1, 0.0, 0.0])
    model = MotionModel(MotionModelParams(coefficients=(0.01, 0.01, 0.01)))
    small = model.evaluate(particles, odo, np.random.default_rng(4))
    model.params = MotionModelParams(coefficients=(1.0, 1.0, 1.0))
    large = model.evaluate(particles, odo, np.random.default_rng(4))
    noise = MotionModel(model.params).sample_noise(5, np.random.default_rng(4))
    np.testing.assert_allclose(large[:, 0], odo[0] + noise[:, 0], atol=1e-12)
    np.testing.assert_allclose(small[:, 0] - odo[0], (large[:, 0] - odo[0]) / 100, atol=1e-12)
