"""The numba random stream of the lidar noise: uniforms and ziggurat normals with the right laws."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from racecar_sim.raycast.rand import normals, seed_from, uniforms, uniforms_and_normals

N = 1_000_000


def _normal_cdf(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.vectorize(math.erf)(x / math.sqrt(2.0)))


def test_normals_follow_the_standard_normal_law() -> None:
    z = np.empty(N)
    normals(20260101, z)
    assert abs(z.mean()) < 5 / math.sqrt(N)
    assert abs(z.std() - 1.0) < 5 * math.sqrt(0.5 / N)
    # Kolmogorov-Smirnov distance on a thinned sorted sample (critical value ~1.63/sqrt(n) at 1 %)
    zs = np.sort(z)[::50]
    ks = np.abs(_normal_cdf(zs) - (np.arange(zs.size) + 0.5) / zs.size).max()
    assert ks < 1.63 / math.sqrt(zs.size)
    # The tail beyond the ziggurat's base (3.44) and the layers' edges come out at their rates.
    for k in (0.5, 1.0, 2.0, 3.0, 3.6):
        p = math.erfc(k / math.sqrt(2.0))
        assert abs((np.abs(z) > k).mean() - p) < 5 * math.sqrt(p * (1 - p) / N) + 1e-6


def test_uniforms_are_uniform_in_the_unit_interval() -> None:
    u = np.empty(N)
    uniforms(7, u)
    assert u.min() >= 0.0 and u.max() < 1.0
    counts = np.histogram(u, bins=50, range=(0.0, 1.0))[0]
    expected = N / 50
    chi2 = ((counts - expected) ** 2 / expected).sum()
    assert chi2 < 90  # 49 degrees of freedom: p ~ 3e-4


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**63 - 1))
def test_a_seed_gives_one_stream_and_another_seed_another(seed: int) -> None:
    a, b, c = np.empty(64), np.empty(64), np.empty(64)
    normals(seed, a)
    normals(seed, b)
    normals(seed ^ 1, c)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_seed_from_draws_from_the_generator() -> None:
    one, two = np.random.default_rng(3), np.random.default_rng(3)
    assert seed_from(one) == seed_from(two) >= 0
    assert seed_from(one) != seed_from(np.random.default_rng(4))


def test_the_scans_uniforms_and_normals_follow_their_laws() -> None:
    u, z = np.empty(N), np.empty(N)
    uniforms_and_normals(99, u, z)
    assert u.min() >= 0.0 and u.max() < 1.0
    assert abs(u.mean() - 0.5) < 5 * math.sqrt(1 / 12 / N)
    assert abs(z.mean()) < 5 / math.sqrt(N)
    assert abs(z.std() - 1.0) < 5 * math.sqrt(0.5 / N)
    zs = np.sort(z)[::50]
    ks = np.abs(_normal_cdf(zs) - (np.arange(zs.size) + 0.5) / zs.size).max()
    assert ks < 1.63 / math.sqrt(zs.size)
    for k in (1.0, 3.0, 3.6):  # inside the layers, and the tail beyond the base
        p = math.erfc(k / math.sqrt(2.0))
        assert abs((np.abs(z) > k).mean() - p) < 5 * math.sqrt(p * (1 - p) / N) + 1e-6
    assert abs(np.corrcoef(u, z)[0, 1]) < 5 / math.sqrt(N)  # a beam's two draws independent
    again_u, again_z = np.empty(1000), np.empty(1000)
    uniforms_and_normals(99, again_u, again_z)
    assert np.array_equal(again_u, u[:1000]) and np.array_equal(again_z, z[:1000])
