"""The filter's belief: the weighted particle cloud and what is read from it (the mean pose, the
covariance, the clusters and ambiguity flag of [`mcl.filter.uncertainty`][mcl.filter.uncertainty]).

[`Belief`][mcl.filter.belief.Belief] is a base of
[`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter], which replaces the particles and
weights (never writing them in place, so their identity keys the memos here). Frames and units:
world poses [x, y, theta] (metres, radians, theta in [-pi, pi)).
"""

from __future__ import annotations

import numpy as np

from mcl.filter.params import ParticleFilterParams
from mcl.filter.step_kernels import covariance_about, pose_moments
from mcl.filter.uncertainty import Uncertainty, assess

__all__ = ["Belief"]


class Belief:
    """The weighted cloud's read-outs (fields set by the filter: ``_particles``, ``_weights``,
    the memos ``_mean_memo`` and ``_ess_memo``, ``params``)."""

    params: ParticleFilterParams
    _particles: np.ndarray | None
    _weights: np.ndarray | None
    _mean_memo: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    _ess_memo: tuple[np.ndarray | None, float]

    def _require(self) -> tuple[np.ndarray, np.ndarray]:
        if self._particles is None or self._weights is None:
            raise RuntimeError("the particle filter has no particles: call initialize() first")
        return self._particles, self._weights

    @property
    def particles(self) -> np.ndarray:
        """(N, 3) world poses [x, y, theta] (metres, radians), read-only view."""
        p = self._require()[0].view()
        p.flags.writeable = False
        return p

    @property
    def weights(self) -> np.ndarray:
        """(N,) normalised weights (sum 1), read-only view."""
        w = self._require()[1].view()
        w.flags.writeable = False
        return w

    @property
    def n_particles(self) -> int:
        """Current number of particles."""
        return int(self._require()[0].shape[0])

    @property
    def effective_sample_size(self) -> float:
        """Kish's 1 / sum(w^2), in [1, N] (the last weight update's while its weights stand)."""
        w = self._require()[1]
        return self._ess_memo[1] if w is self._ess_memo[0] else float(1.0 / np.dot(w, w))

    def estimate(self) -> np.ndarray:
        """(3,) weighted mean pose [x, y, theta]: arithmetic mean of x, y, circular mean of theta."""
        return self._mean().copy()

    def covariance(self) -> np.ndarray:
        """(3, 3) weighted covariance of the particles about `estimate()` (metres, radians).

        Heading deviations are wrapped to [-pi, pi) around the circular mean, so a cloud straddling
        +-pi has a small theta variance. Normalised by sum(w) = 1 (the maximum-likelihood form).
        """
        p, w = self._require()
        return covariance_about(p, w, self._mean())

    def _mean(self) -> np.ndarray:
        """The weighted mean pose, computed once per set of particles and weights (both are only
        ever replaced, never written in place, so their identity tells)."""
        p, w = self._require()
        memo = self._mean_memo
        if memo is None or memo[0] is not p or memo[1] is not w:
            memo = (p, w, pose_moments(p, w, False)[0])
            self._mean_memo = memo
        return memo[2]

    def uncertainty(self) -> Uncertainty:
        """Covariance, clusters and ambiguity flag of the cloud ([`mcl.filter.uncertainty.assess()`][mcl.filter.uncertainty.assess])."""
        p, w = self._require()
        return assess(p, w, self.covariance(), self.params.clusters)
