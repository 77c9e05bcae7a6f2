"""A bound on how much one beam can say about which particle is right, decided over the cloud.

The beam model multiplies the beams' likelihoods as if each were independent evidence. Where the
map is out of date, that lets a few beams outvote the rest: a beam that passes through a wall the
world no longer has returns long from the car's true pose (a near-random return, about
-3.4 in the squashed log table) and ends on that wall from a pose beside it (a hit, about -0.9),
so each such beam moves the weights by 2.5 in log-likelihood, scan after scan, and a third of the
beams doing so drags the cloud off the car (docs/localization_changing_world.md).

`bounded_scores()` caps each beam's say *relative to the cloud*: per beam ``b`` the best
log-likelihood over the particles, ``best_b``, is found first, and every particle's term is
raised to at least ``best_b - bound``. A beam that one particle explains and another does not
separates them by ``bound`` at most; a beam no particle explains (all near the random floor)
says next to nothing about which of them is right; small differences (a hit a few centimetres
off) count in full. The terms come from the caster's fused cast-and-score pass
([RayCaster][racecar_sim.raycast.RayCaster]'s ``cast_score`` with ``terms``), so the bound costs one
more pass over the (N, K) terms. ``bound`` is in the units of the sensor model's log table (natural log,
after the squash exponent): the table's hit peak lies about 2.5 above its floor, so a bound of
0.5 keeps a fifth of a beam's range. The sums without the bound come out of the same pass, for
the likelihood averages (augmented MCL, the adaptive filter), which must stay the model's own.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["bounded_scores"]


@nb.njit(cache=True)
def bounded_scores(terms, bound, out):
    """``out[i] = sum_b max(terms[i, b], max_j terms[j, b] - bound)``: each beam's term at most
    ``bound`` under the cloud's best for that beam.

    Args:
        terms (np.ndarray): (N, K) float64 per-particle, per-beam log-likelihoods (the sensor model's
            squashed log table looked up at each ray's expected range).
        bound (float): how far under the cloud's best a beam's term may fall (log units, >= 0).
        out (np.ndarray): (N,) float64 output, the bounded sums.
    """
    n, k = terms.shape
    best = np.full(k, -np.inf)
    for i in range(n):
        for b in range(k):
            if terms[i, b] > best[b]:
                best[b] = terms[i, b]
    for b in range(k):
        best[b] -= bound
    for i in range(n):
        total = 0.0
        for b in range(k):
            value = terms[i, b]
            total += value if value > best[b] else best[b]
        out[i] = total
