"""The numba step kernels against the plain numpy formulas they replace (same numbers)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mcl.angles import circular_mean, wrap_angle
from mcl.step_kernels import compose_into, pose_moments, systematic_pick, wrap

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(deadline=None)
@given(st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=1, max_size=50))
def test_wrap_is_wrap_angle_bit_for_bit(angles):
    a = np.array(angles)
    want = wrap_angle(a)
    got = np.array([wrap(x) for x in a])
    assert np.array_equal(got, want)
    assert ((got >= -math.pi) & (got < math.pi)).all()


@settings(max_examples=50, deadline=None)
@given(
    w=arrays(np.float64, st.integers(1, 60), elements=st.floats(0, 10)),
    offset=st.floats(0, 1, exclude_max=True),
    n=st.integers(1, 80),
)
def test_systematic_pick_is_searchsorted(w, offset, n):
    """The merge gives what a binary search per pointer gives, including zero-weight bins (never
    drawn) and pointers past the last bin (clipped)."""
    if w.sum() <= 0:
        w[0] = 1.0
    cdf = np.cumsum(w / w.sum())
    cdf /= cdf[-1]
    pointers = (offset + np.arange(n)) / n
    want = np.minimum(np.searchsorted(cdf, pointers, side="right"), cdf.size - 1)
    assert np.array_equal(systematic_pick(cdf, offset, n), want)


@settings(max_examples=50, deadline=None)
@given(
    p=arrays(np.float64, st.tuples(st.integers(1, 40), st.just(3)), elements=finite),
    raw=st.lists(st.floats(0.01, 10), min_size=40, max_size=40),
)
def test_pose_moments_match_the_numpy_formulas(p, raw):
    p[:, 2] = wrap_angle(p[:, 2])
    w = np.array(raw[: p.shape[0]])
    w /= w.sum()
    mean, cov = pose_moments(p, w, True)
    np.testing.assert_allclose(mean[:2], w @ p[:, :2], rtol=1e-12, atol=1e-9)
    theta = circular_mean(p[:, 2], w)
    assert abs(wrap_angle(mean[2] - theta)) <= 1e-9
    dev = p - mean
    dev[:, 2] = wrap_angle(dev[:, 2])
    np.testing.assert_allclose(cov, (dev * w[:, None]).T @ dev, rtol=1e-9, atol=1e-9)
    assert np.array_equal(pose_moments(p, w, False)[0], mean)


@settings(deadline=None)
@given(
    p=arrays(np.float64, st.tuples(st.integers(1, 20), st.just(3)), elements=finite),
    odo=arrays(np.float64, 3, elements=st.floats(-5, 5)),
)
def test_compose_into_matches_the_formula(p, odo):
    out = np.empty_like(p)
    compose_into(p, odo.reshape(1, 3), out)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    np.testing.assert_allclose(out[:, 0], p[:, 0] + c * odo[0] - s * odo[1], atol=1e-9)
    np.testing.assert_allclose(out[:, 1], p[:, 1] + s * odo[0] + c * odo[1], atol=1e-9)
    assert np.array_equal(out[:, 2], wrap_angle(p[:, 2] + odo[2]))


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.float64, st.integers(1, 40), elements=st.floats(-50.0, 0.0)),
    st.data(),
)
def test_bayes_update_matches_the_numpy_formulas(old, data):
    """Normalised log-weights, weights, the log mean likelihood and Kish's sum of squares as the
    numpy code computed them; NaN and +inf likelihoods count as impossible."""
    from mcl.step_kernels import bayes_update

    n = old.size
    old = old - np.log(np.exp(old).sum())  # normalised, as the filter keeps them
    choices = st.one_of(st.floats(-300.0, 10.0), st.sampled_from([np.nan, np.inf, -np.inf]))
    ll = np.array(data.draw(st.lists(choices, min_size=n, max_size=n)))
    lw, w = np.empty(n), np.empty(n)
    top, total, sum_w2 = bayes_update(old, ll, lw, w)
    want = old + np.where(np.isnan(ll) | (ll == np.inf), -np.inf, ll)
    assert top == want.max()
    if not np.isfinite(top):
        return
    np.testing.assert_allclose(total, np.exp(want - top).sum(), rtol=1e-12)
    expected_w = np.exp(want - top) / np.exp(want - top).sum()
    np.testing.assert_allclose(w, expected_w, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(np.exp(lw), expected_w, rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(sum_w2, np.dot(expected_w, expected_w), rtol=1e-12)
