"""The ``lut`` table's planar flags (the high bit of each entry), set after the sweep.

Planar flag (the high bit of entry ``k``)
    Set when the two table rays ``k`` and ``k + 1`` of the cell see one straight face: their
    ranges differ by more than [`FLAG_ABOVE`][racecar_sim.raycast.lut_table.FLAG_ABOVE] cells (closer pairs are judged by the query's
    tolerance), and the exact range from the cell centre along the middle direction
    ``theta_k + pi / K`` lies within [`FLAG_EPS`][racecar_sim.raycast.lut_table.FLAG_EPS] cells of where that ray meets the line
    through the two table hits. The query interpolates flagged pairs however far apart their
    ranges are (oblique walls, corridors seen lengthwise) instead of casting them.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from racecar_sim.raycast.kernels import cast_ray, cast_ray_from
from racecar_sim.raycast.lut_table import CAP_MARGIN, FLAG, RANGE_MASK, foot_hit

__all__ = ["flag_parallel", "flag_rows"]

_GUIDE = 2.0  # cells: the flag check's exact cast starts this far before the nearer table hit


@nb.njit(cache=True, error_model="numpy")
def flag_rows(
    table, rv_of, col_of, field, unit, sub, cos_k, sin_k, cos_m, sin_m, cap, above, eps, i_lo, i_hi
):
    """Set the planar flag on rows ``i_lo <= i < i_hi`` (see the module docstring); returns the
    number of entries flagged. ``cos_m``, ``sin_m``: the K middle directions."""
    n_angles = table.shape[1]
    inv_sub = 1.0 / sub
    above_code = above / unit
    flagged = 0
    for i in range(i_lo, i_hi):
        cx = col_of[i] + 0.5
        cy = rv_of[i] + 0.5
        for k in range(n_angles):
            k1 = k + 1 if k + 1 < n_angles else 0
            c0 = np.int32(table[i, k] & RANGE_MASK)
            c1 = np.int32(table[i, k1] & RANGE_MASK)
            if abs(c0 - c1) <= above_code:
                continue
            r0 = c0 * unit
            r1 = c1 * unit
            if max(r0, r1) >= cap - CAP_MARGIN:
                continue  # one ray leaves the range: nothing to interpolate
            h0x, h0y = foot_hit(cx, cy, cos_k[k], sin_k[k], r0, sub, inv_sub)
            h1x, h1y = foot_hit(cx, cy, cos_k[k + 1], sin_k[k + 1], r1, sub, inv_sub)
            ex = h1x - h0x
            ey = h1y - h0y
            wx = h0x - cx
            wy = h0y - cy
            dx = cos_m[k]
            dy = sin_m[k]
            den = dx * ey - dy * ex
            if abs(den) <= 1e-9:
                continue
            t = (wx * ey - wy * ex) / den
            # The exact middle ray, cast only as far as it matters (a hit beyond the farther
            # table hit is no plane either).
            t_lim = max(max(r0, r1), t) + 1.0
            te = -1.0
            t0 = min(r0, r1) - _GUIDE
            if t0 > 0.0:
                te = cast_ray_from(field, cx, cy, dx, dy, t0, t_lim)
            if te < 0.0:
                te = cast_ray(field, cx, cy, dx, dy, t_lim)
            if te < t_lim and abs(te - t) <= eps:
                table[i, k] |= FLAG
                flagged += 1
    return flagged


@nb.njit(cache=True, parallel=True)
def flag_parallel(
    table, rv_of, col_of, field, unit, sub, cos_k, sin_k, cos_m, sin_m, cap, above, eps
):
    """`flag_rows()` over every row, in blocks of 1024 rows on numba's threads."""
    n = table.shape[0]
    blk = 1024
    n_blk = (n + blk - 1) // blk
    counts = np.zeros(n_blk, dtype=np.int64)
    for bi in nb.prange(n_blk):
        counts[bi] = flag_rows(
            table, rv_of, col_of, field, unit, sub, cos_k, sin_k, cos_m, sin_m, cap, above, eps,
            bi * blk, min(bi * blk + blk, n),
        )  # fmt: skip
    return counts.sum()
