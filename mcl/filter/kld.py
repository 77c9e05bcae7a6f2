"""KLD-sampling: how many particles the belief needs (Fox, "Adapting the sample size in particle
filters through KLD-sampling", IJRR 2003; Probabilistic Robotics, Table 8.4).

The pose space is cut into bins (``bin_size``: x metres, y metres, theta radians, world frame).
If the belief occupies k bins, then n(k) samples drawn from it keep the Kullback-Leibler divergence
between the sample-based maximum-likelihood estimate and the true (binned) belief below ``epsilon``
with probability ``1 - delta`` (Wilson-Hilferty approximation of the chi-square quantile):

    n(k) = (k - 1) / (2 epsilon) * (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z_{1-delta})^3

Fox draws samples one at a time, counting the bins they fall in, and stops once the sample count
reaches n(k) for the bins seen so far. `kld_stop()` does the same on a batch of independent
draws without a Python loop: the number of distinct bins among the first m draws is a cumulative
sum of first-occurrence flags, and the answer is the first m with m >= n(k(m)). (The caller draws
batches of growing size until the rule stops or the maximum is reached.) With augmented MCL some
draws are random free-space poses; each counts as a bin of its own (amcl does the same by drawing
them inside the KLD loop), so a filter that is lost grows its particle set.

A spread-out belief (after a global initialisation, or with injected random particles) occupies
many bins and keeps many particles; a converged one occupies a few and needs only a few hundred.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from mcl.filter.angles import wrap_angle
from mcl.filter.resampling import multinomial
from racecar_sim.settings.validation import short

__all__ = ["KLDParams", "bin_keys", "kld_bound", "kld_count", "kld_stop"]


def _positive_triple(value: tuple[float, ...], name: str) -> tuple[float, float, float]:
    values = tuple(float(v) for v in value)
    if len(values) != 3 or not all(math.isfinite(v) and v > 0 for v in values):
        raise ValueError(
            f"{name} must be three positive numbers (x m, y m, theta rad), got {value!r}"
        )
    return values  # type: ignore[return-value]


@dataclass(frozen=True)
class KLDParams:
    """Settings of KLD-sampling (see the module docstring).

    Attributes:
        enabled: choose the particle count at every resampling by KLD-sampling; when False the
            count stays as it is (the plain filter).
        epsilon: bound on the KL divergence between the particle estimate and the belief.
        delta: the bound holds with probability 1 - delta.
        bin_size: bin edges (x metres, y metres, theta radians); Fox used 0.5 m x 0.5 m x 10 deg.
        min_particles: never fewer particles than this (a converged cloud still needs some spread
            to follow the odometry's errors).
        max_particles: never more than this; None = the filter's global particle count (see
            [`mcl.filter.particle_filter.ParticleFilter.global_particle_count()`][mcl.filter.particle_filter.ParticleFilter.global_particle_count]).
    """

    enabled: bool = False
    epsilon: float = 0.05
    delta: float = 0.01
    bin_size: tuple[float, float, float] = (0.5, 0.5, math.radians(10.0))
    min_particles: int = 500
    max_particles: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ValueError(f"KLDParams.enabled = {short(self.enabled)} must be true or false")
        if not (isinstance(self.epsilon, int | float) and 0 < self.epsilon < math.inf):
            raise ValueError(f"KLDParams.epsilon = {short(self.epsilon)} must be a positive number")
        if not (isinstance(self.delta, int | float) and 0 < self.delta < 1):
            raise ValueError(f"KLDParams.delta = {short(self.delta)} must lie in (0, 1)")
        object.__setattr__(self, "bin_size", _positive_triple(self.bin_size, "KLDParams.bin_size"))
        lo = self.min_particles
        if isinstance(lo, bool) or not isinstance(lo, int) or lo < 1:
            raise ValueError(f"KLDParams.min_particles = {short(lo)} must be a positive integer")
        hi = self.max_particles
        if hi is not None and (isinstance(hi, bool) or not isinstance(hi, int) or hi < lo):
            raise ValueError(
                f"KLDParams.max_particles = {short(hi)} must be None or an integer >= min_particles "
                f"({lo})"
            )

    @property
    def z(self) -> float:
        """Upper 1 - delta quantile of the standard normal distribution."""
        return NormalDist().inv_cdf(1.0 - self.delta)


def kld_bound(k: np.ndarray | int, epsilon: float, z: float) -> np.ndarray:
    """Samples n(k) needed for ``k`` occupied bins (module docstring); 1 for k <= 1. Vectorised."""
    k = np.asarray(k, dtype=np.float64)
    km1 = np.maximum(k - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    n = km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(k <= 1.0, 1.0, np.ceil(n))


_KEY_OFFSET = 1 << 20  # bins either side of the world origin that keys tell apart
_KEY_SPAN = 1 << 21


def bin_keys(poses: np.ndarray, bin_size: tuple[float, float, float]) -> np.ndarray:
    """(N,) non-negative int64 keys, equal exactly when two world poses (N, 3) share a bin.

    Keys are absolute (the same bin gets the same key in every call). Theta bins start at -pi, so
    a bin never straddles the +-pi seam. Positions more than 2^20 bins from the world origin (500
    km for 0.5 m bins) are clipped to the last bin.
    """
    poses = np.asarray(poses, dtype=np.float64)
    sx, sy, st = bin_size
    n_theta = max(1, math.ceil(2.0 * math.pi / st))
    lim = _KEY_OFFSET - 1
    bx = np.clip(np.floor(poses[:, 0] / sx), -lim, lim).astype(np.int64) + _KEY_OFFSET
    by = np.clip(np.floor(poses[:, 1] / sy), -lim, lim).astype(np.int64) + _KEY_OFFSET
    bt = np.floor((wrap_angle(poses[:, 2]) + math.pi) / st).astype(np.int64)
    bt = np.minimum(bt, n_theta - 1)
    return (bx * _KEY_SPAN + by) * n_theta + bt  # < 2^42 * n_theta: no overflow


def kld_stop(keys: np.ndarray, params: KLDParams) -> int | None:
    """Fox's stopping rule on a sequence of draws given by their bin ``keys`` (M,) in draw order.

    Negative keys mark draws that always open a new bin (random particles of augmented MCL).
    Returns the first count m >= ``params.min_particles`` with m >= n(k(m)), where k(m) is the
    number of distinct bins among the first m draws; None when no m <= M qualifies.
    """
    keys = np.asarray(keys, dtype=np.int64)
    m_total = keys.shape[0]
    if m_total == 0:
        return None
    is_new = keys < 0
    real = np.flatnonzero(~is_new)
    if real.size:
        _, first = np.unique(keys[real], return_index=True)
        is_new[real[first]] = True
    k = np.cumsum(is_new)
    m = np.arange(1, m_total + 1)
    done = (m >= kld_bound(k, params.epsilon, params.z)) & (m >= params.min_particles)
    hits = np.flatnonzero(done)
    return int(m[hits[0]]) if hits.size else None


def kld_count(
    particles: np.ndarray,
    weights: np.ndarray,
    params: KLDParams,
    n_max: int,
    rng: np.random.Generator,
    p_random: float = 0.0,
) -> tuple[int, int]:
    """(particles, of which random) that KLD-sampling asks for.

    Draws batches of the weighted particles (N, 3) (multinomial, independent), each draw replaced
    with probability ``p_random`` by a random pose that counts as a bin of its own, doubling the
    batch until Fox's rule (`kld_stop()`) stops or ``n_max`` draws are made.
    """
    keys = np.empty(0, dtype=np.int64)
    random = np.empty(0, dtype=bool)
    batch = min(max(params.min_particles, particles.shape[0]), n_max)
    while True:
        draws = particles[multinomial(weights, rng, batch)]
        new_keys = bin_keys(draws, params.bin_size)
        is_random = rng.random(batch) < p_random if p_random > 0.0 else np.zeros(batch, bool)
        new_keys[is_random] = -1
        keys = np.concatenate([keys, new_keys])
        random = np.concatenate([random, is_random])
        n = kld_stop(keys, params)
        if n is not None or keys.size >= n_max:
            n = min(n if n is not None else n_max, n_max)
            return n, int(np.count_nonzero(random[:n]))
        batch = min(keys.size, n_max - keys.size)
