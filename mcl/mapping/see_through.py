"""What one drive's scans say about the walls of a map: the blocked cells its beams passed
through and the cells its returns ended in ([DriveEvidence][mcl.mapping.see_through.DriveEvidence]).

The poses are the drive's own (a filter's estimates, or the truth in a simulation); only the
scans at poses marked ``use`` count (e.g. the steps the ``lost`` flag did not call lost).
A beam counts as seen through the map as
[MapUpdateParams][mcl.mapping.params.MapUpdateParams] says; each blocked cell it crossed counts
once per scan.

Frames: poses [x m, y m, theta rad] of the rear axle in the world frame, the lidar ``mount_offset``
metres ahead of it; beam angles radians in the car frame; counts in the map's grid frame (row 0 =
the image's top row).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numba as nb
import numpy as np

from mcl.mapping.params import MapUpdateParams
from racecar_sim.maps import OccupancyMap

__all__ = ["DriveEvidence", "drive_evidence"]


@dataclass(frozen=True, eq=False)
class DriveEvidence:
    """One drive's counts, in the map's grid frame.

    Attributes:
        passed: (H, W) int32, scans whose beams passed through each blocked cell.
        returns: (H, W) int32, returns that ended in each cell.
        scans: scans used.
    """

    passed: np.ndarray
    returns: np.ndarray
    scans: int


@nb.njit(cache=True)
def _count_scan(occupied, depth, passed, returns, stamp, scan_id, u0, v0, heading, angles,
                ranges, res, max_range, margin, min_depth, end_margin, reach, smooth):  # fmt: skip
    """Count one scan from the lidar at map-frame cell coordinates (u0 right, v0 up) with
    ``heading`` (radians, map frame): half-cell steps along each beam."""
    h, w = occupied.shape
    for b in range(1, ranges.shape[0] - 1):
        z = ranges[b]
        if not (z == z) or z >= max_range - 0.05 or z > reach:
            continue
        if abs(ranges[b - 1] - z) > smooth or abs(ranges[b + 1] - z) > smooth:
            continue
        dx = math.cos(heading + angles[b])
        dy = math.sin(heading + angles[b])
        tz = z / res
        ex = u0 + tz * dx
        ey = v0 + tz * dy
        if not (ex >= 0.0 and ex < w and ey >= 0.0 and ey < h):
            continue
        er, ec = h - 1 - int(ey), int(ex)
        returns[er, ec] += 1
        first = -1.0
        t = 0.0
        while t < tz:
            px = u0 + t * dx
            py = v0 + t * dy
            if not (px >= 0.0 and px < w and py >= 0.0 and py < h):
                break
            if occupied[h - 1 - int(py), int(px)]:
                first = t
                break
            t += 0.5
        if first < 0.0 or tz < first + margin / res:
            continue
        if occupied[er, ec] and depth[er, ec] < min_depth:
            continue
        t = first
        t_end = tz - end_margin / res
        while t < t_end:
            r = h - 1 - int(v0 + t * dy)
            c = int(u0 + t * dx)
            if occupied[r, c] and stamp[r, c] != scan_id:
                stamp[r, c] = scan_id
                passed[r, c] += 1
            t += 0.5


def drive_evidence(
    old_map: OccupancyMap,
    poses: np.ndarray,
    scans: np.ndarray,
    beam_angles: np.ndarray,
    mount_offset: float,
    max_range: float,
    use: np.ndarray | None = None,
    params: MapUpdateParams | None = None,
) -> DriveEvidence:
    """Count what one drive's scans say about ``old_map``'s walls.

    Args:
        old_map: the map to update.
        poses: (N, 3) pose of the rear axle at each scan, world frame.
        scans: (N, K) ranges in metres (``max_range`` or NaN: no return).
        beam_angles: (K,) radians, car frame.
        mount_offset: metres from the rear axle forward to the lidar.
        max_range: the lidar's longest range, metres.
        use: (N,) bool, the scans to count (None: all).
        params: the update's settings (None: the defaults).

    Raises:
        ValueError: the shapes do not agree.
    """
    params = params or MapUpdateParams()
    poses = np.asarray(poses, dtype=np.float64)
    scans = np.asarray(scans, dtype=np.float64)
    angles = np.ascontiguousarray(beam_angles, dtype=np.float64)
    n = len(poses)
    if poses.shape != (n, 3) or scans.shape != (n, len(angles)):
        raise ValueError(
            f"drive_evidence: poses {poses.shape} and scans {scans.shape} must be (N, 3) and "
            f"(N, {len(angles)} beams)"
        )
    use = np.ones(n, dtype=bool) if use is None else np.asarray(use, dtype=bool)
    if use.shape != (n,):
        raise ValueError(f"drive_evidence: use has shape {use.shape}, expected ({n},)")
    occupied = old_map.occupied
    res = float(old_map.resolution)
    depth = cv2.distanceTransform(occupied.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    depth = depth * res
    passed = np.zeros(occupied.shape, dtype=np.int32)
    returns = np.zeros(occupied.shape, dtype=np.int32)
    stamp = np.full(occupied.shape, -1, dtype=np.int64)
    lidar = poses[:, :2] + mount_offset * np.stack([np.cos(poses[:, 2]), np.sin(poses[:, 2])], 1)
    uv = old_map.world_to_map(lidar) / res
    heading = poses[:, 2] - old_map.yaw
    for i in np.flatnonzero(use):  # one kernel call per scan; the beams are in the kernel
        _count_scan(
            occupied, depth, passed, returns, stamp, int(i), float(uv[i, 0]), float(uv[i, 1]),
            float(heading[i]), angles, scans[i], res, float(max_range), params.margin,
            params.min_depth, params.end_margin, params.reach, params.smooth,
        )  # fmt: skip
    return DriveEvidence(passed, returns, int(np.count_nonzero(use)))
