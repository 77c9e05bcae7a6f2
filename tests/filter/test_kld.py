"""KLD-sampling: the sample-size bound, the bins, and the sequential stopping rule."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.kld import KLDParams, bin_keys, kld_bound, kld_stop

BINS = (0.5, 0.5, math.radians(10.0))


@pytest.mark.parametrize("k", [2, 5, 20, 200])
def test_bound_is_the_chi_square_quantile_over_two_epsilon(k: int) -> None:
    """Fox 2003: n = chi2_{k-1, 1-delta} / (2 epsilon); checked against sampled chi-square values."""
    params = KLDParams(epsilon=0.05, delta=0.01)
    rng = np.random.default_rng(k)
    quantile = np.quantile(rng.chisquare(k - 1, 400_000), 1 - params.delta)
    expected = quantile / (2 * params.epsilon)
    assert kld_bound(k, params.epsilon, params.z) == pytest.approx(expected, rel=0.03, abs=2)


def test_bound_grows_with_bins_and_with_a_tighter_epsilon() -> None:
    z = KLDParams().z
    k = np.arange(1, 500)
    n = kld_bound(k, 0.05, z)
    assert n[0] == 1
    assert np.all(np.diff(n) >= 0) and n[-1] > n[1]
    assert np.all(kld_bound(k[1:], 0.02, z) > n[1:])


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(-50, 50, allow_nan=False),
            st.floats(-50, 50, allow_nan=False),
            st.floats(-math.pi, math.pi, allow_nan=False, exclude_max=True),
        ),
        min_size=2,
        max_size=30,
    )
)
def test_keys_are_equal_exactly_for_poses_in_the_same_bin(poses) -> None:
    p = np.array(poses, dtype=np.float64)
    keys = bin_keys(p, BINS)
    cells = [
        (math.floor(x / BINS[0]), math.floor(y / BINS[1]), math.floor((t + math.pi) / BINS[2]))
        for x, y, t in p
    ]
    for i in range(len(p)):
        for j in range(len(p)):
            assert (keys[i] == keys[j]) == (cells[i] == cells[j])
    assert np.all(keys >= 0)
    np.testing.assert_array_equal(bin_keys(p[::-1], BINS), keys[::-1])  # absolute, not relative


def test_one_bin_stops_at_the_minimum_and_new_bins_keep_drawing() -> None:
    params = KLDParams(min_particles=50)
    assert kld_stop(np.zeros(400, dtype=np.int64), params) == 50
    distinct = np.arange(5000, dtype=np.int64)  # every draw opens a new bin
    assert kld_stop(distinct, params) is None
    random_draws = -np.ones(5000, dtype=np.int64)  # random particles count as new bins too
    assert kld_stop(random_draws, params) is None


def test_stopping_point_satisfies_the_bound_first() -> None:
    params = KLDParams(min_particles=10)
    rng = np.random.default_rng(0)
    keys = rng.integers(0, 40, 3000)  # about 40 bins
    n = kld_stop(keys, params)
    assert n is not None
    seen = [len(set(keys[:m].tolist())) for m in range(1, n + 1)]
    bounds = kld_bound(np.array(seen), params.epsilon, params.z)
    assert n >= bounds[-1]
    assert all(
        m < b or m < params.min_particles for m, b in zip(range(1, n), bounds[:-1], strict=True)
    )


def test_bad_settings_are_named() -> None:
    with pytest.raises(ValueError, match="epsilon"):
        KLDParams(epsilon=0.0)
    with pytest.raises(ValueError, match="delta"):
        KLDParams(delta=1.0)
    with pytest.raises(ValueError, match="bin_size"):
        KLDParams(bin_size=(0.5, 0.0, 0.1))
    with pytest.raises(ValueError, match="max_particles"):
        KLDParams(min_particles=100, max_particles=10)
