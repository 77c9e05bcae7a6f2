"""Per-ray numba kernels in the padded grid frame, shared by every ray casting method.

Frame used by every kernel here (``pad`` frame, units of cells): the occupancy grid flipped so that
index ``[rv, col]`` has ``rv`` counted from the *bottom* row, with a one-cell ring of occupied cells
around it. A point at map-frame ``(u, v)`` metres is at ``(u / res + 1, v / res + 1)`` cells, and
cell ``(rv, col)`` covers ``[col, col + 1) x [rv, rv + 1)``. The ring makes "leaving the map = hit
at the map edge" fall out of the ordinary occupancy test, so the inner loops do no bounds checks.

The *field* array (uint8, padded shape) merges two maps into one memory read per cell:
``OCCUPIED`` for an occupied cell, otherwise a safe jump length in whole cells: no occupied point is
closer than that to any point of the cell (the distance between the closed cell square and the
nearest occupied square, rounded down), or 0 where a jump is not worth taking.
"""

from __future__ import annotations

import math

import cv2
import numba as nb
import numpy as np

from racecar_sim.raycast.shared_work import fetch_add, run_shared

__all__ = [
    "CHUNK",
    "JUMP_MIN",
    "OCCUPIED",
    "PARALLEL_MIN_RAYS",
    "cast_ray",
    "cast_ray_from",
    "exact_rays",
    "field_from_occupancy",
    "grid_frame",
    "march_ray",
    "march_rays",
    "padded_occupancy",
    "to_metres",
    "traverse",
]

JUMP_MIN = 2
"""Cells: a jump shorter than this is not taken, the traversal steps cell by cell instead."""

OCCUPIED = 255
"""Field value of an occupied cell."""

CHUNK = 1024
"""Rays per work item of the parallel kernels."""

PARALLEL_MIN_RAYS = 16384
"""Below this many rays a cast runs on the calling thread: waking numba's threads costs more, and
on a busy machine a parallel region can stall for milliseconds."""

_JUMP_MARGIN = 1e-3  # cells, absorbs float32 rounding of the distance transform
_BIG = 1e30


def padded_occupancy(occupied: np.ndarray) -> np.ndarray:
    """uint8 (H + 2, W + 2) pad frame: 1 = occupied, ring of 1 around, row 0 = bottom row."""
    occ = np.ones((occupied.shape[0] + 2, occupied.shape[1] + 2), dtype=np.uint8)
    occ[1:-1, 1:-1] = occupied[::-1]
    return occ


