"""One lidar scan in one numba call: mount pose, exact cast of every beam and the beam noise.

The simulated lidar casts a single scan (1080 beams) per step. Through [`RayCaster.cast()`][RayCaster.cast] that
is a dozen numpy operations on one pose, a kernel call and a second kernel call for the noise; here
it is one call whose arithmetic is the same, operation for operation, as
[`cast_ray()`][racecar_sim.raycast.kernels.cast_ray] after [`RayCaster.cast()`][RayCaster.cast]'s frame change, and as
the noise of [`racecar_sim.sensors.lidar.Lidar.add_noise()`][racecar_sim.sensors.lidar.Lidar.add_noise] (`add_beam_noise()`, which draws its
uniforms and normals itself from a `racecar_sim.raycast.rand` stream seeded once per scan): the ranges
are the same doubles and the noisy scan the same floats (tested).

The per-ray traversal is [`cast_ray()`][racecar_sim.raycast.kernels.cast_ray] written for one origin:
the beams go through its phases together (see `_exact_scan()`), the flat cell index stepped
along in the exact traversal instead of recomputed, truncation instead of ``floor`` (coordinates
inside the padded grid are never negative).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.raycast.kernels import OCCUPIED
from racecar_sim.raycast.rand import uniforms_and_normals
from racecar_sim.raycast.shared_work import fetch_add, run_shared

__all__ = [
    "GEOMETRY_FIELDS",
    "NOISE_FIELDS",
    "add_beam_noise",
    "exact_one",
    "scan_geometry",
    "scan_with_noise",
    "scans_serial_nogil",
    "scans_shared",
    "scans_with_noise",
]

_BIG = 1e30

GEOMETRY_FIELDS = ("origin_x", "origin_y", "cos_yaw", "sin_yaw", "resolution", "yaw", "mount",
                   "max_cells", "max_range")  # fmt: skip
"""Layout of the float64 ``geometry`` array (world origin of the map, metres; its yaw, radians;
cos and sin of the yaw; metres per cell; lidar mount offset ahead of the rear axle, metres; the
range limit in cells and in metres)."""

NOISE_FIELDS = ("sigma", "max_range", "p_rand", "p_max", "p_short", "short_lambda")
"""Layout of the float64 ``noise`` array (see [`LidarParams`][racecar_sim.settings.config.LidarParams])."""


def scan_geometry(occupancy_map, max_range: float, mount_offset: float) -> np.ndarray:
    """The ``geometry`` array of `scan_with_noise()` for a map, a range (m) and a mount (m)."""
    yaw = float(occupancy_map.yaw)
    res = float(occupancy_map.resolution)
    return np.array(
        [
            float(occupancy_map.origin[0]),
            float(occupancy_map.origin[1]),
            math.cos(yaw),
            math.sin(yaw),
            res,
            yaw,
            float(mount_offset),
            float(max_range) / res,
            float(max_range),
        ]
    )


@nb.njit(cache=True, boundscheck=False)
def _exact_scan(field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, limits, scale, max_out, ranges):
    """Exact ranges (metres) of beams ``cos_a, sin_a`` from pad-frame (gu, gv), heading (cos, sin).

    ``limits``: None, or (M,) per-beam traversal limits in cells, each at most ``max_t``: a beam
    stops at its limit as at ``max_t``, so that its range is then at least ``limits[k] * scale``
    (not ``max_out``) and only a nearer wall is exact (the race's cast: a beam that already hit a
    car stops behind the car). With None the compiled kernel is the one without limits.

    Every beam does the operations of [`cast_ray()`][racecar_sim.raycast.kernels.cast_ray] in the same
    order (so the same doubles), but the beams go through the traversal's phases together, in
    passes over lists of the beams still in a phase: the direction, steps and cell crossings per
    beam (one loop the compiler vectorises); one jump of every beam in jump mode per pass (the
    beams' jumps are independent, so their memory reads overlap instead of each waiting for the
    last, and the loop has no branch that depends on a beam); the start of the cell-by-cell
    traversal of every beam that landed near a wall (its divisions pipelined); then that traversal
    beam by beam, back to the jump list for a beam that leaves the walls again.
    """
    height = field.shape[0]
    w = field.shape[1]
    flat = field.reshape(-1)
    n = cos_a.shape[0]
    inside = gu >= 0.0 and gu < w and gv >= 0.0 and gv < height
    start = flat[int(gv) * w + int(gu)] if inside else OCCUPIED
    if start == OCCUPIED:
        for b in range(n):
            ranges[b] = 0.0
        return
    fw = np.empty((7, n))
    iw = np.empty((8, n), dtype=np.int64)
    t_arr, dx_arr, dy_arr = fw[0], fw[1], fw[2]
    tmx_arr, tmy_arr, tdx_arr, tdy_arr = fw[3], fw[4], fw[5], fw[6]
    v_arr, idx_arr, sx_arr, sy_arr = iw[0], iw[1], iw[2], iw[3]
    jumping, jumping_next, landed, walking = iw[4], iw[5], iw[6], iw[7]
    for k in range(n):
        dx = cos_h * cos_a[k] - sin_h * sin_a[k]
        dy = sin_h * cos_a[k] + cos_h * sin_a[k]
        dx_arr[k] = dx
        dy_arr[k] = dy
        t_arr[k] = 0.0
        v_arr[k] = start
        sx_arr[k] = 1 if dx > 0.0 else -1
        sy_arr[k] = w if dy > 0.0 else -w
        tdx_arr[k] = 1.0 / abs(dx) if dx != 0.0 else _BIG
        tdy_arr[k] = 1.0 / abs(dy) if dy != 0.0 else _BIG
        jumping[k] = k
        landed[k] = k
    n_jump = n if start != 0 else 0
    n_landed = 0 if start != 0 else n
    while n_jump > 0 or n_landed > 0:
        # One jump of every beam in jump mode (the ring of occupied cells keeps landings on the
        # grid, even past max_t).
        m = 0
        for j in range(n_jump):
            k = jumping[j]
            t = t_arr[k] + v_arr[k]
            px = gu + t * dx_arr[k]
            py = gv + t * dy_arr[k]
            v = flat[int(py) * w + int(px)]
            t_arr[k] = t
            v_arr[k] = v
            over = t >= (max_t if limits is None else limits[k])
            jumping_next[m] = k
            m += (not over) & (v != 0) & (v != OCCUPIED)
            landed[n_landed] = k
            n_landed += (not over) & (v == 0)
        jumping, jumping_next = jumping_next, jumping
        n_jump = m
        # Start the exact traversal from each landing inside cell (col, rv).
        for j in range(n_landed):
            k = landed[j]
            t = t_arr[k]
            dx = dx_arr[k]
            dy = dy_arr[k]
            px = gu + t * dx  # the landing point again, the same doubles
            py = gv + t * dy
            col = int(px)
            rv = int(py)
            idx_arr[k] = rv * w + col
            if dx > 0.0:
                tmx_arr[k] = t + (col + 1 - px) / dx
            elif dx < 0.0:
                tmx_arr[k] = t + (col - px) / dx
            else:
                tmx_arr[k] = _BIG
            if dy > 0.0:
                tmy_arr[k] = t + (rv + 1 - py) / dy
            elif dy < 0.0:
                tmy_arr[k] = t + (rv - py) / dy
            else:
                tmy_arr[k] = _BIG
            walking[j] = k
        n_walk = n_landed
        n_landed = 0
        # Cell by cell to a hit, to max_t, or to a cell far enough from walls to jump again.
        for j in range(n_walk):
            k = walking[j]
            tmax_x = tmx_arr[k]
            tmax_y = tmy_arr[k]
            idx = idx_arr[k]
            step_x = sx_arr[k]
            step_yw = sy_arr[k]
            tdelta_x = tdx_arr[k]
            tdelta_y = tdy_arr[k]
            lim = max_t if limits is None else limits[k]
            while True:
                if tmax_x < tmax_y:
                    t = tmax_x
                    idx += step_x
                    tmax_x += tdelta_x
                else:
                    t = tmax_y
                    idx += step_yw
                    tmax_y += tdelta_y
                if t >= lim:
                    t_arr[k] = t
                    break
                v = flat[idx]
                if v == OCCUPIED:
                    t_arr[k] = t
                    break
                if v != 0:
                    t_arr[k] = t
                    v_arr[k] = v
                    jumping[n_jump] = k
                    n_jump += 1
                    break
    for k in range(n):
        r = t_arr[k]  # where the beam stopped: a hit, or at or past max_t
        ranges[k] = max_out if r >= max_t else r * scale


@nb.njit(cache=True, error_model="numpy")
def add_beam_noise(ranges, seed, noise, out) -> int:
    """The four-part beam noise ([`racecar_sim.sensors.lidar`][racecar_sim.sensors.lidar]) of true ``ranges`` into ``out``.

    Args:
        ranges: float64 (M,) true ranges, metres.
        seed: int64 seed of this scan's random stream ([`racecar_sim.raycast.rand.seed_from()`][racecar_sim.raycast.rand.seed_from]).
        noise: float64 array laid out as `NOISE_FIELDS`.
        out: float32 (M,) output, metres.

    Per beam one uniform picks the part (and, rescaled within its interval, gives a random or
    short return's distance) and one normal is the Gaussian part's; both come from
    `racecar_sim.raycast.rand.uniforms_and_normals()` (beam ``i`` from its own counters).

    Returns:
        0, or 2 when a range is NaN or outside [0, max_range] (``out`` then unfinished).
    """
    sigma = noise[0]
    max_range = noise[1]
    p_rand = noise[2]
    p_max = noise[3]
    p_short = noise[4]
    rate = noise[5]
    t_max = p_rand + p_max
    t_short = t_max + p_short
    n = ranges.shape[0]
    u = np.empty(n)
    z = np.empty(n)
    uniforms_and_normals(seed, u, z)
    ok = True
    for i in range(n):  # no branch: the parts by priority, the short returns left for below
        ri = ranges[i]
        ui = u[i]
        ok &= (ri >= 0.0) & (ri <= max_range)  # also catches NaN
        v = ri + sigma * z[i]
        v = max_range if (ui < t_max) | (ri >= max_range) else v  # drop-out, or nothing to hit
        v = ui / p_rand * max_range if ui < p_rand else v  # uniform in [0, max_range)
        # (error_model numpy: with p_rand = 0 the unused quotient is NaN, not an exception)
        out[i] = min(max(v, 0.0), max_range)
    if not ok:
        return 2
    for i in range(n):
        ri = ranges[i]
        ui = u[i]
        if (ui >= t_max) & (ui < t_short) & (ri < max_range):
            w = (ui - t_max) / p_short  # uniform in [0, 1)
            # Inverse CDF of the exponential truncated to [0, ri].
            v = min(-math.log1p(-w * -math.expm1(-rate * ri)) / rate, ri)
            out[i] = min(max(v, 0.0), max_range)
    return 0


@nb.njit(cache=True, inline="always")
def exact_one(field, x, y, th, geometry, cos_a, sin_a, limits, ranges):
    """Mount pose and exact cast of one scan from rear-axle world (x, y, th) into ``ranges``
    (metres); 0, or 1 when the pose is not finite (``ranges`` untouched). ``limits``: None, or
    per-beam limits in cells (see `_exact_scan()`)."""
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(th)):
        return 1
    # Lidar mount (Lidar.mount_pose), then RayCaster._grid_frame: map frame / resolution + 1 cell.
    mount = geometry[6]
    mx = x + mount * math.cos(th)
    my = y + mount * math.sin(th)
    ddx = mx - geometry[0]
    ddy = my - geometry[1]
    c = geometry[2]
    s = geometry[3]
    res = geometry[4]
    gu = (c * ddx + s * ddy) / res + 1.0
    gv = (-s * ddx + c * ddy) / res + 1.0
    heading = th - geometry[5]
    _exact_scan(
        field, gu, gv, math.cos(heading), math.sin(heading), cos_a, sin_a, geometry[7], limits,
        res, geometry[8], ranges,
    )  # fmt: skip
    return 0


@nb.njit(cache=True, inline="always")
def _scan_one(field, x, y, th, geometry, cos_a, sin_a, seed, noise, ranges, out):
    """Mount pose, exact cast and noise of one scan (see `scan_with_noise()`); a status."""
    if exact_one(field, x, y, th, geometry, cos_a, sin_a, None, ranges):
        return 1
    return add_beam_noise(ranges, seed, noise, out)


@nb.njit(cache=True)
def scan_with_noise(field, pose, geometry, cos_a, sin_a, seed, noise, ranges, out) -> int:
    """Cast a scan from the car at rear-axle world ``pose`` and add the beam noise.

    Args:
        field: the exact caster's pad-frame jump field ([`RayCaster.field`][RayCaster.field]).
        pose: float64 (3,) world [x, y, theta] of the rear axle (metres, radians).
        geometry: float64 array laid out as `GEOMETRY_FIELDS`.
        cos_a, sin_a: (M,) cos and sin of the beam angles (car frame).
        seed: int64 seed of the scan's random stream (see `add_beam_noise()`).
        noise: float64 array laid out as `NOISE_FIELDS`.
        ranges: float64 (M,) output, exact ranges in metres.
        out: float32 (M,) output, the noisy scan in metres (see [`racecar_sim.sensors.lidar`][racecar_sim.sensors.lidar]).

    Returns:
        0 on success, 1 when the pose is not finite (outputs untouched), 2 when an exact range
        falls outside [0, max_range] (cannot happen for a finite pose).
    """
    return _scan_one(
        field, pose[0], pose[1], pose[2], geometry, cos_a, sin_a, seed, noise, ranges, out
    )


@nb.njit(cache=True, nogil=True)
def _scans_serial(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status):
    for k in range(poses.shape[0]):
        status[k] = _scan_one(
            field, poses[k, 0], poses[k, 1], poses[k, 2], geometry, cos_a, sin_a, seeds[k],
            noise, ranges[k], out[k],
        )  # fmt: skip


@nb.njit(cache=True, nogil=True)
def scans_shared(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status, chunk,
                 counter):  # fmt: skip
    """`scans_with_noise()`'s cars in chunks of ``chunk`` taken from ``counter`` until none is
    left: one of the threads of [`racecar_sim.raycast.shared_work.run_shared()`][racecar_sim.raycast.shared_work.run_shared]."""
    n = poses.shape[0]
    while True:
        k0 = fetch_add(counter, 1) * chunk
        if k0 >= n:
            break
        for k in range(k0, min(n, k0 + chunk)):
            status[k] = _scan_one(
                field, poses[k, 0], poses[k, 1], poses[k, 2], geometry, cos_a, sin_a, seeds[k],
                noise, ranges[k], out[k],
            )  # fmt: skip


def scans_with_noise(
    field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, parallel: bool
) -> np.ndarray:
    """`scan_with_noise()` for K cars at once: poses (K, 3), seeds (K,), ranges, out (K, M).

    ``parallel`` shares the cars, one at a time, among numba's thread count of threads
    (`shared_work`). Returns the (K,) statuses. The serial kernel
    releases the GIL (`scans_serial_nogil()`), so Python threads can also share the cars out.
    """
    status = np.zeros(poses.shape[0], dtype=np.int64)
    if parallel:
        args = (field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status, 1)
        run_shared(scans_shared, args, nb.get_num_threads())
    else:
        _scans_serial(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status)
    return status


def scans_serial_nogil(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status):
    """`scans_with_noise()` on the calling thread, without holding the GIL."""
    _scans_serial(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status)
