"""Augmented MCL: short- and long-term averages of the measurement likelihood decide how many random
particles to inject (Probabilistic Robotics, Table 8.3; Gutmann & Fox 2002).

Every correction yields the weighted mean likelihood of the scan, ``sum_i w_i p(z | x_i)``. Two
exponential moving averages follow it, a slow one (``alpha_slow``) and a fast one
(``alpha_fast >> alpha_slow``):

    w_slow += alpha_slow * (w_avg - w_slow),    w_fast += alpha_fast * (w_avg - w_fast)

and each particle is replaced by a random free-space pose with probability
``max(0, 1 - w_fast / w_slow)``: when the scans have recently become much less likely than they
used to be, the filter is probably lost (kidnapped, or converged to the wrong place).

Start: both averages begin as the plain running mean of the values so far and switch to the
exponential average once ``1 / n`` drops below their alpha, so that ``w_slow`` soon reflects how
well the scans usually fit (instead of keeping the very first value for ~1 / alpha_slow updates).

Numerics: with the beam model's squash exponent and ~100 beams, ``p(z | x)`` is around e^-150 when
the filter is right and e^-350 when it is lost, and the ratio of two such numbers is not a useful
injection rate (it is 0 or 1). The averages here are therefore taken over the *per-beam geometric
mean likelihood before the squash*

    w_avg = exp(log(sum_i w_i p(z | x_i)) / (squash * K))      (K = beams used by the correction)

which lies in (0, 1) (about 0.03 when the scan fits with the lab's table, 0.02 after a kidnap)
and compares scans with different numbers of usable beams fairly. Undoing the squash keeps the
injection rate independent of how much the likelihood is tempered. The log of the mean likelihood is
computed in log space (`mcl.filter.particle_filter.ParticleFilter.last_log_mean_likelihood`), so
nothing underflows; a correction in which every particle was impossible gives w_avg = 0.

With both alphas at 0 augmented MCL is off: the injection probability is 0 and the filter draws
nothing extra from its random generator (it behaves exactly as the plain filter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from racecar_sim.settings.validation import short

__all__ = ["AugmentedParams", "LikelihoodAverages"]


@dataclass(frozen=True)
class AugmentedParams:
    """Settings of augmented MCL (module docstring).

    Attributes:
        alpha_slow: rate of the long-term average, per correction, in [0, 1).
        alpha_fast: rate of the short-term average, per correction, in [0, 1]; must exceed
            ``alpha_slow`` unless both are 0 (off).
    """

    alpha_slow: float = 0.0
    alpha_fast: float = 0.0

    def __post_init__(self) -> None:
        for name in ("alpha_slow", "alpha_fast"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= 1.0:
                raise ValueError(f"AugmentedParams.{name} = {short(v)} must lie in [0, 1]")
        if self.enabled and not self.alpha_fast > self.alpha_slow:
            raise ValueError(
                f"AugmentedParams: alpha_fast ({self.alpha_fast}) must exceed alpha_slow "
                f"({self.alpha_slow}) (Probabilistic Robotics: 0 <= alpha_slow << alpha_fast)"
            )

    @property
    def enabled(self) -> bool:
        """Whether augmented MCL is on (some alpha is not 0)."""
        return self.alpha_slow > 0.0 or self.alpha_fast > 0.0


class LikelihoodAverages:
    """The slow and fast averages of the per-beam likelihood and the injection probability.

    Args:
        params: `AugmentedParams`.

    Attributes:
        w_slow, w_fast: the averages (NaN before the first update). Each is the plain mean of the
            values so far until ``1 / n_updates`` falls below its alpha, then the exponential
            average (a bias-corrected start: with w_slow = the first value for its first 1000
            updates, the reference would be whatever the filter scored right after starting).
        n_updates: values folded in since the last reset.
    """

    def __init__(self, params: AugmentedParams) -> None:
        self.params = params
        self.w_slow = math.nan
        self.w_fast = math.nan
        self.n_updates = 0

    def reset(self) -> None:
        """Forget the history (after a new initialisation of the particles)."""
        self.w_slow = math.nan
        self.w_fast = math.nan
        self.n_updates = 0

    @staticmethod
    def per_beam(log_mean_likelihood: float, n_beams: int, exponent: float = 1.0) -> float:
        """exp(log_mean_likelihood / (exponent * n_beams)): the geometric mean likelihood of one
        beam before the squash ``exponent``; 1 when no beam was used (no information), 0 when
        every particle was impossible."""
        if n_beams <= 0:
            return 1.0
        if math.isnan(log_mean_likelihood) or log_mean_likelihood == -math.inf:
            return 0.0
        return math.exp(log_mean_likelihood / (exponent * n_beams))

    def update(self, log_mean_likelihood: float, n_beams: int, exponent: float = 1.0) -> float:
        """Fold one correction into the averages; returns its per-beam likelihood w_avg.

        Args:
            log_mean_likelihood: natural log of ``sum_i w_i p(z | x_i)`` (squashed likelihoods).
            n_beams: beams the correction used.
            exponent: the sensor model's squash exponent (undone, see the module docstring).
        """
        w = self.per_beam(log_mean_likelihood, n_beams, exponent)
        if not self.params.enabled:
            return w
        self.n_updates += 1
        if self.n_updates == 1:
            self.w_slow = self.w_fast = w
        else:
            rate = 1.0 / self.n_updates  # plain running mean until the alpha takes over
            self.w_slow += max(self.params.alpha_slow, rate) * (w - self.w_slow)
            self.w_fast += max(self.params.alpha_fast, rate) * (w - self.w_fast)
        return w

    @property
    def injection_probability(self) -> float:
        """max(0, 1 - w_fast / w_slow); 0 when off or before the first update."""
        if not self.params.enabled or math.isnan(self.w_slow) or not self.w_slow > 0.0:
            return 0.0
        return max(0.0, 1.0 - self.w_fast / self.w_slow)
