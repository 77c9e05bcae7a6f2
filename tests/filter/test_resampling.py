"""Resamplers: indexes in range, expected counts preserved, variance ordering, input checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mcl.filter.resampling import (
    RESAMPLERS,
    effective_sample_size,
    multinomial,
    normalize_weights,
    resample,
    stratified,
    systematic,
)

weight_arrays = arrays(
    np.float64,
    st.integers(1, 60),
    elements=st.floats(0.0, 1e3, allow_nan=False, allow_infinity=False),
).filter(lambda w: w.sum() > 0)


@settings(max_examples=60)
@given(weight_arrays, st.sampled_from(sorted(RESAMPLERS)), st.integers(0, 2**32 - 1))
def test_indexes_in_range_and_never_zero_weight(w: np.ndarray, method: str, seed: int) -> None:
    idx = resample(method, w, np.random.default_rng(seed))
    assert idx.shape == w.shape
    assert np.issubdtype(idx.dtype, np.integer)
    assert idx.min() >= 0 and idx.max() < len(w)
    assert np.all(w[idx] > 0)


@settings(max_examples=60)
@given(weight_arrays, st.integers(1, 200), st.integers(0, 2**32 - 1))
def test_systematic_counts_are_floor_or_ceil_of_expectation(
    w: np.ndarray, n: int, seed: int
) -> None:
    counts = np.bincount(systematic(w, np.random.default_rng(seed), n), minlength=len(w))
    expected = n * w / w.sum()
    assert counts.sum() == n
    # floor/ceil of n * w_i, with a hair of slack for rounding in the cumulative sum
    assert np.all(counts >= np.floor(expected - 1e-9))
    assert np.all(counts <= np.ceil(expected + 1e-9))


@settings(max_examples=40)
@given(weight_arrays, st.integers(1, 200), st.integers(0, 2**32 - 1))
def test_stratified_counts_within_one_of_expectation_plus_strata(w, n, seed) -> None:
    counts = np.bincount(stratified(w, np.random.default_rng(seed), n), minlength=len(w))
    expected = n * w / w.sum()
    assert counts.sum() == n
    # each bin spans at most ceil(n w_i) + 1 strata, each giving at most one draw to it
    assert np.all(counts <= np.ceil(expected + 1e-9) + 1)


@pytest.mark.parametrize("method", sorted(RESAMPLERS))
def test_expected_counts_are_preserved(method: str) -> None:
    """Mean count of each index over many draws is n w_i, within 5 standard errors."""
    rng = np.random.default_rng(11)
    w = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625 - 0.01, 0.01])
    n, reps = 200, 2000
    counts = np.array([np.bincount(resample(method, w, rng, n), minlength=6) for _ in range(reps)])
    expected = n * w
    # multinomial variance n w (1 - w) bounds the other two schemes' variance
    se = np.sqrt(n * w * (1 - w) / reps)
    assert np.all(np.abs(counts.mean(axis=0) - expected) < 5 * se + 1e-12)


def test_low_variance_schemes_have_lower_variance() -> None:
    rng = np.random.default_rng(12)
    w = rng.random(50) ** 3
    var = {}
    for method in RESAMPLERS:
        counts = np.array([np.bincount(resample(method, w, rng), minlength=50) for _ in range(500)])
        var[method] = counts.var(axis=0).sum()
    assert var["systematic"] < var["stratified"] < var["multinomial"]


def test_one_hot_weights_always_pick_that_particle() -> None:
    w = np.zeros(10)
    w[7] = 3.0
    for fn in (multinomial, systematic, stratified):
        assert np.all(fn(w, np.random.default_rng(0)) == 7)


def test_multinomial_counts_chi_square() -> None:
    rng = np.random.default_rng(13)
    w = np.array([1.0, 2.0, 3.0, 4.0])
    n = 100_000
    counts = np.bincount(multinomial(w, rng, n), minlength=4)
    expected = n * w / w.sum()
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    assert chi2 < 16.27  # 99.9 % quantile of chi-square with 3 degrees of freedom


def test_effective_sample_size() -> None:
    assert effective_sample_size(np.ones(40)) == pytest.approx(40.0)
    assert effective_sample_size(np.eye(1, 40, 3)[0]) == pytest.approx(1.0)
    assert effective_sample_size(np.array([1.0, 1.0, 0.0, 0.0])) == pytest.approx(2.0)


@given(weight_arrays)
def test_normalized_weights_sum_to_one(w: np.ndarray) -> None:
    nw = normalize_weights(w)
    assert math.isclose(nw.sum(), 1.0, rel_tol=1e-12)
    assert np.all(nw >= 0)
    assert 1.0 - 1e-9 <= effective_sample_size(w) <= len(w) * (1 + 1e-9)


def test_seeded_draws_repeat() -> None:
    w = np.random.default_rng(1).random(100)
    for method in RESAMPLERS:
        a = resample(method, w, np.random.default_rng(5))
        b = resample(method, w, np.random.default_rng(5))
        np.testing.assert_array_equal(a, b)


def test_bad_weights_raise() -> None:
    rng = np.random.default_rng()
    with pytest.raises(ValueError, match="non-negative"):
        systematic(np.array([0.5, -0.1]), rng)
    with pytest.raises(ValueError, match="finite"):
        multinomial(np.array([0.5, np.nan]), rng)
    with pytest.raises(ValueError, match="all be zero"):
        stratified(np.zeros(3), rng)
    with pytest.raises(ValueError, match="1-D"):
        systematic(np.ones((2, 2)), rng)
    with pytest.raises(ValueError, match="positive integer"):
        systematic(np.ones(3), rng, 0)
    with pytest.raises(ValueError, match="unknown resampling method"):
        resample("residual-ish", np.ones(3), rng)
