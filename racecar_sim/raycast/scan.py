"""One lidar scan in one numba call: mount pose, exact cast of every beam and the beam noise.

The simulated lidar casts a single scan (1080 beams) per step. Through :meth:`RayCaster.cast` that
is a dozen numpy operations on one pose, a kernel call and a second kernel call for the noise; here
it is one call whose arithmetic is the same, operation for operation, as
:func:`~racecar_sim.raycast.kernels.cast_ray` after :meth:`RayCaster.cast`'s frame change, and as
the noise of :meth:`racecar_sim.sensors.Lidar.add_noise` (:func:`add_beam_noise`, which draws its
uniforms and normals itself from a :mod:`racecar_sim.rand` stream seeded once per scan): the ranges
are the same doubles and the noisy scan the same floats (tested).

The per-ray traversal is :func:`~racecar_sim.raycast.kernels.cast_ray` written for one origin:
beams in order, the flat cell index stepped along in the exact traversal instead of recomputed,
truncation instead of ``floor`` (coordinates inside the padded grid are never negative).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.rand import normal, uniform
from racecar_sim.raycast.kernels import OCCUPIED

__all__ = [
    "GEOMETRY_FIELDS",
    "NOISE_FIELDS",
    "add_beam_noise",
    "scan_geometry",
    "scan_with_noise",
    "scans_serial_nogil",
    "scans_with_noise",
]

_BIG = 1e30

GEOMETRY_FIELDS = ("origin_x", "origin_y", "cos_yaw", "sin_yaw", "resolution", "yaw", "mount",
                   "max_cells", "max_range")  # fmt: skip
"""Layout of the float64 ``geometry`` array (world origin of the map, metres; its yaw, radians;
cos and sin of the yaw; metres per cell; lidar mount offset ahead of the rear axle, metres; the
range limit in cells and in metres)."""

NOISE_FIELDS = ("sigma", "max_range", "p_rand", "p_max", "p_short", "short_lambda")
"""Layout of the float64 ``noise`` array (see :class:`~racecar_sim.config.LidarParams`)."""


def scan_geometry(occupancy_map, max_range: float, mount_offset: float) -> np.ndarray:
    """The ``geometry`` array of :func:`scan_with_noise` for a map, a range (m) and a mount (m)."""
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
def _exact_scan(field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, scale, max_out, ranges):
    """Exact ranges (metres) of beams ``cos_a, sin_a`` from pad-frame (gu, gv), heading (cos, sin)."""
    height = field.shape[0]
    w = field.shape[1]
    flat = field.reshape(-1)
    inside = gu >= 0.0 and gu < w and gv >= 0.0 and gv < height
    start = flat[int(gv) * w + int(gu)] if inside else OCCUPIED
    for b in range(cos_a.shape[0]):
        if start == OCCUPIED:
            ranges[b] = 0.0
            continue
        dx = cos_h * cos_a[b] - sin_h * sin_a[b]
        dy = sin_h * cos_a[b] + cos_h * sin_a[b]
        px = gu + 0.0 * dx
        py = gv + 0.0 * dy
        col = int(px)
        rv = int(py)
        idx = rv * w + col
        v = start
        step_x = 1 if dx > 0.0 else -1
        step_y = 1 if dy > 0.0 else -1
        step_yw = step_y * w
        tdelta_x = 1.0 / abs(dx) if dx != 0.0 else _BIG
        tdelta_y = 1.0 / abs(dy) if dy != 0.0 else _BIG
        t = 0.0
        r = 0.0
        done = False
        while not done:
            if v != 0:
                # Jump through free space (the padded ring keeps the landing on the grid).
                t += v
                if t >= max_t:
                    r = max_t
                    break
                px = gu + t * dx
                py = gv + t * dy
                col = int(px)
                rv = int(py)
                idx = rv * w + col
                v = flat[idx]
                if v == OCCUPIED:
                    r = t
                    break
                if v != 0:
                    continue
            # Exact traversal from the point at t inside cell (col, rv).
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
                    idx += step_x
                    tmax_x += tdelta_x
                else:
                    t = tmax_y
                    rv += step_y
                    idx += step_yw
                    tmax_y += tdelta_y
                if t >= max_t:
                    r = max_t
                    done = True
                    break
                v = flat[idx]
                if v == OCCUPIED:
                    r = t
                    done = True
                    break
                if v != 0:
                    px = gu + t * dx
                    py = gv + t * dy
                    break
        ranges[b] = max_out if r >= max_t else r * scale


@nb.njit(cache=True)
def add_beam_noise(ranges, seed, noise, out) -> int:
    """The four-part beam noise (:mod:`racecar_sim.sensors`) of true ``ranges`` into ``out``.

    Args:
        ranges: float64 (M,) true ranges, metres.
        seed: int64 seed of this scan's random stream (:func:`racecar_sim.rand.seed_from`).
        noise: float64 array laid out as :data:`NOISE_FIELDS`.
        out: float32 (M,) output, metres.

    Per beam in order: one uniform picks the part (and, rescaled within its interval, gives a
    random or short return's distance); a beam with Gaussian noise then draws one normal.

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
    state = np.uint64(seed)
    for i in range(ranges.shape[0]):
        ri = ranges[i]
        if not (ri >= 0.0 and ri <= max_range):  # also catches NaN
            return 2
        state, ui = uniform(state)
        if ui < p_rand:
            v = ui / p_rand * max_range  # uniform in [0, max_range)
        elif ui < t_max or ri >= max_range:
            v = max_range  # a drop-out, or no surface in range to return from
        elif ui < t_short:
            w = (ui - t_max) / p_short  # uniform in [0, 1)
            # Inverse CDF of the exponential truncated to [0, ri].
            v = min(-math.log1p(-w * -math.expm1(-rate * ri)) / rate, ri)
        else:
            state, zi = normal(state)
            v = ri + sigma * zi
        out[i] = min(max(v, 0.0), max_range)
    return 0


@nb.njit(cache=True, inline="always")
def _scan_one(field, x, y, th, geometry, cos_a, sin_a, seed, noise, ranges, out):
    """Mount pose, exact cast and noise of one scan (see :func:`scan_with_noise`); a status."""
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
        field, gu, gv, math.cos(heading), math.sin(heading), cos_a, sin_a, geometry[7], res,
        geometry[8], ranges,
    )  # fmt: skip
    return add_beam_noise(ranges, seed, noise, out)


