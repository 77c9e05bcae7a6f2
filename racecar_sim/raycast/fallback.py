"""Many exact casts at once, in lockstep: the fallbacks of the ``lut`` query.

Each ray is :func:`~racecar_sim.raycast.kernels.cast_ray_from` from its own start parameter
``t0`` (cells, pad frame), or :func:`~racecar_sim.raycast.kernels.cast_ray` from its origin when
``t0 <= 0`` or the point at ``t0`` is occupied or off the grid: the same doubles, operation for
operation (tested). What differs is the order of work. One ray at a time, the cell-by-cell
traversal costs a mispredicted branch at most steps (x or y crossing next?) and waits on each
field read; here every ray takes one step per pass over the list of rays still stepping, with
selects instead of branches, so the passes are branch-free and the reads of different rays
overlap. A ray that leaves the walls (a field value allowing a jump) finishes on its own with
:func:`~racecar_sim.raycast.kernels.traverse`; those are few, as the ``lut`` starts its fallbacks
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
    arrays (their contents are overwritten). The segment of each ray before ``t0`` must be free,
    as for :func:`~racecar_sim.raycast.kernels.cast_ray_from`.
    """
    h = field.shape[0]
    w = field.shape[1]
    flat = field.reshape(-1)
    tmx = fstate[0]
    tmy = fstate[1]
    tdx = fstate[2]
    tdy = fstate[3]
    cell = istate[0]
    sx = istate[1]
    sy = istate[2]
    jumps = istate[3]
    na = 0
    # Setup, as cast_ray_from (then cast_ray where it gives -1); rays starting where a jump is
    # allowed are cast on their own.
    for k in range(n):
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
        tmx[k] = _BIG if ux == 0.0 else ax
        tmy[k] = _BIG if uy == 0.0 else ay
        bx = 1.0 / abs(ux)
        by = 1.0 / abs(uy)
        tdx[k] = _BIG if ux == 0.0 else bx
        tdy[k] = _BIG if uy == 0.0 else by
        sx[k] = 1 if ux > 0.0 else -1
        sy[k] = w if uy > 0.0 else -w
        cell[k] = rv * w + col
        active[na] = k
        na += 1
    # Lockstep: one cell step of every ray still stepping per pass, the list compacted as it
    # goes; a ray that reaches a cell allowing a jump is set aside and finished on its own after.
    nj = 0
    while na > 0:
        nn = 0
        for q in range(na):
            k = np.uint64(active[q])  # unsigned: numba emits no wrap-around test for negatives
            a = tmx[k]
            b = tmy[k]
            go_x = a < b
            # x + 1 * d or x + 0 * d (exactly x): as a select, LLVM made these branches again
            gx = 1.0 if go_x else 0.0
            t = a if go_x else b
            tmx[k] = a + gx * tdx[k]
            tmy[k] = b + (1.0 - gx) * tdy[k]
            c = cell[k] + (sx[k] if go_x else sy[k])
            cell[k] = c
            v = flat[np.uint64(c)]
            clipped = t >= max_t
            out[k] = max_t if clipped else t
            stepping = (v == 0) & ~clipped
            jumps[nj] = k
            nj += (v != 0) & (v != OCCUPIED) & ~clipped
            active[nn] = k
            nn += stepping
        na = nn
    for q in range(nj):
        k = jumps[q]
        t = out[k]
        gu = x[k]
        gv = y[k]
        v = flat[cell[k]]
        out[k] = traverse(
            field, gu, gv, dx[k], dy[k], t, gu + t * dx[k], gv + t * dy[k], 0, 0, v, max_t
        )
