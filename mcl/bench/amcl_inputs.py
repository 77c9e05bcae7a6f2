"""What nav2's amcl is fed, converted from our drives and maps (numpy only; amcl itself never runs
in this process, see [mcl.bench.peer_amcl][]).

nav2_amcl's C core works in the frames of a ROS robot, and these functions build them from a
[RecordedDrive][mcl.experiments.recorded.RecordedDrive]:

* the map: an axis-aligned grid in the world frame (amcl ignores a map's yaw), cell
  ``(i, j)`` (x, y) at index ``i + j * size_x``; 0 free, 100 occupied; amcl takes the centre of
  cell (0, 0) for the origin
  ([AmclGrid.amcl_origin][mcl.bench.amcl_inputs.AmclGrid.amcl_origin]). Our maps may be rotated (Stata's origin yaw is 3.14 rad), so each amcl cell takes the
  occupancy of our map at the cell's centre; what lies off our map is occupied. Unknown cells are
  occupied in ours and stop amcl's rays too.
* odometry: the pose of ``base`` in an ``odom`` frame, the VESC's twist integrated as our filter
  moves its particles ([twist_to_odometry][mcl.filter.motion_model.twist_to_odometry], composed step by
  step), starting at [0, 0, 0]. amcl uses only its differences.
* the laser: ``[range m, bearing rad]`` pairs, bearings the lidar's beam angles, ``base`` being
  our rear axle and the laser ``mount_offset`` m ahead of it; a reading at or above the lidar's
  max range (no return) or at or below its min range goes in as ``range_max`` exactly, as nav2's
  ``laserReceived`` does, so that amcl's beam model counts it as a max-range reading.
* when to update: nav2's ``shouldUpdateFilter``: on a fresh scan when the odometry moved more
  than ``update_min_d`` along x or y of the odom frame, or turned more than ``update_min_a``,
  since the last update (the first scan always updates).
* the estimate at every step: nav2 publishes ``map -> odom`` at each update; the robot's pose in
  between is that update's pose composed with the odometry since then, which is what
  [estimates_between][mcl.bench.amcl_inputs.estimates_between] returns.

Frames and units: world frame of the map, metres and radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcl.filter.angles import wrap_angle
from racecar_sim.maps import OccupancyMap

__all__ = [
    "AmclGrid",
    "amcl_grid",
    "amcl_ranges",
    "estimates_between",
    "odometry_poses",
    "relative_poses",
    "update_steps",
]

FREE, OCCUPIED = 0, 100
"""amcl's cell values (ROS OccupancyGrid: 0 free, 100 occupied)."""


@dataclass(frozen=True, eq=False)
class AmclGrid:
    """An axis-aligned occupancy grid as amcl reads it.

    Attributes:
        data: (size_y, size_x) int8, 0 free or 100 occupied; row ``j`` is y, column ``i`` is x, so
            ``data.ravel()`` is amcl's ``i + j * size_x`` order.
        resolution: metres per cell.
        origin_x: world x of the grid's lower-left corner, metres.
        origin_y: world y of the grid's lower-left corner, metres.
    """

    data: np.ndarray
    resolution: float
    origin_x: float
    origin_y: float

    @property
    def amcl_origin(self) -> tuple[float, float]:
        """The origin to give amcl: the corner moved by half a cell (metres, world).

        nav2_amcl's ``map_t`` puts cell ``i``'s *centre* at ``origin + i * resolution`` (its
        ``MAP_GXWX`` rounds), where a ROS grid has the cell's corner; given the corner, amcl would
        see the map half a cell (2.5 cm at Stata's resolution) down and left of where it is.
        """
        half = 0.5 * self.resolution
        return self.origin_x + half, self.origin_y + half

    def occupied_at(self, xy: np.ndarray) -> np.ndarray:
        """bool (...,): whether world points (..., 2) fall in an occupied cell or off the grid."""
        xy = np.asarray(xy, dtype=np.float64)
        i = np.floor((xy[..., 0] - self.origin_x) / self.resolution).astype(np.int64)
        j = np.floor((xy[..., 1] - self.origin_y) / self.resolution).astype(np.int64)
        ny, nx = self.data.shape
        inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        out = np.ones(i.shape, dtype=bool)
        out[inside] = self.data[j[inside], i[inside]] != FREE
        return out


def amcl_grid(grid: OccupancyMap) -> AmclGrid:
    """``grid`` resampled onto an axis-aligned grid of the same resolution covering its world
    bounding box (each cell the occupancy of ``grid`` at the cell's centre)."""
    res = grid.resolution
    w, h = grid.extent
    corners = grid.map_to_world(np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]]))
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    nx, ny = (int(math.ceil((hi[k] - lo[k]) / res - 1e-9)) for k in (0, 1))
    x = lo[0] + (np.arange(nx) + 0.5) * res
    y = lo[1] + (np.arange(ny) + 0.5) * res
    centres = np.stack(np.meshgrid(x, y, indexing="xy"), axis=-1)  # (ny, nx, 2)
    free = grid.is_free(centres)
    data = np.where(free, FREE, OCCUPIED).astype(np.int8)
    return AmclGrid(np.ascontiguousarray(data), res, float(lo[0]), float(lo[1]))