def field_from_occupancy(occupied: np.ndarray) -> np.ndarray:
    """uint8 (H + 2, W + 2) pad-frame field: ``OCCUPIED`` (255), else a safe jump in whole cells.

    The distance between the closed squares of cells with integer centre offset ``(a, b)`` is
    ``hypot(max(|a| - 1, 0), max(|b| - 1, 0))``, which is the centre distance to the nearest cell of
    the occupied set dilated by a 3x3 square: one exact Euclidean distance transform gives it. It is
    rounded down to whole cells (at most 254), and set to 0 below ``JUMP_MIN``. One byte per cell
    keeps the field in cache.

    Args:
        occupied: bool (H, W) in the grid frame (row 0 = top of the image).
    """
    occ = padded_occupancy(occupied)
    # Pad once more so the dilation sees the ring as occupied on every side.
    dil = cv2.dilate(np.pad(occ, 1, constant_values=1), np.ones((3, 3), np.uint8))[1:-1, 1:-1]
    dist = cv2.distanceTransform((dil == 0).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    # In place: the same float32 operations without three more map-sized temporaries (a
    # freed 9 MB temporary on Stata stays in the process's resident memory).
    np.subtract(dist, _JUMP_MARGIN, out=dist)
    np.clip(dist, 0.0, 254.0, out=dist)
    np.floor(dist, out=dist)
    jump = dist.astype(np.uint8)
    del dist
    jump[jump < JUMP_MIN] = 0
    jump[occ.astype(bool)] = OCCUPIED
    return np.ascontiguousarray(jump)


@nb.njit(cache=True, inline="always")
def cast_ray_from(field, gu, gv, dx, dy, t0, max_t):
    """Like `cast_ray()` but the traversal starts at parameter ``t0`` (cells) along the ray.

    Returns -1 when the point at ``t0`` is in an occupied cell or off the grid. Exact provided
    the segment before ``t0`` is free (``t0 = 0`` always is).
    """
    h = field.shape[0]
    w = field.shape[1]
    px = gu + t0 * dx
    py = gv + t0 * dy
    if not (px >= 0.0 and px < w and py >= 0.0 and py < h):
        return -1.0
    col = int(px)
    rv = int(py)
    v = field[rv, col]
    if v == OCCUPIED:
        return -1.0
    return traverse(field, gu, gv, dx, dy, t0, px, py, col, rv, v, max_t)


@nb.njit(cache=True, inline="always")
def traverse(field, gu, gv, dx, dy, t, px, py, col, rv, v, max_t):
    """The traversal of `cast_ray_from()` from the free cell ``(col, rv)`` whose field value is
    ``v``, holding the point ``(px, py) = (gu + t dx, gv + t dy)`` at parameter ``t`` (cells).

    With ``v != 0`` it jumps first (``col, rv`` are then recomputed and may be anything); with
    ``v == 0`` it steps cell by cell from that point. Returns the range in cells (``max_t`` if
    clipped).
    """
    step_x = 1 if dx > 0.0 else -1
    step_y = 1 if dy > 0.0 else -1
    tdelta_x = 1.0 / abs(dx) if dx != 0.0 else _BIG
    tdelta_y = 1.0 / abs(dy) if dy != 0.0 else _BIG
    while True:
        if v != 0:
            # Jump through free space; landing stays inside the padded grid (the ring is occupied).
            t += v
            if t >= max_t:
                return max_t
            px = gu + t * dx
            py = gv + t * dy
            col = int(math.floor(px))
            rv = int(math.floor(py))
            v = field[rv, col]
            if v == OCCUPIED:  # only by float rounding at the far end of a jump
                return t
            if v != 0:
                continue
        # Exact traversal from the point at parameter t inside cell (col, rv).
        if dx > 0.0:
            tmax_x = t + (col + 1 - px) / dx
        elif dx < 0.0:
            tmax_x = t + (col - px) / dx
        else:
            tmax_x = _BIG
        if dy > 0.0:
            tmax_y = t + (rv + 1 - py) / dy
        elif dy < 0.0:
            tmax_y = t + (rv - py) / dy
        else:
            tmax_y = _BIG
        while True:
            if tmax_x < tmax_y:
                t = tmax_x
                col += step_x
                tmax_x += tdelta_x
            else:
                t = tmax_y
                rv += step_y
                tmax_y += tdelta_y
            if t >= max_t:
                return max_t
            v = field[rv, col]
            if v == OCCUPIED:
                return t
            if v != 0:
                px = gu + t * dx
                py = gv + t * dy
                break


@nb.njit(cache=True, inline="always")
def cast_ray(field, gu, gv, dx, dy, max_t):
    """Exact range in cells of one ray from (gu, gv) (pad frame, cells) along unit (dx, dy).

    Amanatides–Woo traversal that jumps through free space by the field's safe jumps. Returns the
    parameter where the ray enters the first occupied cell, ``max_t`` if that is farther, and 0 when
    the start is off the grid or in an occupied cell.
    """
    r = cast_ray_from(field, gu, gv, dx, dy, 0.0, max_t)
    return r if r > 0.0 else 0.0


@nb.njit(cache=True, inline="always")
def march_ray(field, gu, gv, dx, dy, max_t, min_step, n_refine):
    """Approximate range in cells by sphere tracing on the field, then bisection.

    Steps by ``max(safe jump, min_step)`` cells (``min_step <= 1``, so a step from a free cell
    stays on the padded grid) until a sample lands in an occupied cell, then bisects the last step
    ``n_refine`` times. A corner cut by less than ``min_step`` at a grazing angle can be missed.
    """
    if not (gu >= 0.0 and gu < field.shape[1] and gv >= 0.0 and gv < field.shape[0]):
        return 0.0
    v = field[int(gv), int(gu)]
    if v == OCCUPIED:
        return 0.0
    t = 0.0
    t_lo = 0.0
    while True:
        t_lo = t
        t += v if v > min_step else min_step
        if t >= max_t:
            t = max_t
        v = field[int(gv + t * dy), int(gu + t * dx)]
        if v == OCCUPIED:
            break
        if t == max_t:
            return max_t
    t_hi = t
    for _ in range(n_refine):
        mid = 0.5 * (t_lo + t_hi)
        if field[int(gv + mid * dy), int(gu + mid * dx)] == OCCUPIED:
            t_hi = mid
        else:
            t_lo = mid
    return 0.5 * (t_lo + t_hi)


@nb.njit(cache=True)
def grid_frame(poses, ox, oy, yaw, res, offset, gu, gv, heading, cos_h, sin_h):
    """World poses (N, 3) -> pad-frame position (cells) and map-frame heading (radians).

    The point ``offset`` metres ahead of each pose along its heading (a lidar's mount; 0 for
    the pose itself) is moved into the map frame of an origin ``(ox, oy, yaw)`` (the inverse of
    the map's origin transform), divided by the resolution ``res`` and shifted by the pad ring.
    Fills ``gu``, ``gv``, ``heading = theta - yaw`` and its cos/sin in one pass (the cos/sin
    within a few ulps of ``math.cos(heading)``, ``math.sin(heading)``).
    """
    cy = math.cos(yaw)
    sy = math.sin(yaw)
    for i in range(poses.shape[0]):
        th = poses[i, 2]
        c = math.cos(th)
        s = math.sin(th)
        x = poses[i, 0] + offset * c
        y = poses[i, 1] + offset * s
        dx = x - ox
        dy = y - oy
        gu[i] = (cy * dx + sy * dy) / res + 1.0
        gv[i] = (-sy * dx + cy * dy) / res + 1.0
        heading[i] = th - yaw
        # cos and sin of th - yaw by the difference formulas: two trig calls per pose, not four
        # (equal to cos(th - yaw), sin(th - yaw) within a few ulps)
        cos_h[i] = c * cy + s * sy
        sin_h[i] = s * cy - c * sy


@nb.njit(cache=True, inline="always")
def to_metres(r, max_t, scale, max_out):
    """A range in cells to the output unit: ``max_out`` exactly when clipped, else ``r * scale``."""
    return max_out if r >= max_t else r * scale


@nb.njit(cache=True)
def _exact_span(field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, scale, max_out, out, q0, q1):
    """Rays ``q0 <= q < q1`` (pose ``q // M``, beam ``q % M``) of `exact_rays()`."""
    m = cos_a.shape[0]
    for q in range(q0, q1):
        i = q // m
        b = q - i * m
        dx = cos_h[i] * cos_a[b] - sin_h[i] * sin_a[b]
        dy = sin_h[i] * cos_a[b] + cos_h[i] * sin_a[b]
        r = cast_ray(field, gu[i], gv[i], dx, dy, max_t)
        out[i, b] = to_metres(r, max_t, scale, max_out)


@nb.njit(cache=True, nogil=True)
def _exact_shared(field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, scale, max_out, out, counter):
    """`_exact_span()` over chunks of ``CHUNK`` rays taken from ``counter`` (shared work)."""
    total = gu.shape[0] * cos_a.shape[0]
    while True:
        q0 = fetch_add(counter, 1) * CHUNK
        if q0 >= total:
            break
        _exact_span(
            field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, scale, max_out, out, q0,
            min(total, q0 + CHUNK),
        )  # fmt: skip


@nb.njit(cache=True)
def _march_span(
    field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, min_step, n_refine, scale, max_out, out,
    q0, q1,
):  # fmt: skip
    """Rays ``q0 <= q < q1`` of `march_rays()`."""
    m = cos_a.shape[0]
    for q in range(q0, q1):
        i = q // m
        b = q - i * m
        dx = cos_h[i] * cos_a[b] - sin_h[i] * sin_a[b]
        dy = sin_h[i] * cos_a[b] + cos_h[i] * sin_a[b]
        r = march_ray(field, gu[i], gv[i], dx, dy, max_t, min_step, n_refine)
        out[i, b] = to_metres(r, max_t, scale, max_out)


@nb.njit(cache=True, nogil=True)
def _march_shared(
    field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, min_step, n_refine, scale, max_out, out,
    counter,
):  # fmt: skip
    """`_march_span()` over chunks of ``CHUNK`` rays taken from ``counter`` (shared work)."""
    total = gu.shape[0] * cos_a.shape[0]
    while True:
        q0 = fetch_add(counter, 1) * CHUNK
        if q0 >= total:
            break
        _march_span(
            field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, min_step, n_refine, scale, max_out,
            out, q0, min(total, q0 + CHUNK),
        )  # fmt: skip


def exact_rays(field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, scale, max_out, out, parallel):
    """Fill ``out`` (N, M) with exact ranges: cells times ``scale``, exactly ``max_out`` if clipped.

    Poses as pad-frame (gu, gv) in cells and heading cos/sin in the map frame; beams as cos/sin
    relative to the heading; ``max_t`` in cells. ``parallel``: share chunks of rays among numba's
    thread count of threads (`shared_work`; worth it from about
    `PARALLEL_MIN_RAYS` rays).
    """
    if parallel:
        args = (field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, scale, max_out, out)
        run_shared(_exact_shared, args, nb.get_num_threads())
    else:
        _exact_span(
            field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, scale, max_out, out, 0, out.size
        )


def march_rays(
    field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, min_step, n_refine, scale, max_out, out,
    parallel,
):  # fmt: skip
    """Like `exact_rays()` with `march_ray()` (approximate)."""
    args = (field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, min_step, n_refine, scale, max_out)
    if parallel:
        run_shared(_march_shared, (*args, out), nb.get_num_threads())
    else:
        _march_span(*args, out, 0, out.size)
