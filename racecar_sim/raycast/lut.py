"""Lookup-table ray casting for particles: the query (the table: `lut_table`, its build:
`lut_build`).

Everything here works in the pad frame of `racecar_sim.raycast.kernels` (cells).

Query
    A pose's cell row and the two directions ``k0, k1`` bracketing the ray give ranges ``r0, r1``
    and hit points ``H = F + r d``. When ``|r0 - r1| <= tolerance``, or the table flags the pair
    as one straight face, the range is where the ray from the true position meets the line
    ``H0 H1``: exact for a straight wall seen by both table rays, and it corrects for where the
    pose lies inside its cell. Otherwise (corners, occluding edges, grazing walls) the ray is cast
    exactly, starting ``guide`` before the nearer table hit (or from the pose if that point is
    occupied): this *guided* fallback misses only an obstacle that both table rays passed.
Kernel layout
    Per pose, three loops over the beams (the vectorised ones in `lut_beams`): (1) the
    bracketing directions in 32-bit fixed point
    (a turn is 2**32) and the two table entries; (2) the interpolation, branch-free, so LLVM
    vectorises it (SIMD division; the bracketing directions come from the ray's by a rotation
    through the fixed-point remainder, a short Taylor series, instead of table look-ups);
    (3) the list of rays to cast, without branches. The rays to cast of a group of poses are cast
    together, in lockstep (`fallback`: the same doubles as casting them one by one, about
    1.5x faster), then the group's output is written (ranges, or the score look-ups).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from racecar_sim.raycast.fallback import guided_casts
from racecar_sim.raycast.kernels import to_metres
from racecar_sim.raycast.lut_beams import (
    MASK32,
    SANE,
    TURN,
    column,
    directions,
    interpolate,
    unpack,
)
from racecar_sim.raycast.lut_build import PARALLEL_MIN_ENTRIES, build_lut
from racecar_sim.raycast.lut_table import LutTable
from racecar_sim.raycast.morton import spread_order
from racecar_sim.raycast.prefetch import prefetch
from racecar_sim.raycast.shared_work import fetch_add, run_shared
from racecar_sim.settings.validation import check_number

__all__ = ["PARALLEL_MIN_ENTRIES", "LutParams", "LutTable", "build_lut", "lut_rays", "lut_score"]

_GROUP = 16  # poses whose fallback casts go together (about 8 per pose at 100 beams)
_BLOCK_RAYS = 8192  # rays per item of the shared query: 80 poses at 100 beams, 0.05-0.1 ms


@dataclass(frozen=True)
class LutParams:
    """Parameters of the ``"lut"`` ray casting method (defaults measured on the Stata basement).

    Attributes:
        n_angles: K, table directions over the full turn. Memory is ``2 K`` bytes per free cell.
            On the Stata basement K = 180, 256 and 360 gave the same accuracy; more directions
            mean fewer exact fallbacks (faster queries) but a larger table and a longer build.
        sub_lines: sweep lines per cell width; a table entry is the range from a point at most
            ``0.5 / sub_lines`` cells beside the cell centre. Build time grows with it (2 and 4
            gave the same accuracy).
        tolerance: metres; where the two bracketing directions' ranges differ by more and the
            table does not flag them as one straight face, the ray is cast exactly instead of
            interpolated. Smaller is more accurate and slower.
        guide: metres; the exact fallback starts this far before the nearer of the two table hits.
            ``math.inf`` makes every fallback an exact cast from the pose (slower, slightly more
            accurate).
        sort_extent: metres; a batch of poses whose bounding box is at least this wide (on
            either axis) is cast in Z-order of its cells (`morton`) and the results are
            scattered back: the same numbers, fewer cache misses on a cloud spread over the map
            (global localization). ``math.inf`` never sorts. A tracking cloud is narrower.
    """

    n_angles: int = 360
    sub_lines: int = 2
    tolerance: float = 0.05
    guide: float = 0.10
    sort_extent: float = 10.0

    def __post_init__(self) -> None:
        for name in ("n_angles", "sub_lines"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool):
                raise ValueError(f"LutParams.{name} must be an integer, got {value!r}")
        check_number("LutParams", "n_angles", self.n_angles, low=8, high=65536)
        check_number("LutParams", "sub_lines", self.sub_lines, low=1, high=16)
        check_number("LutParams", "tolerance", self.tolerance, low=0.0)
        check_number("LutParams", "guide", self.guide, low=0.0, allow_inf=True)
        check_number("LutParams", "sort_extent", self.sort_extent, low=0.0, allow_inf=True)


@nb.njit(cache=True, inline="always")
def _pose_row(index, x, y):
    """Table row of the free cell holding (x, y) (pad frame, cells), or -1."""
    if not (x >= 0.0 and x < index.shape[1] and y >= 0.0 and y < index.shape[0]):
        return -1
    return index[int(y), int(x)]


_AHEAD = 2  # poses: a row is prefetched this many poses before it is read


@nb.njit(cache=True, inline="always")
def _prefetch_row(index, table, gu, gv, i, i1):
    """Prefetch the table row of pose ``i < i1`` (if any), so that its cache misses overlap the
    work of the poses before it. Prefetches, not loads: a load that misses must complete before
    the work behind it retires (reading the next far row into a sum instead was 8-15 % slower on
    a spread cloud; on a tracking cloud the rows are in cache and the prefetches cost nothing)."""
    if i < i1:
        fn = _pose_row(index, gu[i], gv[i])
        if fn >= 0:
            k_angles = table.shape[1]
            start = fn * k_angles
            for k in range(0, k_angles, 32):  # 32 entries: one 64-byte line
                prefetch(table, start + k)
            prefetch(table, start + k_angles - 1)  # a row need not start on a line


@nb.njit(cache=True, error_model="numpy")
def _lut_poses(
    table, index, unit, sub, tol, guide, field, gu, gv, heading, cos_h, sin_h,
    afix, cos_a, sin_a, max_t, scale, max_out, ranges, rows, per_out, top, scores, terms, i0, i1,
):  # fmt: skip
    """Poses ``i0 <= i < i1``: their rays' ranges into ``ranges`` (N, M), or, when ``ranges`` is
    empty, ``scores[i] = sum_b rows[b, round(clip(range * per_out, 0, top))]``, each term also
    into ``terms[i, b]`` when ``terms`` is not empty.

    ``heading`` (N,) radians, map frame; ``afix`` (M,) int64 beam angles in fixed point (a turn
    is 2**32, see `_fixed()`). ``error_model="numpy"``: a float division raises nothing, which
    lets LLVM vectorise loop (2) of the module docstring.
    """
    m = cos_a.shape[0]
    n_angles = table.shape[1]
    inv_sub = 1.0 / sub
    delta = 2.0 * math.pi / n_angles
    cos_d = math.cos(delta)
    sin_d = math.sin(delta)
    phi_unit = delta / TURN
    tol_code = tol / unit
    sat = max_t + SANE  # both table ranges beyond this: the ray reaches max range
    want_ranges = ranges.shape[0] > 0
    want_terms = terms.shape[0] > 0
    kb = np.empty(m, dtype=np.int64)
    e0b = np.empty(m, dtype=np.uint16)
    e1b = np.empty(m, dtype=np.uint16)
    c0b = np.empty(m, dtype=np.float32)
    c1b = np.empty(m, dtype=np.float32)
    phb = np.empty(m, dtype=np.float32)
    cos_a32 = cos_a.astype(np.float32)
    sin_a32 = sin_a.astype(np.float32)
    f32 = np.float32
    # Poses go in groups of _GROUP: their fallbacks are cast together (see .fallback).
    group = max(1, min(_GROUP, i1 - i0))  # a single scan's call allocates for one pose only
    cap = group * m
    tbs = np.empty((group, m), dtype=np.float32)
    dbs = np.empty((group, m))
    off_map = np.empty(group, dtype=np.bool_)
    f_slot = np.empty(cap, dtype=np.int64)
    f_x = np.empty(cap)
    f_y = np.empty(cap)
    f_dx = np.empty(cap)
    f_dy = np.empty(cap)
    f_t0 = np.empty(cap)
    f_t = np.empty(cap)
    f_state = np.empty((4, cap))
    i_state = np.empty((4, cap), dtype=np.int64)
    active = np.empty(cap, dtype=np.int64)
    for i in range(i0, min(i1, i0 + _AHEAD)):
        _prefetch_row(index, table, gu, gv, i, i1)
    for g0 in range(i0, i1, group):
        g1 = min(i1, g0 + group)
        nf = 0
        for i in range(g0, g1):
            j = i - g0
            x = gu[i]
            y = gv[i]
            fi = _pose_row(index, x, y)
            _prefetch_row(index, table, gu, gv, i + _AHEAD, i1)
            off_map[j] = fi < 0
            if fi < 0:  # in a wall or off the map: every range is 0
                continue
            cx = int(x) + 0.5
            cy = int(y) + 0.5
            ch = cos_h[i]
            sh = sin_h[i]
            hf = heading[i] / (2.0 * math.pi)
            hb = np.int64((hf - math.floor(hf)) * TURN) & MASK32
            # (1) bracketing directions (vectorised) and table entries (gathers)
            directions(hb, afix, n_angles, phi_unit, kb, phb)
            row = table[fi]
            for b in range(m):
                k0 = kb[b]
                # unsigned indexes: no wrap-around test for negative ones (3 % faster)
                e0b[b] = row[np.uint64(k0)]
                e1b[b] = row[np.uint64(k0 + 1 if k0 + 1 < n_angles else 0)]
            unpack(e0b, e1b, c0b, c1b)
            # (2) interpolation, branch-free (vectorised); -1 marks a ray to cast
            tb = tbs[j]
            interpolate(
                phb, c0b, c1b, cos_a32, sin_a32, f32(ch), f32(sh), f32(cx - x), f32(cy - y),
                f32(cx * sub), f32(cy * sub), f32(inv_sub), f32(unit), f32(cos_d), f32(sin_d),
                f32(tol_code), f32(sat), f32(max_t), max_t, scale, max_out, per_out, top, tb,
                dbs[j],
            )  # fmt: skip
            # (3) the rays to cast (corners, occluding edges, grazing walls), listed without
            # branches, with where their guided casts start
            n0 = nf
            for b in range(m):
                f_slot[nf] = j * m + b
                nf += tb[b] < 0.0
            for q in range(n0, nf):
                b = f_slot[q] - j * m
                f_x[q] = x
                f_y[q] = y
                f_dx[q] = ch * cos_a[b] - sh * sin_a[b]
                f_dy[q] = sh * cos_a[b] + ch * sin_a[b]
                f_t0[q] = min(abs(c0b[b]), c1b[b]) * unit - guide
        guided_casts(field, f_x, f_y, f_dx, f_dy, f_t0, max_t, nf, f_t, f_state, i_state, active)
        for q in range(nf):
            j = f_slot[q] // m
            b = f_slot[q] - j * m
            t = f_t[q]
            tbs[j, b] = t
            dbs[j, b] = column(to_metres(t, max_t, scale, max_out), per_out, top)
        # output
        for i in range(g0, g1):
            j = i - g0
            if want_ranges:
                for b in range(m):
                    ranges[i, b] = (
                        0.0
                        if off_map[j]
                        else to_metres(np.float64(tbs[j, b]), max_t, scale, max_out)
                    )
            else:
                acc = 0.0
                for b in range(m):
                    term = rows[b, 0] if off_map[j] else rows[b, int(dbs[j, b])]
                    acc += term
                    if want_terms:
                        terms[i, b] = term
                scores[i] = acc


@nb.njit(cache=True, nogil=True)
def _lut_shared(
    table, index, unit, sub, tol, guide, field, gu, gv, heading, cos_h, sin_h,
    afix, cos_a, sin_a, max_t, scale, max_out, ranges, rows, per_out, top, scores, terms, counter,
):  # fmt: skip
    """`_lut_poses()` over blocks of about ``_BLOCK_RAYS`` rays taken from ``counter`` until
    none is left (see `shared_work`); one of the threads that share the poses."""
    n = gu.shape[0]
    blk = max(1, _BLOCK_RAYS // max(1, cos_a.shape[0]))
    while True:
        i0 = fetch_add(counter, 1) * blk
        if i0 >= n:
            break
        _lut_poses(
            table, index, unit, sub, tol, guide, field, gu, gv, heading, cos_h, sin_h,
            afix, cos_a, sin_a, max_t, scale, max_out, ranges, rows, per_out, top, scores, terms,
            i0, min(n, i0 + blk),
        )  # fmt: skip


_NO_RANGES = np.empty((0, 0), dtype=np.float64)
_NO_ROWS = np.empty((0, 1), dtype=np.float64)
_NO_SCORES = np.empty(0, dtype=np.float64)


def _fixed(angles: np.ndarray) -> np.ndarray:
    """Angles (radians) as int64 fixed point in [0, 2**32): a full turn is 2**32."""
    turns = np.asarray(angles, dtype=np.float64) / (2.0 * math.pi)
    return np.floor((turns - np.floor(turns)) * TURN).astype(np.int64) & MASK32


def _run(lut, tol, guide, field, gu, gv, heading, cos_h, sin_h, angles, cos_a, sin_a, max_t,
         scale, max_out, ranges, rows, per_out, top, scores, parallel, sort_cells,
         terms=None):  # fmt: skip
    heading = np.ascontiguousarray(heading, dtype=np.float64)
    order = spread_order(gu, gv, sort_cells)
    terms = _NO_RANGES if terms is None else terms
    out_ranges, out_scores, out_terms = ranges, scores, terms
    if order is not None:  # cast in Z-order, scatter back below (each pose's numbers unchanged)
        gu, gv, heading, cos_h, sin_h = (a[order] for a in (gu, gv, heading, cos_h, sin_h))
        if ranges.shape[0] > 0:
            ranges = np.empty_like(ranges)
        if scores.shape[0] > 0:
            scores = np.empty_like(scores)
        if terms.shape[0] > 0:
            terms = np.empty_like(terms)
    args = (
        lut.table, lut.index, lut.unit, float(lut.sub_lines), float(tol), float(guide), field,
        gu, gv, heading, cos_h, sin_h, _fixed(angles),
        cos_a, sin_a, float(max_t), float(scale), float(max_out), ranges, rows, float(per_out),
        float(top), scores, terms,
    )  # fmt: skip
    if parallel:
        run_shared(_lut_shared, args, nb.get_num_threads())
    else:
        _lut_poses(*args, 0, gu.shape[0])
    if order is not None:
        if ranges.shape[0] > 0:
            out_ranges[order] = ranges
        if scores.shape[0] > 0:
            out_scores[order] = scores
        if terms.shape[0] > 0:
            out_terms[order] = terms


def lut_rays(
    lut: LutTable,
    tol: float,
    guide: float,
    field: np.ndarray,
    gu: np.ndarray,
    gv: np.ndarray,
    heading: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    angles: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    max_t: float,
    scale: float,
    max_out: float,
    out: np.ndarray,
    parallel: bool,
    sort_cells: float = math.inf,
) -> None:
    """Fill ``out`` (N, M) with table ranges: cells times ``scale``, exactly ``max_out`` if clipped.

    Poses as pad-frame (gu, gv) in cells and heading (radians, map frame) with its cos/sin; beams
    as angles relative to the heading with their cos/sin. ``tol``, ``guide``, ``max_t`` in cells.
    ``field`` is the exact kernel's field, for the fallback casts. Poses whose bounding box is
    at least ``sort_cells`` wide are cast in Z-order (`morton`); the output is the same.
    """
    _run(
        lut, tol, guide, field, gu, gv, heading, cos_h, sin_h, angles, cos_a, sin_a, max_t,
        scale, max_out, out, _NO_ROWS, 1.0, 0.0, _NO_SCORES, parallel, sort_cells,
    )  # fmt: skip


def lut_score(
    lut: LutTable,
    tol: float,
    guide: float,
    field: np.ndarray,
    gu: np.ndarray,
    gv: np.ndarray,
    heading: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    angles: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    max_t: float,
    scale: float,
    max_out: float,
    rows: np.ndarray,
    per_out: float,
    out: np.ndarray,
    parallel: bool,
    sort_cells: float = math.inf,
    terms: np.ndarray | None = None,
) -> None:
    """``out[i] = sum_b rows[b, round(clip(range_ib * per_out, 0, W - 1))]`` without storing ranges.

    ``range_ib`` is exactly what `lut_rays()` writes for pose ``i`` and beam ``b`` (same
    arguments); ``rows`` is a float64 (M, W) table of per-beam scores (a sensor model's log
    likelihood row of each beam's measured range), ``per_out`` converts the output unit to row
    columns. Cast and score share one pass over the poses, so the (N, M) ranges never reach memory;
    ``terms`` (N, M) float64, when given, receives each ray's score ``rows[b, ...]``.
    """
    _run(
        lut, tol, guide, field, gu, gv, heading, cos_h, sin_h, angles, cos_a, sin_a, max_t,
        scale, max_out, _NO_RANGES, rows, per_out, float(rows.shape[1] - 1), out, parallel,
        sort_cells, terms,
    )  # fmt: skip
