"""Resampling: pure functions (weights, rng) -> indexes of the particles to keep.

Each resampler draws ``n`` indexes (default: as many as there are weights) with
``E[count of i] = n * w_i / sum(w)``. They differ in variance:

``multinomial``
    n independent draws from the weights (the MIT RSS lab's ``np.random.choice``). Counts are
    multinomial: the most variance.
``systematic``
    Low-variance / systematic resampling (Probabilistic Robotics, Table 4.4; Kitagawa 1996): one
    uniform offset u in [0, 1/n), pointers u + k/n. Every count is floor(n w_i) or ceil(n w_i).
``stratified``
    One uniform draw inside each of the n strata [k/n, (k+1)/n) (Kitagawa 1996).

Multinomial and stratified are O(n log n) with ``np.searchsorted`` on the cumulative weights,
systematic one merge of its ascending pointers with them (numba). The particle filter draws through
`resample_particles()`, whose systematic path also copies the drawn particles in that kernel.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mcl.filter.step_kernels import systematic_pick, systematic_resample

__all__ = [
    "RESAMPLERS",
    "effective_sample_size",
    "multinomial",
    "normalize_weights",
    "resample",
    "resample_particles",
    "stratified",
    "systematic",
]


def normalize_weights(weights: np.ndarray) -> np.ndarray:
    """Weights (N,) divided by their sum, as float64.

    Raises:
        ValueError: the weights are not a non-empty 1-D array of finite non-negative numbers with a
            positive sum.
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    if not np.isfinite(w).all():
        raise ValueError("weights must be finite")
    if (w < 0).any():
        raise ValueError("weights must be non-negative")
    total = w.sum()
    if not total > 0:
        raise ValueError("weights must not all be zero")
    return w / total


def effective_sample_size(weights: np.ndarray) -> float:
    """Kish's effective sample size 1 / sum(w_i^2) of the normalised weights, in [1, N]."""
    w = normalize_weights(weights)
    return float(1.0 / np.dot(w, w))


def _cumulative(weights: np.ndarray) -> np.ndarray:
    cdf = np.cumsum(normalize_weights(weights))
    return cdf / cdf[-1]  # exactly 1 at the end despite rounding; zero-weight bins stay empty


def _pick(cdf: np.ndarray, pointers: np.ndarray) -> np.ndarray:
    """Index of the first bin whose cumulative weight exceeds each pointer in [0, 1), at most the
    first bin that reaches the end (a pointer that rounds up to 1 draws no empty bin)."""
    idx = np.searchsorted(cdf, pointers, side="right")
    return np.minimum(idx, np.searchsorted(cdf, cdf[-1]))


def _count(weights: np.ndarray, n: int | None) -> int:
    n = np.asarray(weights).shape[0] if n is None else n
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"number of draws must be a positive integer, got {n!r}")
    return int(n)


def multinomial(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """(n,) int64 indexes drawn independently with probability proportional to ``weights``."""
    n = _count(weights, n)
    return _pick(_cumulative(weights), rng.random(n))


def systematic(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """(n,) int64 indexes, sorted, by systematic (low-variance) resampling: one random offset."""
    n = _count(weights, n)
    return systematic_pick(_cumulative(weights), rng.random(), n)


def stratified(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """(n,) int64 indexes, sorted, by stratified resampling: one random draw per stratum."""
    n = _count(weights, n)
    pointers = (rng.random(n) + np.arange(n)) / n
    return _pick(_cumulative(weights), pointers)


RESAMPLERS: dict[str, Callable[..., np.ndarray]] = {
    "multinomial": multinomial,
    "systematic": systematic,
    "stratified": stratified,
}
"""Resamplers by name."""


def resample(
    method: str, weights: np.ndarray, rng: np.random.Generator, n: int | None = None
) -> np.ndarray:
    """Indexes from the resampler named ``method`` (one of `RESAMPLERS`)."""
    try:
        fn = RESAMPLERS[method]
    except KeyError:
        raise ValueError(
            f"unknown resampling method {method!r}; choose one of {sorted(RESAMPLERS)}"
        ) from None
    return fn(weights, rng, n)


def resample_particles(
    method: str, particles: np.ndarray, weights: np.ndarray, rng: np.random.Generator, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(idx, particles[idx])`` for ``idx = resample(method, weights, rng, n)``: the particle
    filter's step, for its own valid weights (not checked) and (N, 3) float64 particles; ``n``
    is checked as `resample()` checks it.

    ``"systematic"`` runs as one numba kernel (`mcl.filter.step_kernels.systematic_resample()`: the
    same draw of ``rng`` and the same indexes up to the rounding of the weights' sum, which is a
    running sum there and numpy's pairwise one in `systematic()`).
    """
    n = _count(weights, n)
    if method == "systematic":
        return systematic_resample(particles, weights, rng.random(), n)
    idx = resample(method, weights, rng, n)
    return idx, particles[idx]
