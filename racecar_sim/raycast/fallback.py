"""Many exact casts at once, in lockstep: the fallbacks of the ``lut`` query.

Each ray is [`cast_ray_from()`][racecar_sim.raycast.kernels.cast_ray_from] from its own start parameter
``t0`` (cells, pad frame), or [`cast_ray()`][racecar_sim.raycast.kernels.cast_ray] from its origin when
``t0 <= 0`` or the point at ``t0`` is occupied or off the grid: the same doubles, operation for
operation (tested). What differs is the order of work. One ray at a time, the cell-by-cell
traversal costs a mispredicted branch at most steps (x or y crossing next?) and waits on each
field read; here every ray takes one step per pass over the list of rays still stepping, with
selects instead of branches, so the passes are branch-free and the reads of different rays
overlap. A ray that leaves the walls (a field value allowing a jump) finishes on its own with
[`traverse()`][racecar_sim.raycast.kernels.traverse]; those are few, as the ``lut`` starts its fallbacks
just before a wall.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from racecar_sim.raycast.kernels import OCCUPIED, traverse

__all__ = ["guided_casts"]

_BIG = 1e30


@nb.njit(cache=True, error_model="numpy")
def guided_casts(field, x, y, dx, dy, t0, max_t, n, out, fstate, istate, active):
    """``out[k]`` = exact range in cells of ray ``k < n`` from ``(x[k], y[k])`` along the unit
    ``(dx[k], dy[k])`` (pad frame), its traversal started at ``t0[k]`` (see the module docstring).

    ``fstate`` (4, >= n) float64, ``istate`` (4, >= n) int64 and ``active`` (>= n) int64 are work
    arrays (their contents are overwritten; C-contiguous, read as four numbers per ray). The
    segment of each ray before ``t0`` must be free, as for
    [`cast_ray_from()`][racecar_sim.raycast.kernels.cast_ray_from].
    """
    h = field.shape[0]
    w = field.shape[1]
    flat = field.reshape(-1)
    # One record of four per ray, so that a step touches two cache lines, not seven arrays
    # (and LLVM keeps two base pointers in registers instead of spilling seven; 10 % faster):
    # fs[4k:4k+4] = the t of the next x and y crossings and their increments, js[4k:4k+4] = the
    # flat cell, its x and y steps, and 1 when the ray stopped at a cell allowing a jump.
    fs = fstate.reshape(-1)
    js = istate.reshape(-1)
    na = 0
    # Setup, as cast_ray_from (then cast_ray where it gives -1); rays starting where a jump is
    # allowed are cast on their own.
    for k in range(n):
        js[4 * k + 3] = 0
        gu = x[k]
        gv = y[k]
        ux = dx[k]
        uy = dy[k]
        t = t0[k]
        v = 0
        start = t > 0.0
        if start:
            px = gu + t * ux
            py = gv + t * uy
            if px >= 0.0 and px < w and py >= 0.0 and py < h:
                col = int(px)
                rv = int(py)
                v = field[rv, col]
                start = v != OCCUPIED
            else:
                start = False
        if not start:  # cast_ray: from the origin, 0 if that is off the grid or occupied
            t = 0.0
            px = gu
            py = gv
            if not (px >= 0.0 and px < w and py >= 0.0 and py < h):
                out[k] = 0.0
                continue
            col = int(px)
            rv = int(py)
            v = field[rv, col]
            if v == OCCUPIED:
                out[k] = 0.0
                continue
        if v != 0:
            r = traverse(field, gu, gv, ux, uy, t, px, py, col, rv, v, max_t)
            out[k] = r if start or r > 0.0 else 0.0
            continue
        # the signs' branches of cast_ray_from as selects (the same operations)
        cx = col + 1 if ux > 0.0 else col
        cy = rv + 1 if uy > 0.0 else rv
        ax = t + (cx - px) / ux
        ay = t + (cy - py) / uy
        # capped: 1 / |u| overflows for a subnormal u, and 0 * inf would make the steps below NaN
        bx = min(1.0 / abs(ux), _BIG)
        by = min(1.0 / abs(uy), _BIG)
        fs[4 * k] = _BIG if ux == 0.0 else ax
        fs[4 * k + 1] = _BIG if uy == 0.0 else ay
        fs[4 * k + 2] = _BIG if ux == 0.0 else bx
        fs[4 * k + 3] = _BIG if uy == 0.0 else by
        js[4 * k] = rv * w + col
        js[4 * k + 1] = 1 if ux > 0.0 else -1
        js[4 * k + 2] = w if uy > 0.0 else -w
        active[na] = k
        na += 1
    # Lockstep: one cell step of every ray still stepping per pass, the list compacted as it
    # goes; a ray that reaches a cell allowing a jump is set aside and finished on its own after.
    while na > 0:
        nn = 0
        for q in range(na):
            k = np.uint64(active[q])  # unsigned: numba emits no wrap-around test for negatives
            kf = k * np.uint64(4)
            a = fs[kf]
            b = fs[kf + np.uint64(1)]
            go_x = a < b
            # x + 1 * d or x + 0 * d (exactly x): as a select, LLVM made these branches again
            gx = 1.0 if go_x else 0.0
            t = a if go_x else b
            fs[kf] = a + gx * fs[kf + np.uint64(2)]
            fs[kf + np.uint64(1)] = b + (1.0 - gx) * fs[kf + np.uint64(3)]
            sxk = js[kf + np.uint64(1)]
            syk = js[kf + np.uint64(2)]
            c = js[kf] + (sxk if go_x else syk)
            js[kf] = c
            v = flat[np.uint64(c)]
            clipped = t >= max_t
            out[k] = max_t if clipped else t
            stepping = (v == 0) & ~clipped
            js[kf + np.uint64(3)] = (v != 0) & (v != OCCUPIED) & ~clipped
            active[np.uint64(nn)] = k
            nn += stepping
        na = nn
    for k in range(n):
        if js[4 * k + 3] == 0:
            continue
        t = out[k]
        gu = x[k]
        gv = y[k]
        v = flat[js[4 * k]]
        out[k] = traverse(
            field, gu, gv, dx[k], dy[k], t, gu + t * dx[k], gv + t * dy[k], 0, 0, v, max_t
        )
