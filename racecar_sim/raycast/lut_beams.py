"""The ``lut`` query's loops over one pose's beams, written so that LLVM vectorises them.

Pad frame of `racecar_sim.raycast.kernels` (cells). Called by
`racecar_sim.raycast.lut._lut_poses()` for each pose: `directions()` (the two table
directions bracketing each ray, in 32-bit fixed point), `unpack()` (table entries to range
codes and planar flags), `interpolate()` (the range where the true ray meets the line through
the two table hits, or -1 where the ray must be cast exactly).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from racecar_sim.raycast.lut_table import FLAG, RANGE_MASK

__all__ = ["MASK32", "SANE", "TURN", "column", "directions", "interpolate", "unpack"]

SANE = 1.5  # cells an interpolated range may lie outside the two table ranges
TURN = 4294967296.0  # 2**32: a full turn in the fixed-point angles
MASK32 = 0xFFFFFFFF


_FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}
"""LLVM fast-math flags of the vectorised loops: no ``nnan`` / ``ninf``, the range checks rely on
comparisons with infinities (a ray parallel to a wall divides by zero)."""


@nb.njit(cache=True, inline="always")
def column(r, per_out, top):
    """Score-table column (plus one half, truncated by the caller) of output range ``r``."""
    d = r * per_out
    return min(max(d, 0.0), top) + 0.5


@nb.njit(cache=True, error_model="numpy", fastmath=_FAST)
def directions(hb, afix, n_angles, phi_unit, kb, phb):
    """Ray ``b`` of a pose of fixed-point heading ``hb``: its lower table direction ``kb[b]``
    and how far past it, ``phb[b]`` radians."""
    for b in range(afix.shape[0]):
        a = ((hb + afix[b]) & MASK32) * n_angles
        kb[b] = a >> 32
        phb[b] = (a & MASK32) * phi_unit


@nb.njit(cache=True, error_model="numpy", fastmath=_FAST)
def unpack(e0b, e1b, c0b, c1b):
    """Table entries to float32 range codes, the first negative where its planar flag is set."""
    for b in range(e0b.shape[0]):
        c0 = np.float32(e0b[b] & RANGE_MASK)
        c0b[b] = -c0 if e0b[b] & FLAG else c0
        c1b[b] = np.float32(e1b[b] & RANGE_MASK)


@nb.njit(cache=True, error_model="numpy", fastmath=_FAST)
def interpolate(
    phb, c0b, c1b, cos_a, sin_a, ch, sh, qx, qy, cxs, cys, inv_sub, unit, cos_d, sin_d,
    tol_code, sat, max_t, max_t64, scale, max_out, per_out, top, tb, db,
):  # fmt: skip
    """One pose's interpolated ranges ``tb`` (cells; -1 where the ray must be cast) and score
    columns ``db``, branch-free so that LLVM vectorises it (see `racecar_sim.raycast.lut._lut_poses()`). ``c0b`` is
    negative where the table flags the pair as one straight face.

    float32 (arrays, scalars and constants; the score column in float64 from the float32 range,
    as the ranges output computes it), 16 rays per AVX-512 instruction: the
    positions are relative to the pose (a few hundred cells at most), so single precision keeps
    them to 1e-4 cells; only the sweep line of a foot (``floor(sn)``, ``sn`` up to a few
    thousand) can come out one line off, for about 1 ray in 2000 (then off by half a cell).
    """
    one = np.float32(1.0)
    half = np.float32(0.5)
    sixth = np.float32(1.0 / 6.0)
    s120 = np.float32(1.0 / 120.0)
    s24 = np.float32(1.0 / 24.0)
    sane = np.float32(SANE)
    tiny = np.float32(1e-9)
    minus = np.float32(-1.0)
    zero = np.float32(0.0)
    for b in range(phb.shape[0]):
        dx = ch * cos_a[b] - sh * sin_a[b]
        dy = sh * cos_a[b] + ch * sin_a[b]
        ph = phb[b]  # the ray is ph radians past direction k0: rotate it back (Taylor series)
        p2 = ph * ph
        # Error below 1e-13 rad at K = 360, 3e-4 rad at the coarsest table (K = 8).
        sp = ph * (one - p2 * (sixth - p2 * s120))
        cp = one - p2 * (half - p2 * s24)
        co0 = dx * cp + dy * sp
        si0 = dy * cp - dx * sp
        co1 = co0 * cos_d - si0 * sin_d
        si1 = si0 * cos_d + co0 * sin_d
        flat = c0b[b] < zero
        c0 = abs(c0b[b])
        c1 = c1b[b]
        r0 = c0 * unit
        r1 = c1 * unit
        # Hit points relative to the pose (the feet of the cell centre on the sweep lines).
        sn0 = cys * co0 - cxs * si0
        dl0 = (np.floor(sn0) + half - sn0) * inv_sub
        sn1 = cys * co1 - cxs * si1
        dl1 = (np.floor(sn1) + half - sn1) * inv_sub
        wx = qx - dl0 * si0 + r0 * co0
        wy = qy + dl0 * co0 + r0 * si0
        ex = qx - dl1 * si1 + r1 * co1 - wx
        ey = qy + dl1 * co1 + r1 * si1 - wy
        den = dx * ey - dy * ex
        t = (wx * ey - wy * ex) / den
        lo = min(r0, r1)
        hi = max(r0, r1)
        bad = (
            ((abs(c0 - c1) > tol_code) & ~flat)
            | (abs(den) <= tiny)
            | (t < lo - sane)
            | (t > hi + sane)
        )
        t = minus if bad else t
        t = max_t if lo >= sat else t
        tb[b] = t
        t64 = np.float64(t)
        r = max_out if t64 >= max_t64 else t64 * scale
        db[b] = column(r, per_out, top)
