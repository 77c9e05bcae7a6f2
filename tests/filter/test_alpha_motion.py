"""Tests of the alpha motion model (mcl.filter.alpha_motion, MotionModelParams(scheme="alpha"))."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.alpha_motion import alpha_odometry_into
from mcl.filter.motion_model import MotionModel, MotionModelParams, compose
from racecar_sim.raycast.rand import normals
from racecar_sim.settings.config import from_mapping


def numpy_alpha(odo, alphas, floor, z):
    """Probabilistic Robotics table 5.6 (sample_motion_model_odometry) in numpy, with the normals
    ``z`` (N, 6) given: rot1, trans, rot2 and the floor's dx, dy, dtheta."""
    dx, dy, dth = odo
    trans = np.hypot(dx, dy)
    rot1 = np.arctan2(dy, dx) if trans >= 1e-9 else 0.0
    rot2 = dth - rot1

    def size(a):  # backwards moves get a forward move's noise (amcl)
        w = abs((a + np.pi) % (2 * np.pi) - np.pi)
        return min(w, np.pi - w)

    r1, r2 = size(rot1), size(rot2)
    a1, a2, a3, a4 = alphas
    n1 = rot1 + np.sqrt(a1 * r1**2 + a2 * trans**2) * z[:, 0]
    nt = trans + np.sqrt(a3 * trans**2 + a4 * (r1**2 + r2**2)) * z[:, 1]
    n2 = rot2 + np.sqrt(a1 * r2**2 + a2 * trans**2) * z[:, 2]
    return np.column_stack(
        [nt * np.cos(n1) + floor[0] * z[:, 3], nt * np.sin(n1) + floor[1] * z[:, 4],
         n1 + n2 + floor[2] * z[:, 5]]
    )  # fmt: skip


small = st.floats(-0.4, 0.4)


@settings(max_examples=60)
@given(
    odo=st.tuples(st.floats(-0.5, 0.5), small, small),
    alphas=st.tuples(*[st.floats(0.0, 0.5)] * 4),
    floor=st.tuples(*[st.floats(0.0, 0.05)] * 3),
    seed=st.integers(0, 2**62),
    n=st.integers(1, 40),
)
def test_kernel_is_the_numpy_formula(odo, alphas, floor, seed, n) -> None:
    out = np.empty((n, 3))
    alpha_odometry_into(np.array(odo), np.array(alphas), np.array(floor), seed, out)
    z = np.empty(6 * n)
    normals(seed, z)
    expected = numpy_alpha(odo, alphas, floor, z.reshape(n, 6))
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-12)


def _sd(model: MotionModel, odo, n: int = 40000) -> np.ndarray:
    return model.noisy_odometry(n, np.array(odo), np.random.default_rng(0)).std(axis=0)


def test_noise_grows_with_speed_and_turn_rate() -> None:
    alphas = (0.2, 0.08, 0.16, 0.02)
    model = MotionModel(MotionModelParams(scheme="alpha", coefficients=0.0, alphas=alphas))
    slow, fast = _sd(model, (0.05, 0.0, 0.0)), _sd(model, (0.175, 0.0, 0.0))  # 2 and 7 m/s, 40 Hz
    assert fast[[0, 2]] == pytest.approx(slow[[0, 2]] * 3.5, rel=0.03)  # linear in translation
    assert fast[1] == pytest.approx(slow[1] * 3.5**2, rel=0.05)  # sideways: t x sd(rot1) ~ t²
    assert fast[0] == pytest.approx(math.sqrt(alphas[2]) * 0.175, rel=0.03)
    assert fast[2] == pytest.approx(math.sqrt(2 * alphas[1]) * 0.175, rel=0.03)  # two turns
    turning = _sd(model, (0.175, 0.0, 0.1))
    want = math.sqrt(2 * alphas[1] * 0.175**2 + alphas[0] * 0.1**2)  # rot2 carries the turn
    assert turning[2] == pytest.approx(want, rel=0.03) and turning[0] > fast[0]
    rest = _sd(MotionModel(MotionModelParams(scheme="alpha", coefficients=(0.01, 0.02, 0.03))),
               (0.0, 0.0, 0.0))  # fmt: skip
    np.testing.assert_allclose(rest, [0.01, 0.02, 0.03], rtol=0.03)  # the floor alone


def test_backwards_gets_the_noise_of_forwards() -> None:
    model = MotionModel(MotionModelParams(scheme="alpha", coefficients=0.0))
    ahead = model.noisy_odometry(20000, np.array([0.1, 0.0, 0.05]), np.random.default_rng(1))
    back = model.noisy_odometry(20000, np.array([-0.1, 0.0, 0.05]), np.random.default_rng(1))
    np.testing.assert_allclose(ahead.mean(axis=0) * [-1, 1, 1], back.mean(axis=0), atol=3e-3)
    np.testing.assert_allclose(ahead.std(axis=0), back.std(axis=0), rtol=0.05, atol=1e-4)


@settings(max_examples=30)
@given(odo=st.tuples(st.floats(-0.5, 0.5), small, small), seed=st.integers(0, 2**32))
def test_without_noise_it_is_the_pose_product(odo, seed) -> None:
    model = MotionModel(MotionModelParams(scheme="alpha", coefficients=0.0, alphas=(0, 0, 0, 0)))
    particles = np.random.default_rng(seed).uniform(-3.0, 3.0, (7, 3))
    moved = model.evaluate(particles, np.array(odo), np.random.default_rng(seed))
    np.testing.assert_allclose(moved, compose(particles, np.array(odo)), atol=1e-12)


def test_evaluate_composes_the_noisy_odometry_and_is_seeded() -> None:
    model = MotionModel(MotionModelParams(scheme="alpha"))
    particles = np.random.default_rng(2).uniform(-3.0, 3.0, (50, 3))
    odo = np.array([0.12, 0.01, 0.04])
    moved = model.evaluate(particles, odo, np.random.default_rng(9))
    noisy = model.noisy_odometry(50, odo, np.random.default_rng(9))
    np.testing.assert_array_equal(moved, compose(particles, noisy))
    assert not np.array_equal(moved, model.evaluate(particles, odo, np.random.default_rng(10)))
    with pytest.raises(ValueError, match="noisy_odometry"):
        model.sample_noise(3, np.random.default_rng(0))


def test_params_alphas_from_mapping_and_errors() -> None:
    p = from_mapping(MotionModelParams, {"scheme": "alpha", "alphas": [0.1, 0.2, 0.3, 0.4]})
    assert p.alphas == (0.1, 0.2, 0.3, 0.4)
    for bad in ((0.1, 0.2, 0.3), (0.1, -0.2, 0.3, 0.4), "x"):
        with pytest.raises(ValueError, match="alphas"):
            MotionModelParams(scheme="alpha", alphas=bad)