@nb.njit(cache=True)
def scan_with_noise(field, pose, geometry, cos_a, sin_a, seed, noise, ranges, out) -> int:
    """Cast a scan from the car at rear-axle world ``pose`` and add the beam noise.

    Args:
        field: the exact caster's pad-frame jump field (:attr:`RayCaster.field`).
        pose: float64 (3,) world [x, y, theta] of the rear axle (metres, radians).
        geometry: float64 array laid out as :data:`GEOMETRY_FIELDS`.
        cos_a, sin_a: (M,) cos and sin of the beam angles (car frame).
        seed: int64 seed of the scan's random stream (see :func:`add_beam_noise`).
        noise: float64 array laid out as :data:`NOISE_FIELDS`.
        ranges: float64 (M,) output, exact ranges in metres.
        out: float32 (M,) output, the noisy scan in metres (see :mod:`racecar_sim.sensors`).

    Returns:
        0 on success, 1 when the pose is not finite (outputs untouched), 2 when an exact range
        falls outside [0, max_range] (cannot happen for a finite pose).
    """
    return _scan_one(
        field, pose[0], pose[1], pose[2], geometry, cos_a, sin_a, seed, noise, ranges, out
    )


@nb.njit(cache=True, parallel=True)
def _scans_parallel(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status):
    for k in nb.prange(poses.shape[0]):
        status[k] = _scan_one(
            field, poses[k, 0], poses[k, 1], poses[k, 2], geometry, cos_a, sin_a, seeds[k],
            noise, ranges[k], out[k],
        )  # fmt: skip


@nb.njit(cache=True, nogil=True)
def _scans_serial(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status):
    for k in range(poses.shape[0]):
        status[k] = _scan_one(
            field, poses[k, 0], poses[k, 1], poses[k, 2], geometry, cos_a, sin_a, seeds[k],
            noise, ranges[k], out[k],
        )  # fmt: skip


def scans_with_noise(
    field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, parallel: bool
) -> np.ndarray:
    """:func:`scan_with_noise` for K cars at once: poses (K, 3), seeds (K,), ranges, out (K, M).

    ``parallel`` spreads the cars over numba's threads. Returns the (K,) statuses. The serial
    kernel releases the GIL (:func:`scans_serial_nogil`), so Python threads can also share the
    cars out.
    """
    status = np.zeros(poses.shape[0], dtype=np.int64)
    if parallel:
        _scans_parallel(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status)
    else:
        _scans_serial(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status)
    return status


def scans_serial_nogil(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status):
    """:func:`scans_with_noise` on the calling thread, without holding the GIL."""
    _scans_serial(field, poses, geometry, cos_a, sin_a, seeds, noise, ranges, out, status)