def odometry_poses(odom: np.ndarray, dt: np.ndarray | float) -> np.ndarray:
    """(n, 3) odom-frame poses [x m, y m, theta rad] from per-step twists.

    Args:
        odom: (n, 3) car-frame twists [vx m/s, vy m/s, omega rad/s]; row k moves the car from pose
            k-1 to pose k (row 0 is not used: pose 0 is [0, 0, 0]).
        dt: seconds each twist is held (one number, or (n,) per step).

    The displacement of each step is [twist_to_odometry][mcl.filter.motion_model.twist_to_odometry]'s
    constant-twist arc; theta is wrapped to [-pi, pi).
    """
    tw = np.asarray(odom, dtype=np.float64)
    dt = np.broadcast_to(np.asarray(dt, dtype=np.float64), (len(tw),))
    vx, vy, om = tw[1:, 0], tw[1:, 1], tw[1:, 2]
    dth = om * dt[1:]
    small = np.abs(dth) < 1e-6
    safe = np.where(small, 1.0, dth)
    a = np.where(small, 1.0 - dth * dth / 6.0, np.sin(safe) / safe)
    b = np.where(small, dth / 2.0, (1.0 - np.cos(safe)) / safe)
    dx = (a * vx - b * vy) * dt[1:]
    dy = (b * vx + a * vy) * dt[1:]
    theta = np.concatenate([[0.0], np.cumsum(dth)])
    c, s = np.cos(theta[:-1]), np.sin(theta[:-1])
    x = np.concatenate([[0.0], np.cumsum(c * dx - s * dy)])
    y = np.concatenate([[0.0], np.cumsum(s * dx + c * dy)])
    return np.stack([x, y, wrap_angle(theta)], axis=-1)


def amcl_ranges(
    scan: np.ndarray, beam_angles: np.ndarray, max_range: float, min_range: float = 0.0
) -> np.ndarray:
    """(..., n_beams, 2) ``[range m, bearing rad]`` pairs of scans (..., n_beams), no-returns
    (at or beyond ``max_range``, at or below ``min_range``, or not finite) at ``max_range``."""
    z = np.asarray(scan, dtype=np.float64)
    z = np.where(np.isfinite(z) & (z > min_range) & (z < max_range), z, float(max_range))
    bearings = np.broadcast_to(np.asarray(beam_angles, dtype=np.float64), z.shape)
    return np.stack([z, bearings], axis=-1)


def update_steps(
    poses: np.ndarray, fresh: np.ndarray, update_min_d: float, update_min_a: float
) -> np.ndarray:
    """Indices of the steps at which nav2's amcl updates its filter (module docstring).

    Args:
        poses: (n, 3) odom-frame poses ([odometry_poses][mcl.bench.amcl_inputs.odometry_poses]).
        fresh: (n,) bool, steps with a fresh scan; step 0 must be one.
        update_min_d: metres along the odom frame's x or y (a negative value: every fresh scan).
        update_min_a: radians of heading.
    """
    fresh_steps = np.flatnonzero(np.asarray(fresh, dtype=bool))
    if len(fresh_steps) == 0 or fresh_steps[0] != 0:
        raise ValueError("update_steps: step 0 must carry a fresh scan")
    poses = np.asarray(poses, dtype=np.float64)
    out = [0]
    last = poses[0]
    for k in fresh_steps[1:].tolist():  # one comparison per scan, a few thousand a drive
        p = poses[k]
        turn = abs(math.remainder(p[2] - last[2], 2 * math.pi))
        if (
            abs(p[0] - last[0]) > update_min_d
            or abs(p[1] - last[1]) > update_min_d
            or (turn > update_min_a)
        ):
            out.append(k)
            last = p
    return np.array(out, dtype=np.int64)


def relative_poses(base: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(n, 3) poses (n, 3) in the frames of ``base`` (n, 3) (``base^-1 * pose``, SE(2))."""
    base, poses = np.asarray(base, np.float64), np.asarray(poses, np.float64)
    c, s = np.cos(base[:, 2]), np.sin(base[:, 2])
    dx, dy = poses[:, 0] - base[:, 0], poses[:, 1] - base[:, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(poses[:, 2] - base[:, 2])], -1)


def estimates_between(updates: np.ndarray, at: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(n, 3) world estimates at every step from amcl's estimates at its update steps.

    Args:
        updates: (m, 3) amcl's pose estimates (world) right after each update.
        at: (m,) increasing step indices of the updates, the first 0.
        poses: (n, 3) odom-frame poses of every step.

    Returns:
        At step k, the latest update u <= k composed with the odometry from u to k.
    """
    at = np.asarray(at, dtype=np.int64)
    poses = np.asarray(poses, dtype=np.float64)
    last = np.searchsorted(at, np.arange(len(poses)), side="right") - 1
    est = np.asarray(updates, dtype=np.float64)[last]
    rel = relative_poses(poses[at[last]], poses)
    c, s = np.cos(est[:, 2]), np.sin(est[:, 2])
    return np.stack([
        est[:, 0] + c * rel[:, 0] - s * rel[:, 1],
        est[:, 1] + s * rel[:, 0] + c * rel[:, 1],
        wrap_angle(est[:, 2] + rel[:, 2]),
    ], axis=-1)  # fmt: skip
