"""Building the lookup table of the ``"lut"`` ray casting method (its format: `lut_table`;
its planar flags: `lut_flags`; the query: `lut`).

In the spirit of range_libc's CDDT/GLT (Walsh & Karaman, ICRA 2018), with its own build and query.
Everything here works in the pad frame of `racecar_sim.raycast.kernels` (cells).

Build: one sweep per direction (parallel over directions)
    For direction ``theta_k`` with normal ``n_k``, the parallel lines ``s = (j + 1/2) / sub``
    (``s`` the coordinate along ``n_k``) are each walked once, Amanatides–Woo, from one side of the
    map to the other, jumping through wide occupied areas. Every free cell is *owned* by the line
    nearest its centre (at most ``0.5 / sub`` cells away, so the line crosses the cell) and gets
    the exact range along that line from the foot ``F_k`` of its centre to the first occupied cell
    the line enters. Cost: one walk over the map per direction and line spacing, instead of one cast
    per (cell, direction); directions are swept in blocks and scattered into the row-major table.
"""

from __future__ import annotations

import math
import time

import cv2
import numba as nb
import numpy as np

from racecar_sim.raycast.kernels import cast_ray
from racecar_sim.raycast.lut_flags import flag_parallel, flag_rows
from racecar_sim.raycast.lut_table import (
    CAP_MARGIN,
    CODE_MAX,
    FLAG_ABOVE,
    FLAG_EPS,
    LutTable,
)

__all__ = ["PARALLEL_MIN_ENTRIES", "build_lut"]

PARALLEL_MIN_ENTRIES = 4_000_000
"""Tables with fewer entries (free cells x directions) are built on the calling thread."""

_UNSET = 65535  # marks an entry the sweep has not written yet
@nb.njit(cache=True, inline="always")
def _store(row, pend_i, pend_t, npend, t_hit, unit, cap):
    for q in range(npend):
        r = min(max(t_hit - pend_t[q], 0.0), cap)
        row[pend_i[q]] = np.uint16(int(r / unit + 0.5))


@nb.njit(cache=True)
def _sweep_direction(kind, index, th, sub, box, unit, cap, row, pend_i, pend_t):
    """Fill ``row`` (uint16 code per free cell) for direction ``th`` (radians, map frame).

    ``kind``: uint8 pad frame, 0 for a free cell, ``1 + skip`` for an occupied cell from which no
    free cell is nearer than ``skip`` cells. ``index``: int32 pad frame, free-cell rows. Lines
    ``s = (j + 1/2) / sub`` are walked once each; a free cell is owned by the line nearest its
    centre. Returns the number of entries written.
    """
    dx = math.cos(th)
    dy = math.sin(th)
    nx = -dy
    ny = dx
    u0, u1, v0, v1 = box[0], box[1], box[2], box[3]
    s_lo = min(u0 * nx, u1 * nx) + min(v0 * ny, v1 * ny)
    s_hi = max(u0 * nx, u1 * nx) + max(v0 * ny, v1 * ny)
    step_x = 1 if dx > 0.0 else -1
    step_y = 1 if dy > 0.0 else -1
    tdelta_x = 1.0 / abs(dx) if dx != 0.0 else 1e30
    tdelta_y = 1.0 / abs(dy) if dy != 0.0 else 1e30
    written = 0
    for j in range(int(math.floor(s_lo * sub)) - 1, int(math.floor(s_hi * sub)) + 1):
        s = (j + 0.5) / sub
        bx = s * nx
        by = s * ny
        t_lo = -1e30
        t_hi = 1e30
        if dx != 0.0:
            ta = (u0 - bx) / dx
            tb = (u1 - bx) / dx
            t_lo = max(t_lo, min(ta, tb))
            t_hi = min(t_hi, max(ta, tb))
        elif not (u0 < bx < u1):
            continue
        if dy != 0.0:
            ta = (v0 - by) / dy
            tb = (v1 - by) / dy
            t_lo = max(t_lo, min(ta, tb))
            t_hi = min(t_hi, max(ta, tb))
        elif not (v0 < by < v1):
            continue
        if t_hi - t_lo < 1e-9:
            continue
        t = t_lo
        px = bx + t * dx
        py = by + t * dy
        col = min(max(int(math.floor(px + 1e-9 * dx)), u0), u1 - 1)
        rv = min(max(int(math.floor(py + 1e-9 * dy)), v0), v1 - 1)
        npend = 0
        while True:
            # (px, py) at parameter t lies in cell (col, rv); set up the exact walk from there.
            if dx > 0.0:
                tmax_x = t + (col + 1 - px) / dx
            elif dx < 0.0:
                tmax_x = t + (col - px) / dx
            else:
                tmax_x = 1e30
            if dy > 0.0:
                tmax_y = t + (rv + 1 - py) / dy
            elif dy < 0.0:
                tmax_y = t + (rv - py) / dy
            else:
                tmax_y = 1e30
            jumped = False
            while True:
                c = kind[rv, col]
                if c != 0:
                    if npend > 0:
                        _store(row, pend_i, pend_t, npend, t, unit, cap)
                        written += npend
                        npend = 0
                    if c > 3:  # at least 3 cells of occupied space around: jump along the line
                        t += c - 1
                        jumped = True
                        break
                else:
                    cx = col + 0.5
                    cy = rv + 0.5
                    if int(math.floor((cx * nx + cy * ny) * sub)) == j:
                        pend_i[npend] = index[rv, col]
                        pend_t[npend] = cx * dx + cy * dy
                        npend += 1
                if tmax_x < tmax_y:
                    t = tmax_x
                    col += step_x
                    tmax_x += tdelta_x
                else:
                    t = tmax_y
                    rv += step_y
                    tmax_y += tdelta_y
                if col < u0 or col >= u1 or rv < v0 or rv >= v1:
                    break
            if not jumped or t >= t_hi:
                break
            px = bx + t * dx
            py = by + t * dy
            # clamped as at the entry: rounding may put the landing point on the box's far edge
            col = min(max(int(math.floor(px)), u0), u1 - 1)
            rv = min(max(int(math.floor(py)), v0), v1 - 1)
        if npend > 0:
            _store(row, pend_i, pend_t, npend, t, unit, cap)
            written += npend
    return written


