"""Resampling that keeps a search's rival places alive.

A global search weighs thousands of poses spread over the map. One scan's log-likelihood differs
between places by tens to hundreds of nats, so plain resampling puts every particle on the few
poses that fit the first scan or two best: a place drawn near the car but a little off is gone
before later scans could prefer it, and the search settles on a look-alike (traced on an honest
kidnap in docs/recovery.md: half a second after a plain search started, none of its 15 800
particles lay near the car with its heading).

[resample_keeping_places][mcl.filter.place_keeping.resample_keeping_places] divides the poses
into *places* (cells of ``cell_m`` x ``cell_m`` metres in the world frame and ``headings``
heading sectors) and draws from a proposal that gives every place ``draws`` draws, spread over
its particles by weight, and the rest of the draws by weight (the places' draws together at
most ``share`` of them). Each drawn particle carries its weight divided by the proposal's, so the
belief is unchanged in expectation: every place keeps its share of the weight and the weighted
estimate stays where the evidence puts it; only which places keep particles changes. A later
scan that favours a kept place moves the weight there without having to find it again.

Frames and units: world poses [x m, y m, theta rad]; log-weights in nats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcl.filter.resampling import systematic

__all__ = ["PlaceKeeping", "place_index", "resample_keeping_places"]


@dataclass(frozen=True)
class PlaceKeeping:
    """How a resampling keeps rival places (module docstring).

    Attributes:
        cell_m: metres; the side of a place's square cell in the world frame.
        headings: heading sectors per cell (each 2 pi / headings radians).
        draws: draws each place with particles is given (spread over them by weight).
        share: the most of a resampling's draws the places' draws may take together, in
            (0, 1): with more places than ``share`` x n / ``draws``, each gets fewer.
    """

    cell_m: float = 2.0
    headings: int = 8
    draws: float = 4.0
    share: float = 0.5

    def __post_init__(self) -> None:
        for name, low, high in (("cell_m", 0.0, 1000.0), ("draws", 0.0, 1e6)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not low < value <= high:
                raise ValueError(f"PlaceKeeping.{name} = {value!r} must lie in ({low:g}, {high:g}]")
        if isinstance(self.headings, bool) or not isinstance(self.headings, int) or not 1 <= self.headings <= 360:
            raise ValueError(f"PlaceKeeping.headings = {self.headings!r} must be an integer in [1, 360]")
        if isinstance(self.share, bool) or not isinstance(self.share, int | float) or not 0 < self.share < 1:
            raise ValueError(f"PlaceKeeping.share = {self.share!r} must lie in (0, 1)")


def place_index(particles: np.ndarray, keeping: PlaceKeeping) -> np.ndarray:
    """(N,) int64: the place of each world pose (row [x m, y m, theta rad]), numbered 0, 1, ...
    in order of (cell x, cell y, heading sector)."""
    p = np.asarray(particles, dtype=np.float64)
    ix = np.floor(p[:, 0] / keeping.cell_m).astype(np.int64)
    iy = np.floor(p[:, 1] / keeping.cell_m).astype(np.int64)
    sector = 2.0 * math.pi / keeping.headings
    ih = np.floor(np.mod(p[:, 2], 2.0 * math.pi) / sector).astype(np.int64) % keeping.headings
    ix -= ix.min()
    iy -= iy.min()
    key = (ix * (int(iy.max()) + 1) + iy) * keeping.headings + ih
    return np.unique(key, return_inverse=True)[1].astype(np.int64).reshape(-1)


def resample_keeping_places(
    particles: np.ndarray,
    log_weights: np.ndarray,
    rng: np.random.Generator,
    n: int,
    keeping: PlaceKeeping,
) -> tuple[np.ndarray, np.ndarray]:
    """Draw ``n`` particles so that every place keeps particles (module docstring).

    Args:
        particles: (N, 3) world poses.
        log_weights: (N,) log-weights (nats; any offset; the largest finite).
        rng: the generator of the systematic draw.
        n: particles to draw.
        keeping: the places and their draws.

    Returns:
        (n,) indexes of the drawn particles and (n,) their log-weights (normalised: the weights
        sum to 1), each its weight over the proposal's. A place's particles are drawn side by
        side, so a place whose proposal share is q keeps floor(n q) or ceil(n q) particles: at
        least floor(``draws``) while ``share`` allows that many for every place.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    lw = lw - lw.max()
    place = place_index(particles, keeping)
    n_places = int(place.max()) + 1
    best = np.full(n_places, -np.inf)
    np.maximum.at(best, place, lw)
    alive = np.isfinite(best)  # a place of impossible particles only gets no draws
    live = alive[place]
    relative = np.zeros_like(lw)  # within its place; the best of each place is 1
    relative[live] = np.exp(lw[live] - best[place[live]])
    total = np.bincount(place, relative, minlength=n_places)
    within = np.where(live, relative / np.where(alive, total, 1.0)[place], 0.0)
    weight = np.exp(lw)
    weight /= weight.sum()
    per_place = min(float(keeping.draws), keeping.share * n / int(alive.sum()))
    kept = per_place * int(alive.sum()) / n
    proposal = (1.0 - kept) * weight + (per_place / n) * within
    order = np.argsort(place, kind="stable")  # a place's particles side by side
    drawn = order[systematic(proposal[order], rng, n)]
    new = lw[drawn] - np.log(proposal[drawn])
    top = new.max()
    new -= top + math.log(np.exp(new - top).sum())
    return drawn, new
