"""Likelihood-field sensor model (Probabilistic Robotics 6.4; amcl's and beluga's default).

No ray casting: each beam's end point ``lidar + z (cos, sin)(theta + angle)`` (world frame, metres)
is looked up in a per-cell table of

    log p(z) = log(z_hit * exp(-d^2 / (2 sigma^2)) + z_rand / max_range),

``d`` the distance (metres) from the cell's centre to the nearest occupied cell's centre
(:attr:`racecar_sim.maps.OccupancyMap.distance`, unknown cells count as occupied), clipped to
``max_distance``; end points off the map score as ``d = max_distance``. Beams at or beyond
``max_range`` (no return) and non-finite beams are skipped, as amcl does. A particle's log-likelihood
is ``squash_exponent`` times the sum over beams (the product of the beam likelihoods, softened like
the beam model's).

The table is float32 in the pad frame of :mod:`racecar_sim.raycast.kernels` without its ring
(row 0 = the image's bottom row), so an end point at map-frame ``(u, v)`` metres reads
``table[int(v / res), int(u / res)]``: one memory read per beam, about 9 MB for the Stata basement.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.maps import OccupancyMap

__all__ = ["PARALLEL_MIN_POINTS", "likelihood_table", "score_endpoints"]

PARALLEL_MIN_POINTS = 2_000_000
"""End points (particles x beams) per call from which the kernel runs on all numba threads."""


def likelihood_table(
    grid: OccupancyMap,
    sigma: float,
    z_hit: float,
    z_rand: float,
    max_distance: float,
    max_range: float,
) -> tuple[np.ndarray, float]:
    """(float32 (H, W) log-likelihood per cell with row 0 at the bottom, off-map log-likelihood).

    Args: see :class:`mcl.sensor_model.SensorModelParams` (``likelihood_*``), metres.
    """
    d = np.minimum(grid.distance[::-1], max_distance)
    floor = z_rand / max_range
    table = np.log(z_hit * np.exp(-0.5 * (d / sigma) ** 2) + floor).astype(np.float32)
    off_map = math.log(z_hit * math.exp(-0.5 * (max_distance / sigma) ** 2) + floor)
    return np.ascontiguousarray(table), float(off_map)


@nb.njit(cache=True, inline="always")
def _score_one(table, off_map, gu, gv, c, s, bx, by, i):
    """Sum of log p over the beams of particle ``i``; ``(bx, by)`` end points in the lidar frame
    (cells), rotated by the particle's heading and moved to its position (map frame, cells)."""
    h = table.shape[0]
    w = table.shape[1]
    x = gu[i]
    y = gv[i]
    ch = c[i]
    sh = s[i]
    acc = 0.0
    for b in range(bx.shape[0]):
        ex = x + ch * bx[b] - sh * by[b]
        ey = y + sh * bx[b] + ch * by[b]
        if ex >= 0.0 and ex < w and ey >= 0.0 and ey < h:
            acc += table[int(ey), int(ex)]
        else:
            acc += off_map
    return acc


@nb.njit(cache=True)
def _score_serial(table, off_map, gu, gv, c, s, bx, by, squash, out):
    for i in range(gu.shape[0]):
        out[i] = squash * _score_one(table, off_map, gu, gv, c, s, bx, by, i)


@nb.njit(cache=True, parallel=True)
def _score_parallel(table, off_map, gu, gv, c, s, bx, by, squash, out):
    for i in nb.prange(gu.shape[0]):
        out[i] = squash * _score_one(table, off_map, gu, gv, c, s, bx, by, i)


def score_endpoints(
    grid: OccupancyMap,
    table: np.ndarray,
    off_map: float,
    lidar: np.ndarray,
    angles: np.ndarray,
    ranges: np.ndarray,
    squash: float,
    parallel: bool | None,
) -> np.ndarray:
    """(N,) log-likelihoods of the beams ``(angles, ranges)`` (car frame radians, metres, all used)
    from the lidar poses ``lidar`` (N, 3) world frame."""
    lidar = np.asarray(lidar, dtype=np.float64)
    res = grid.resolution
    uv = grid.world_to_map(lidar[:, :2]) / res
    heading = lidar[:, 2] - grid.yaw
    out = np.empty(lidar.shape[0], dtype=np.float64)
    args = (
        table,
        float(off_map),
        np.ascontiguousarray(uv[:, 0]),
        np.ascontiguousarray(uv[:, 1]),
        np.cos(heading),
        np.sin(heading),
        np.ascontiguousarray(ranges / res * np.cos(angles), dtype=np.float64),
        np.ascontiguousarray(ranges / res * np.sin(angles), dtype=np.float64),
        float(squash),
        out,
    )
    if parallel is None:
        parallel = lidar.shape[0] * len(ranges) >= PARALLEL_MIN_POINTS
    (_score_parallel if parallel else _score_serial)(*args)
    return out
