"""How trustworthy a particle cloud is: its covariance, its clusters, and an ambiguity flag.

Clusters are the connected components of the occupied cells of a pose grid (``bin_size``: x metres,
y metres, theta radians, world frame; the 26 neighbours of a cell touch it, theta wraps around at
+-pi). A cluster's weight is the sum of its particles' weights; clusters lighter than
``min_weight`` (a few stray or freshly injected particles) are not counted.

The cloud is *ambiguous* when the pose is not pinned down to one place:

- a second cluster holds at least ``ambiguous_weight`` of the weight (e.g. the two ends of a
  symmetric corridor, or a heading and its opposite), or
- the position standard deviation (square root of the largest eigenvalue of the x-y covariance)
  exceeds ``max_position_sd`` metres (one long smeared cluster along a featureless corridor), or
- the heading standard deviation exceeds ``max_heading_sd`` radians.

Labelling runs in a small numba kernel over the occupied cells (a flood fill on a dense grid of the
cloud's bounding box); the rest is vectorised numpy. About 2-4 ms for 10 000 particles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from mcl.filter.angles import wrap_angle
from racecar_sim.settings.validation import short

__all__ = [
    "ClusterParams",
    "Clusters",
    "Uncertainty",
    "assess",
    "cluster_particles",
    "largest_position_sd",
]

_MAX_GRID_CELLS = 20_000_000  # cells of the dense labelling grid before the bins are coarsened


@dataclass(frozen=True)
class ClusterParams:
    """Settings of the clustering and of the ambiguity flag (module docstring).

    Attributes:
        bin_size: grid cells (x metres, y metres, theta radians).
        min_weight: clusters lighter than this fraction of the weight are not counted.
        ambiguous_weight: a second cluster at least this heavy makes the cloud ambiguous.
        max_position_sd: metres; a larger position standard deviation makes it ambiguous.
        max_heading_sd: radians; a larger heading standard deviation makes it ambiguous.
    """

    bin_size: tuple[float, float, float] = (0.5, 0.5, math.radians(30.0))
    min_weight: float = 0.02
    ambiguous_weight: float = 0.1
    max_position_sd: float = 0.5
    max_heading_sd: float = math.radians(15.0)

    def __post_init__(self) -> None:
        size = tuple(float(v) for v in self.bin_size)
        if len(size) != 3 or not all(math.isfinite(v) and v > 0 for v in size):
            raise ValueError(
                f"ClusterParams.bin_size = {short(self.bin_size)} must be three positive numbers "
                "(x m, y m, theta rad)"
            )
        object.__setattr__(self, "bin_size", size)
        for name in ("min_weight", "ambiguous_weight"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= 1.0:
                raise ValueError(f"ClusterParams.{name} = {short(v)} must be a fraction in [0, 1]")
        for name in ("max_position_sd", "max_heading_sd"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not v > 0:
                raise ValueError(f"ClusterParams.{name} = {short(v)} must be a positive number")


@dataclass(frozen=True)
class Clusters:
    """Connected components of a particle cloud.

    Attributes:
        labels: (N,) int64 cluster of each particle (index into the arrays below).
        weights: (C,) total weight of each cluster, heaviest first.
        means: (C, 3) weighted mean pose [x, y, theta] of each cluster (circular mean of theta).
        sizes: (C,) particles in each cluster.
    """

    labels: np.ndarray
    weights: np.ndarray
    means: np.ndarray
    sizes: np.ndarray


@dataclass(frozen=True)
class Uncertainty:
    """A summary of how well the cloud pins down the pose (module docstring).

    Attributes:
        covariance: (3, 3) weighted covariance (metres, radians) about the estimate.
        position_sd: metres, square root of the largest eigenvalue of the x-y covariance.
        heading_sd: radians, square root of the theta variance.
        n_clusters: clusters holding at least ``min_weight`` of the weight.
        top_weight: weight of the heaviest cluster. second_weight: of the next one (0 if none).
        top_mean: (3,) mean pose of the heaviest cluster.
        ambiguous: whether the pose is ambiguous.
    """

    covariance: np.ndarray
    position_sd: float
    heading_sd: float
    n_clusters: int
    top_weight: float
    second_weight: float
    top_mean: np.ndarray
    ambiguous: bool


@nb.njit(cache=True)
def _label_cells(bx, by, bt, nx, ny, nt):  # pragma: no cover - compiled
    """Connected-component label (0, 1, ...) of each occupied cell (bx[i], by[i], bt[i]).

    26-neighbourhood, theta index wrapping modulo nt. Cells must be distinct.
    """
    n = bx.shape[0]
    grid = np.full((nx, ny, nt), -1, dtype=np.int64)
    for i in range(n):
        grid[bx[i], by[i], bt[i]] = i
    labels = np.full(n, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    n_labels = 0
    for s in range(n):
        if labels[s] >= 0:
            continue
        labels[s] = n_labels
        stack[0] = s
        top = 1
        while top > 0:
            top -= 1
            i = stack[top]
            for dx in range(-1, 2):
                x = bx[i] + dx
                if x < 0 or x >= nx:
                    continue
                for dy in range(-1, 2):
                    y = by[i] + dy
                    if y < 0 or y >= ny:
                        continue
                    for dt in range(-1, 2):
                        t = (bt[i] + dt) % nt
                        j = grid[x, y, t]
                        if j >= 0 and labels[j] < 0:
                            labels[j] = n_labels
                            stack[top] = j
                            top += 1
        n_labels += 1
    return labels


def cluster_particles(
    particles: np.ndarray, weights: np.ndarray, bin_size: tuple[float, float, float]
) -> Clusters:
    """Connected components of the occupied pose-grid cells (module docstring).

    Args:
        particles: (N, 3) world poses [x, y, theta] (metres, radians).
        weights: (N,) non-negative weights summing to 1.
        bin_size: grid cells (x m, y m, theta rad); coarsened (x, y doubled) when the cloud's
            bounding box would need more than 20 million cells.
    """
    p = np.asarray(particles, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"particles must have shape (N, 3) with N >= 1, got {p.shape}")
    if w.shape != (p.shape[0],):
        raise ValueError(f"weights must have shape ({p.shape[0]},), got {w.shape}")
    sx, sy, st = bin_size
    nt = max(1, math.ceil(2.0 * math.pi / st))
    theta = wrap_angle(p[:, 2])
    bt = np.minimum(np.floor((theta + math.pi) / st).astype(np.int64), nt - 1)
    while True:
        bx = np.floor(p[:, 0] / sx).astype(np.int64)
        by = np.floor(p[:, 1] / sy).astype(np.int64)
        bx -= bx.min()
        by -= by.min()
        nx, ny = int(bx.max()) + 1, int(by.max()) + 1
        if nx * ny * nt <= _MAX_GRID_CELLS:
            break
        sx, sy = 2 * sx, 2 * sy
    keys = (bx * ny + by) * nt + bt
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    cell_labels = _label_cells(bx[first], by[first], bt[first], nx, ny, nt)
    labels = cell_labels[inverse.reshape(-1)]
    n_labels = int(cell_labels.max()) + 1
    cw = np.bincount(labels, weights=w, minlength=n_labels)
    sizes = np.bincount(labels, minlength=n_labels)
    safe = np.where(cw > 0, cw, 1.0)
    mx = np.bincount(labels, weights=w * p[:, 0], minlength=n_labels) / safe
    my = np.bincount(labels, weights=w * p[:, 1], minlength=n_labels) / safe
    ms = np.bincount(labels, weights=w * np.sin(theta), minlength=n_labels)
    mc = np.bincount(labels, weights=w * np.cos(theta), minlength=n_labels)
    means = np.column_stack([mx, my, wrap_angle(np.arctan2(ms, mc))])
    order = np.argsort(-cw, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(n_labels)
    return Clusters(labels=rank[labels], weights=cw[order], means=means[order], sizes=sizes[order])


def largest_position_sd(covariance: np.ndarray) -> float:
    """Metres: the standard deviation of a cloud's position along its widest axis, from its
    (3, 3) pose covariance (world frame; the square root of the xy block's largest eigenvalue)."""
    xy = np.asarray(covariance, dtype=np.float64)[:2, :2]
    return float(math.sqrt(max(float(np.linalg.eigvalsh(xy)[-1]), 0.0)))


def assess(
    particles: np.ndarray,
    weights: np.ndarray,
    covariance: np.ndarray,
    params: ClusterParams,
) -> Uncertainty:
    """The `Uncertainty` of a weighted cloud with covariance ``covariance`` (3, 3)."""
    cov = np.asarray(covariance, dtype=np.float64)
    clusters = cluster_particles(particles, weights, params.bin_size)
    position_sd = largest_position_sd(cov)
    heading_sd = float(math.sqrt(max(float(cov[2, 2]), 0.0)))
    cw = clusters.weights
    n_clusters = int(np.count_nonzero(cw >= params.min_weight))
    top = min(float(cw[0]), 1.0)  # rounding of the weight sums
    second = float(cw[1]) if cw.size > 1 else 0.0
    ambiguous = (
        (cw.size > 1 and second >= params.ambiguous_weight)
        or position_sd > params.max_position_sd
        or heading_sd > params.max_heading_sd
    )
    return Uncertainty(
        covariance=cov,
        position_sd=position_sd,
        heading_sd=heading_sd,
        n_clusters=n_clusters,
        top_weight=top,
        second_weight=second,
        top_mean=clusters.means[0].copy(),
        ambiguous=bool(ambiguous),
    )