@nb.njit(cache=True)
def _sweep_rows(kind, index, n_angles, k_start, r_lo, r_hi, sub, box, unit, cap, buf, written):
    """Sweep directions ``k_start + r`` into ``buf[r]`` for ``r_lo <= r < r_hi``."""
    n_buf = (box[1] - box[0]) + (box[3] - box[2]) + 4
    pend_i = np.empty(n_buf, dtype=np.int64)
    pend_t = np.empty(n_buf, dtype=np.float64)
    for r in range(r_lo, r_hi):
        k = k_start + r
        if k >= n_angles:
            break
        th = 2.0 * math.pi * k / n_angles
        written[k] = _sweep_direction(kind, index, th, sub, box, unit, cap, buf[r], pend_i, pend_t)


@nb.njit(cache=True, parallel=True)
def _sweep_parallel(kind, index, n_angles, k_start, sub, box, unit, cap, buf, written):
    """`_sweep_rows()` over all of ``buf``, one direction per work item."""
    for r in nb.prange(buf.shape[0]):
        _sweep_rows(kind, index, n_angles, k_start, r, r + 1, sub, box, unit, cap, buf, written)


@nb.njit(cache=True)
def _scatter_rows(buf, k_start, table, i_lo, i_hi):
    """``table[i, k_start + r] = buf[r, i]`` for ``i_lo <= i < i_hi`` and the block's rows."""
    n_rows = min(buf.shape[0], table.shape[1] - k_start)
    for i in range(i_lo, i_hi):
        for r in range(n_rows):
            table[i, k_start + r] = buf[r, i]


