"""Likelihood-field sensor model (Probabilistic Robotics 6.4; amcl's and beluga's default).

No ray casting: each beam's end point ``lidar + z (cos, sin)(theta + angle)`` (world frame, metres)
is looked up in a per-cell table of

    log p(z) = log(z_hit * exp(-d^2 / (2 sigma^2)) + z_rand / max_range),

``d`` the distance (metres) from the cell's centre to the nearest occupied cell's centre
(`racecar_sim.maps.OccupancyMap.distance`, unknown cells count as occupied), clipped to
``max_distance``; end points off the map score as ``d = max_distance``. Beams at or beyond
``max_range`` (no return) and non-finite beams are skipped, as amcl does. A particle's log-likelihood
is ``squash_exponent`` times the sum over beams (the product of the beam likelihoods, softened like
the beam model's).

The table holds uint16 codes in the pad frame of `racecar_sim.raycast.kernels` (a one-cell
ring of the off-map code around the map, row 1 = the image's bottom row), so an end point at
map-frame ``(u, v)`` metres reads ``codes[int(v / res + 1), int(u / res + 1)]``: one 2-byte read
per beam (4.5 MB for the Stata basement; a float32 table, twice the size, was 13 % slower), summed
as integers. A code stands for
``lo + code * step`` with ``step = (hi - lo) / 65535``, so a beam's log-likelihood is off by at most
``step / 2`` (about 4e-5 with amcl's settings).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast.shared_work import fetch_add, run_shared

__all__ = ["PARALLEL_MIN_POINTS", "FieldTable", "likelihood_table", "score_endpoints"]

PARALLEL_MIN_POINTS = 2_000_000
"""End points (particles x beams) per call from which the kernel runs on all numba threads."""


@dataclass(frozen=True, eq=False)
class FieldTable:
    """The likelihood field of one map and parameter set.

    Attributes:
        codes: uint16 (H + 2, W + 2): the map's cells (row 1 = the image's bottom row) inside a
            ring of the off-map code; ``lo + code * step`` is the cell's log p.
        lo: log p of code 0.
        step: log p per code unit.
        off_map: log p of an end point off the map.
    """

    codes: np.ndarray
    lo: float
    step: float
    off_map: float


def likelihood_table(
    grid: OccupancyMap,
    sigma: float,
    z_hit: float,
    z_rand: float,
    max_distance: float,
    max_range: float,
) -> FieldTable:
    """The per-cell log-likelihood table (see the module docstring), with a one-cell ring of the
    off-map code around the map: an end point's indexes, clamped into the table, land on the ring
    when they leave the map, so the kernel's loop has no branch (LLVM vectorises it: 2.2x faster
    than a bounds test per beam, measured).

    Args: see [`mcl.filter.sensor_model.SensorModelParams`][mcl.filter.sensor_model.SensorModelParams] (``likelihood_*``), metres.
    """
    d = np.minimum(grid.distance[::-1], max_distance)
    floor = z_rand / max_range
    log_p = np.log(z_hit * np.exp(-0.5 * (d / sigma) ** 2) + floor)
    off_map = math.log(z_hit * math.exp(-0.5 * (max_distance / sigma) ** 2) + floor)
    lo = min(off_map, float(log_p.min()))
    hi = max(off_map, float(log_p.max()))
    step = (hi - lo) / 65535.0 if hi > lo else 1.0
    codes = np.full((grid.height + 2, grid.width + 2), round((off_map - lo) / step), np.uint16)
    codes[1:-1, 1:-1] = np.rint((log_p - lo) / step)
    return FieldTable(np.ascontiguousarray(codes), lo, step, off_map)


@nb.njit(cache=True, inline="always")
def _score_one(codes, lo, step, off_map, gu, gv, c, s, bx, by, i):
    """Sum of log p over the beams of particle ``i``; ``(bx, by)`` are the end points in the lidar
    frame (cells), rotated by the particle's heading and moved to its position (map frame, cells).
    """
    top_row = codes.shape[0] - 1
    top_col = codes.shape[1] - 1
    m = bx.shape[0]
    x = gu[i] + 1.0  # the ring of off-map codes
    y = gv[i] + 1.0
    ch = c[i]
    sh = s[i]
    acc = 0
    for b in range(m):
        ex = x + ch * bx[b] - sh * by[b]
        ey = y + sh * bx[b] + ch * by[b]
        # Clamped into the table: an end point off the map lands on the ring.
        col = min(max(int(ex), 0), top_col)
        row = min(max(int(ey), 0), top_row)
        acc += codes[row, col]
    return acc * step + m * lo


@nb.njit(cache=True)
def _score_span(codes, lo, step, off_map, gu, gv, c, s, bx, by, squash, out, i0, i1):
    """``out[i] = squash * log p`` for particles ``i0 <= i < i1``."""
    for i in range(i0, i1):
        out[i] = squash * _score_one(codes, lo, step, off_map, gu, gv, c, s, bx, by, i)


@nb.njit(cache=True, nogil=True)
def _score_shared(codes, lo, step, off_map, gu, gv, c, s, bx, by, squash, out, counter):
    """`_score_span()` over blocks of 64 particles taken from ``counter`` (shared work,
    `racecar_sim.raycast.shared_work`)."""
    n = gu.shape[0]
    blk = 64
    while True:
        i0 = fetch_add(counter, 1) * blk
        if i0 >= n:
            break
        _score_span(codes, lo, step, off_map, gu, gv, c, s, bx, by, squash, out, i0,
                    min(n, i0 + blk))  # fmt: skip


def score_endpoints(
    grid: OccupancyMap,
    table: FieldTable,
    lidar: np.ndarray,
    angles: np.ndarray,
    ranges: np.ndarray,
    squash: float,
    parallel: bool | None,
) -> np.ndarray:
    """(N,) log-likelihoods of the beams ``(angles, ranges)`` (car frame radians, metres, all used)
    from the lidar poses ``lidar`` (N, 3) world frame."""
    lidar = np.asarray(lidar, dtype=np.float64)
    if not np.isfinite(lidar).all():
        raise ValueError("particles must be finite (found NaN or inf)")
    res = grid.resolution
    # Clipped far outside any map, so the kernel's float -> int conversions stay defined.
    uv = np.clip(grid.world_to_map(lidar[:, :2]) / res, -1e7, 1e7)
    heading = lidar[:, 2] - grid.yaw
    out = np.empty(lidar.shape[0], dtype=np.float64)
    args = (
        table.codes,
        float(table.lo),
        float(table.step),
        float(table.off_map),
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
    if parallel:
        run_shared(_score_shared, args, nb.get_num_threads())
    else:
        _score_span(*args, 0, lidar.shape[0])
    return out
