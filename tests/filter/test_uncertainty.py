"""Clusters of a particle cloud and the ambiguity flag."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.angles import wrap_angle
from mcl.filter.uncertainty import ClusterParams, assess, cluster_particles

PARAMS = ClusterParams()


def _cloud(rng, centre, n, sd=(0.05, 0.05, 0.02)) -> np.ndarray:
    p = np.asarray(centre) + rng.standard_normal((n, 3)) * np.asarray(sd)
    p[:, 2] = wrap_angle(p[:, 2])
    return p


def _cov(p: np.ndarray, w: np.ndarray) -> np.ndarray:
    mean = np.array(
        [w @ p[:, 0], w @ p[:, 1], math.atan2(w @ np.sin(p[:, 2]), w @ np.cos(p[:, 2]))]
    )
    dev = p - mean
    dev[:, 2] = wrap_angle(dev[:, 2])
    return (dev * w[:, None]).T @ dev


def test_two_separate_blobs_are_two_clusters_with_their_weights_and_means() -> None:
    rng = np.random.default_rng(0)
    a, b = _cloud(rng, [1.0, 2.0, 0.3], 700), _cloud(rng, [8.0, -3.0, -2.0], 300)
    p = np.vstack([a, b])
    w = np.full(1000, 1 / 1000)
    c = cluster_particles(p, w, PARAMS.bin_size)
    assert len(c.weights) == 2
    np.testing.assert_allclose(c.weights, [0.7, 0.3])
    np.testing.assert_array_equal(c.sizes, [700, 300])
    np.testing.assert_allclose(c.means[0, :2], a[:, :2].mean(axis=0), atol=1e-9)
    np.testing.assert_allclose(c.means[1, :2], b[:, :2].mean(axis=0), atol=1e-9)
    assert np.all(c.labels[:700] == 0) and np.all(c.labels[700:] == 1)
    u = assess(p, w, _cov(p, w), PARAMS)
    assert u.ambiguous and u.n_clusters == 2
    assert u.top_weight == pytest.approx(0.7) and u.second_weight == pytest.approx(0.3)


def test_a_cloud_across_plus_minus_pi_is_one_cluster() -> None:
    rng = np.random.default_rng(1)
    p = _cloud(rng, [3.0, 3.0, math.pi - 0.01], 2000, sd=(0.05, 0.05, 0.05))
    assert np.any(p[:, 2] < 0) and np.any(p[:, 2] > 0)
    w = np.full(len(p), 1 / len(p))
    c = cluster_particles(p, w, PARAMS.bin_size)
    assert c.weights[0] == pytest.approx(1.0)
    assert abs(wrap_angle(c.means[0, 2] - (math.pi - 0.01))) < 0.005
    u = assess(p, w, _cov(p, w), PARAMS)
    assert not u.ambiguous and u.n_clusters == 1


def test_opposite_headings_at_one_place_are_ambiguous() -> None:
    rng = np.random.default_rng(2)
    p = np.vstack([_cloud(rng, [3, 3, 0.0], 500), _cloud(rng, [3, 3, math.pi / 2 + 2.0], 500)])
    w = np.full(1000, 1e-3)
    u = assess(p, w, _cov(p, w), PARAMS)
    assert u.n_clusters == 2 and u.ambiguous


def test_a_long_smear_is_ambiguous_by_its_spread_and_stray_particles_are_not() -> None:
    rng = np.random.default_rng(3)
    smear = np.column_stack([rng.uniform(0, 30, 3000), rng.normal(1, 0.05, 3000), np.zeros(3000)])
    w = np.full(3000, 1 / 3000)
    u = assess(smear, w, _cov(smear, w), PARAMS)
    assert u.ambiguous and u.position_sd > 5.0
    tight = _cloud(rng, [5.0, 5.0, 1.0], 990)
    stray = np.column_stack([rng.uniform(-20, 20, (10, 2)), rng.uniform(-3, 3, 10)])
    p = np.vstack([tight, stray])
    w = np.r_[np.full(990, 1.0), np.full(10, 1e-9)]
    w /= w.sum()
    u = assess(p, w, _cov(p, w), PARAMS)
    assert not u.ambiguous and u.n_clusters == 1  # light strays are not clusters


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 400), st.integers(0, 2**31))
def test_cluster_weights_sum_to_one_and_do_not_depend_on_order(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.uniform(0, 8, (n, 2)), rng.uniform(-math.pi, math.pi, n)])
    w = rng.random(n) + 1e-3
    w /= w.sum()
    c = cluster_particles(p, w, PARAMS.bin_size)
    assert c.weights.sum() == pytest.approx(1.0)
    assert np.all(np.diff(c.weights) <= 1e-12)
    np.testing.assert_allclose(np.bincount(c.labels, weights=w), c.weights)
    perm = rng.permutation(n)
    c2 = cluster_particles(p[perm], w[perm], PARAMS.bin_size)
    np.testing.assert_allclose(np.sort(c2.weights), np.sort(c.weights))


def test_bad_input_is_named() -> None:
    with pytest.raises(ValueError, match="bin_size"):
        ClusterParams(bin_size=(0.5, 0.5))
    with pytest.raises(ValueError, match="ambiguous_weight"):
        ClusterParams(ambiguous_weight=1.5)
    with pytest.raises(ValueError, match="particles"):
        cluster_particles(np.zeros((0, 3)), np.zeros(0), PARAMS.bin_size)