@nb.njit(cache=True, parallel=True)
def _scatter_parallel(buf, k_start, table):
    """`_scatter_rows()` over every table row, in blocks of 1024 rows."""
    n = table.shape[0]
    blk = 1024
    for bi in nb.prange((n + blk - 1) // blk):
        _scatter_rows(buf, k_start, table, bi * blk, min(bi * blk + blk, n))


@nb.njit(cache=True, parallel=True)
def _fill_unset(field, index, cells, out, unit, cap):
    """Exact casts from the centres of (cell, direction) entries the sweep left unset."""
    n_angles = out.shape[1]
    for q in nb.prange(cells.shape[0]):
        rv = cells[q, 0]
        col = cells[q, 1]
        k = cells[q, 2]
        th = 2.0 * math.pi * k / n_angles
        r = cast_ray(field, col + 0.5, rv + 0.5, math.cos(th), math.sin(th), cap)
        out[index[rv, col], k] = np.uint16(int(min(r, cap) / unit + 0.5))


def _cell_kinds(occ_pad: np.ndarray) -> np.ndarray:
    """uint8 pad frame: 0 free, ``1 + skip`` occupied (see `_sweep_direction()`)."""
    free = occ_pad == 0
    # Distance between closed squares = centre distance to the 3x3-dilated set (as for the field).
    near_free = cv2.dilate(free.astype(np.uint8), np.ones((3, 3), np.uint8))
    dist = cv2.distanceTransform(
        (near_free == 0).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE
    )
    skip = np.floor(np.clip(dist - 1e-3, 0.0, 254.0)).astype(np.uint8)
    kind = skip + np.uint8(1)
    kind[free] = 0
    return np.ascontiguousarray(kind)


def build_lut(
    occ_pad: np.ndarray,
    field: np.ndarray,
    max_cells: float,
    n_angles: int,
    sub: int = 1,
    block: int = 32,
    flag_above: float = FLAG_ABOVE,
    flag_eps: float = FLAG_EPS,
) -> LutTable:
    """Build the table for a pad-frame occupancy (uint8, 1 = occupied, occupied ring).

    Args:
        occ_pad: uint8 (H + 2, W + 2) pad frame.
        field: the matching exact-kernel field (for entries the sweep might leave unset).
        max_cells: the caster's max range in cells.
        n_angles: K.
        sub: sweep lines per cell width; a table entry is the range from a point at most
            ``0.5 / sub`` cells beside the cell centre.
        block: directions swept per pass before they are scattered into the table.
        flag_above: cells; pairs of ranges differing by more are checked for the planar flag
            (``math.inf``: no flags).
        flag_eps: cells; the planar check's allowance (module docstring).
    """
    start = time.perf_counter()
    kind = _cell_kinds(occ_pad)
    free = kind == 0
    n_free = int(np.count_nonzero(free))
    index = np.full(occ_pad.shape, -1, dtype=np.int32)
    index[free] = np.arange(n_free, dtype=np.int32)
    rows = np.flatnonzero(free.any(axis=1))
    cols = np.flatnonzero(free.any(axis=0))
    # Free bounding box plus its occupied ring (always inside the padded grid): lines leave the
    # box only after entering an occupied cell.
    box = np.array([cols[0] - 1, cols[-1] + 2, rows[0] - 1, rows[-1] + 2], dtype=np.int64)
    cap = float(max_cells) + CAP_MARGIN
    unit = cap / CODE_MAX
    table = np.empty((n_free, n_angles), dtype=np.uint16)
    buf = np.empty((min(block, n_angles), n_free), dtype=np.uint16)
    written = np.zeros(n_angles, dtype=np.int64)
    parallel = n_free * n_angles >= PARALLEL_MIN_ENTRIES
    for k_start in range(0, n_angles, buf.shape[0]):
        buf.fill(_UNSET)
        if parallel:
            _sweep_parallel(kind, index, n_angles, k_start, int(sub), box, unit, cap, buf, written)
            _scatter_parallel(buf, k_start, table)
        else:
            _sweep_rows(
                kind, index, n_angles, k_start, 0, len(buf), int(sub), box, unit, cap, buf, written
            )
            _scatter_rows(buf, k_start, table, 0, n_free)
    if (written != n_free).any():  # a cell its owner line did not visit (float ties): cast it
        unset = np.argwhere(table == _UNSET)
        fi_rows, fi_cols = np.nonzero(free)
        cells = np.column_stack([fi_rows[unset[:, 0]], fi_cols[unset[:, 0]], unset[:, 1]])
        _fill_unset(field, index, cells.astype(np.int64), table, unit, cap)
    theta = 2.0 * math.pi * np.arange(n_angles + 1) / n_angles
    mid = theta[:-1] + math.pi / n_angles
    fi_rows, fi_cols = np.nonzero(free)
    flag_args = (
        table, fi_rows.astype(np.int64), fi_cols.astype(np.int64), field, unit, float(sub),
        np.cos(theta), np.sin(theta), np.cos(mid), np.sin(mid), cap, float(flag_above),
        float(flag_eps),
    )  # fmt: skip
    if parallel:
        n_flagged = int(flag_parallel(*flag_args))
    else:
        n_flagged = int(flag_rows(*flag_args, 0, n_free))
    return LutTable(
        table=table,
        index=index,
        unit=unit,
        sub_lines=int(sub),
        cos_k=np.cos(theta),
        sin_k=np.sin(theta),
        build_seconds=time.perf_counter() - start,
        n_flagged=n_flagged,
    )
