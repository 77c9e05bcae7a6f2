"""Ray casting on an occupancy grid: one API for the simulated lidar and for particles.

A ray starts at a pose's position and runs along ``theta + angle`` (world frame). Its range is the
distance in metres to where it *enters* the first occupied cell (unknown cells and everything beyond
the image border count as occupied), clipped to ``max_range``. A pose inside an occupied cell, or off
the map, gives 0 on every ray.

Methods (``METHODS``):

``"exact"``
    Amanatides–Woo grid traversal in numba, sped up by jumping through free space with the map's
    distance field (the jump length is a proven lower bound of the distance to any occupied cell, so
    the result is still exact to floating-point rounding). Parallel over rays.

Casting is done in the grid's own axis-aligned frame (see :mod:`racecar_sim.maps`), so a map origin
with a yaw is handled by rotating the ray, not the grid.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.maps import OccupancyMap

__all__ = ["METHODS", "RayCaster", "cast_exact_grid"]

METHODS: tuple[str, ...] = ("exact",)
"""Names accepted by :class:`RayCaster`'s ``method``."""

_SQRT2 = math.sqrt(2.0)
_JUMP_MIN = 2.0  # cells: below this the DDA steps cell by cell instead of jumping
_BIG = 1e30


@nb.njit(cache=True, inline="always")
def _cast_ray(occ, jump, gu, gv, dx, dy, max_t):
    """Range in cells of one ray from (gu, gv) (map frame, cells) along unit (dx, dy).

    occ: uint8 (H, W) grid frame, 1 = occupied. jump: float32 (H, W), a safe free-space jump in
    cells from anywhere inside that cell (0 where not worth it).
    """
    h = occ.shape[0]
    w = occ.shape[1]
    col = int(math.floor(gu))
    rv = int(math.floor(gv))  # row counted from the bottom of the image
    if col < 0 or col >= w or rv < 0 or rv >= h:
        return 0.0
    if occ[h - 1 - rv, col]:
        return 0.0
    step_x = 1 if dx > 0.0 else -1
    step_y = 1 if dy > 0.0 else -1
    tdelta_x = 1.0 / abs(dx) if dx != 0.0 else _BIG
    tdelta_y = 1.0 / abs(dy) if dy != 0.0 else _BIG
    t = 0.0
    while True:
        j = jump[h - 1 - rv, col]
        if j > _JUMP_MIN:
            t += j
            if t >= max_t:
                return max_t
            px = gu + t * dx
            py = gv + t * dy
            col = int(math.floor(px))
            rv = int(math.floor(py))
        else:
            px = gu + t * dx
            py = gv + t * dy
        # Restart the exact traversal from the point at parameter t inside cell (col, rv).
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
            if col < 0 or col >= w or rv < 0 or rv >= h:
                return t
            if occ[h - 1 - rv, col]:
                return t
            if jump[h - 1 - rv, col] > _JUMP_MIN:
                break


@nb.njit(cache=True, parallel=True)
def _cast_exact_kernel(occ, jump, gu, gv, heading, cos_a, sin_a, max_t, out):
    """Fill out (N, M) with ranges in cells; heading per pose in the map frame, beams as cos/sin."""
    n = gu.shape[0]
    m = cos_a.shape[0]
    for k in nb.prange(n * m):
        i = k // m
        b = k - i * m
        ch = math.cos(heading[i])
        sh = math.sin(heading[i])
        dx = ch * cos_a[b] - sh * sin_a[b]
        dy = sh * cos_a[b] + ch * sin_a[b]
        out[i, b] = _cast_ray(occ, jump, gu[i], gv[i], dx, dy, max_t)


def cast_exact_grid(
    occupied: np.ndarray,
    jump_cells: np.ndarray,
    gu: np.ndarray,
    gv: np.ndarray,
    heading: np.ndarray,
    angles: np.ndarray,
    max_cells: float,
) -> np.ndarray:
    """Exact ranges in *cells* for rays given in the map frame (cells, radians).

    Low-level entry point used by :class:`RayCaster`; ``jump_cells`` may be all zeros (plain
    Amanatides–Woo).
    """
    out = np.empty((gu.shape[0], angles.shape[0]), dtype=np.float64)
    _cast_exact_kernel(
        occupied,
        jump_cells,
        np.ascontiguousarray(gu, dtype=np.float64),
        np.ascontiguousarray(gv, dtype=np.float64),
        np.ascontiguousarray(heading, dtype=np.float64),
        np.cos(angles).astype(np.float64),
        np.sin(angles).astype(np.float64),
        float(max_cells),
        out,
    )
    return out


def _safe_jump_cells(grid: OccupancyMap) -> np.ndarray:
    """float32 (H, W): a jump length in cells safe from anywhere inside each cell.

    The distance field holds centre-to-centre distances d to the nearest occupied cell. A point in the
    cell is within sqrt(2)/2 cells of its centre and every point of an occupied cell is within
    sqrt(2)/2 of that cell's centre, so no occupied point is nearer than d - sqrt(2) cells.
    """
    d = grid.distance / grid.resolution - _SQRT2
    return np.where(d > 0.0, d, 0.0).astype(np.float32)


class RayCaster:
    """Casts rays from poses on an occupancy map.

    Args:
        occupancy_map: the map (world frame defined by its origin).
        max_range: metres; ranges are clipped to it.
        method: one of :data:`METHODS`.
    """

    def __init__(
        self, occupancy_map: OccupancyMap, max_range: float, method: str = "exact"
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"unknown ray casting method {method!r}; choose one of {METHODS}")
        if not (max_range > 0 and math.isfinite(max_range)):
            raise ValueError(f"max_range must be a positive number of metres, got {max_range}")
        self.map = occupancy_map
        self.max_range = float(max_range)
        self.method = method
        self._occ = np.ascontiguousarray(occupancy_map.occupied, dtype=np.uint8)
        self._jump = _safe_jump_cells(occupancy_map)

    def _to_grid_frame(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World poses (N, 3) -> map-frame position in cells (gu, gv) and heading (radians)."""
        uv = self.map.world_to_map(poses[:, :2]) / self.map.resolution
        return uv[:, 0], uv[:, 1], poses[:, 2] - self.map.yaw

    def cast(self, poses: np.ndarray, angles: np.ndarray) -> np.ndarray:
        """Ranges (N, M) float64 in metres.

        Args:
            poses: (N, 3) or (3,) world [x, y, theta] (metres, radians).
            angles: (M,) beam angles relative to each pose's heading (radians).
        """
        poses = np.asarray(poses, dtype=np.float64)
        if poses.ndim == 1:
            poses = poses[None, :]
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ValueError(f"poses must have shape (N, 3), got {poses.shape}")
        angles = np.asarray(angles, dtype=np.float64).reshape(-1)
        if not (np.isfinite(poses).all() and np.isfinite(angles).all()):
            raise ValueError("poses and angles must be finite")
        gu, gv, heading = self._to_grid_frame(poses)
        res = self.map.resolution
        cells = cast_exact_grid(
            self._occ, self._jump, gu, gv, heading, angles, self.max_range / res
        )
        return np.minimum(cells * res, self.max_range)
