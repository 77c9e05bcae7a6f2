"""Morton (Z-order) ordering of poses by their grid cells, for casting a spread cloud.

When a particle cloud covers the whole map, consecutive particles read table rows and field cells
far apart, so nearly every read misses the cache. Casting them in Z-order of their cells (pad
frame, whole cells) makes neighbouring poses read neighbouring memory. Each pose's ranges depend
only on that pose, so casting in another order and scattering the results back gives the same
doubles ([`racecar_sim.raycast.lut.lut_score()`][racecar_sim.raycast.lut.lut_score] relies on it).
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["cell_extent", "morton_codes", "radix_order", "spread_order"]

_CELL_MAX = (1 << 31) - 1  # cells beyond are clamped (a map is far smaller)


@nb.njit(cache=True, inline="always")
def _part1by1(v):
    """The low 32 bits of ``v`` spread to the even bits of a uint64."""
    v = np.uint64(v) & np.uint64(0xFFFFFFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)
    v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    v = (v | (v << np.uint64(2))) & np.uint64(0x3333333333333333)
    v = (v | (v << np.uint64(1))) & np.uint64(0x5555555555555555)
    return v


@nb.njit(cache=True, inline="always")
def _cell(x):
    """Whole cell of coordinate ``x`` (cells), clamped to [0, 2**31 - 1]."""
    if not x > 0.0:  # negative (off the map) or NaN
        return 0
    if x >= _CELL_MAX:
        return _CELL_MAX
    return int(x)


@nb.njit(cache=True)
def morton_codes(gu, gv, out):
    """``out[i]`` (uint64) = the Z-order code of cell ``(int(gu[i]), int(gv[i]))``: the bits of
    the column in the even places, of the row in the odd ones. ``gu, gv`` in cells."""
    for i in range(gu.shape[0]):
        out[i] = _part1by1(_cell(gu[i])) | (_part1by1(_cell(gv[i])) << np.uint64(1))


@nb.njit(cache=True)
def cell_extent(gu, gv):
    """The larger side (cells) of the axis-aligned box around the points ``(gu, gv)``; 0 for none."""
    n = gu.shape[0]
    if n == 0:
        return 0.0
    u0 = u1 = gu[0]
    v0 = v1 = gv[0]
    for i in range(1, n):
        u = gu[i]
        v = gv[i]
        u0 = min(u0, u)
        u1 = max(u1, u)
        v0 = min(v0, v)
        v1 = max(v1, v)
    return max(u1 - u0, v1 - v0)


@nb.njit(cache=True)
def radix_order(codes):
    """The stable permutation sorting ``codes`` (uint64): a least-significant-digit radix sort,
    11 bits a pass, as many passes as the largest code needs (two for a 2048 x 2048-cell map).
    O(n) a pass, against the O(n log n) of ``np.argsort``."""
    n = codes.shape[0]
    order = np.arange(n)
    if n == 0:
        return order
    tmp = np.empty(n, dtype=np.int64)
    counts = np.empty(2049, dtype=np.int64)
    top = codes.max()
    mask = np.uint64(2047)
    shift = np.uint64(0)
    while True:
        counts[:] = 0
        for i in range(n):
            counts[np.int64((codes[order[i]] >> shift) & mask) + 1] += 1
        for d in range(2048):
            counts[d + 1] += counts[d]
        for i in range(n):
            d = np.int64((codes[order[i]] >> shift) & mask)
            tmp[counts[d]] = order[i]
            counts[d] += 1
        order, tmp = tmp, order
        shift += np.uint64(11)
        if shift >= np.uint64(64) or (top >> shift) == np.uint64(0):
            break
    return order


def spread_order(gu: np.ndarray, gv: np.ndarray, min_extent: float) -> np.ndarray | None:
    """The permutation casting poses ``(gu, gv)`` (cells) in Z-order of their cells, or None
    when the cloud's box is narrower than ``min_extent`` cells on both axes (a tracking cloud:
    its reads are in cache already, sorting would only cost time).

    ``gu[order]`` lists the poses in Z-order; results cast in that order go back with
    ``out[order] = sorted_out``.
    """
    if gu.shape[0] < 2 or min_extent == np.inf or not cell_extent(gu, gv) >= min_extent:
        return None
    codes = np.empty(gu.shape[0], dtype=np.uint64)
    morton_codes(gu, gv, codes)
    return radix_order(codes)
