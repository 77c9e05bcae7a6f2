"""Race test helpers: an open hall (cars far from walls) and quiet settings (no sensor noise)."""

from __future__ import annotations

import numpy as np

from racecar_sim.maps import OccupancyMap

QUIET = {"range_sigma": 0.0, "p_short": 0.0, "p_max": 0.0, "p_rand": 0.0,
         "odom_proportional": (0.0, 0.0, 0.0), "odom_additive": (0.0, 0.0, 0.0)}  # fmt: skip
"""Settings without sensor noise: the scans are the exact ranges (metres, as float32)."""


def hall_map(length: float = 30.0, width: float = 10.0, resolution: float = 0.05) -> OccupancyMap:
    """An empty ``length x width`` metre hall with walls 2 cells thick, origin (0, 0, 0)."""
    h, w = round(width / resolution), round(length / resolution)
    occ = np.zeros((h, w), dtype=bool)
    occ[:2, :] = occ[-2:, :] = True
    occ[:, :2] = occ[:, -2:] = True
    return OccupancyMap(occupied=occ, resolution=resolution, origin=(0.0, 0.0, 0.0), name="hall")


def penetration(a: np.ndarray, b: np.ndarray) -> float:
    """Metres two convex boxes (4, 2) overlap along their least-overlap axis (<= 0: apart)."""
    depth = np.inf
    for box in (a, b):
        edges = np.roll(box, -1, axis=0) - box
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        normals /= np.hypot(normals[:, 0], normals[:, 1])[:, None]
        pa, pb = a @ normals.T, b @ normals.T
        overlap = np.minimum(pa.max(axis=0), pb.max(axis=0)) - np.maximum(
            pa.min(axis=0), pb.min(axis=0)
        )
        depth = min(depth, float(overlap.min()))
    return depth
