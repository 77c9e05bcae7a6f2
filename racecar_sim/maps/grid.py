"""Occupancy grid maps in ROS map_server format (YAML + PNG/PGM).

Frames
------
``world``
    The map frame of the YAML ``origin``: metres, x right, y up.
``grid``
    (row, col) of the image, row 0 is the *top* row of the PNG.
``map`` (internal)
    Metres along the image axes before the origin rotation: ``u = col * res`` grows with the column,
    ``v = (H - row) * res`` grows towards the top of the image. The corner of cell (row, col) with the
    smallest (u, v) is ``(col * res, (H - 1 - row) * res)``, and
    ``world = origin_xy + R(origin_yaw) @ (u, v)`` as the ROS map_server and the MIT racecar simulator
    define it.

Unknown cells (neither free nor occupied by the thresholds) count as occupied, for ray casting and for
collision alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

__all__ = ["MapError", "OccupancyMap"]


class MapError(ValueError):
    """A map YAML or its image is missing or invalid; the message names the file and the problem."""


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """An occupancy grid with its geometry.

    Attributes:
        occupied: bool array (H, W), grid frame (row 0 = top of the image); True where a cell is
            occupied *or unknown*.
        resolution: cell size in metres per cell.
        origin: (x, y, yaw) of the lower-left corner of the image in the world frame (metres, radians).
        name: a short name (the YAML's stem).
        path: the YAML path the map was loaded from, if any.
    """

    occupied: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str = "map"
    path: Path | None = None
    _distance: np.ndarray | None = field(default=None, repr=False)
    _free_by_clearance: dict[float, np.ndarray] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        occ = np.ascontiguousarray(self.occupied, dtype=bool)
        if occ.ndim != 2 or occ.size == 0:
            raise MapError(
                f"map {self.name!r}: occupancy must be a non-empty 2-D array, got {occ.shape}"
            )
        if not (self.resolution > 0 and math.isfinite(self.resolution)):
            raise MapError(f"map {self.name!r}: resolution must be positive, got {self.resolution}")
        if occ.all():
            raise MapError(f"map {self.name!r}: the map has no free cell")
        occ.setflags(write=False)
        object.__setattr__(self, "occupied", occ)
        object.__setattr__(self, "resolution", float(self.resolution))
        object.__setattr__(self, "origin", tuple(float(v) for v in self.origin))

    # ------------------------------------------------------------------ geometry
    @property
    def height(self) -> int:
        """Number of rows (cells)."""
        return int(self.occupied.shape[0])

    @property
    def width(self) -> int:
        """Number of columns (cells)."""
        return int(self.occupied.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) in cells."""
        return (self.height, self.width)

    @property
    def free(self) -> np.ndarray:
        """bool array (H, W): True where a cell is known free."""
        return ~self.occupied

    @property
    def free_area(self) -> float:
        """Free floor area in square metres."""
        return float(np.count_nonzero(~self.occupied)) * self.resolution**2

    @property
    def extent(self) -> tuple[float, float]:
        """(width, height) of the image in metres."""
        return (self.width * self.resolution, self.height * self.resolution)

    @property
    def yaw(self) -> float:
        """Rotation of the grid in the world frame, radians."""
        return self.origin[2]

    def world_to_map(self, xy: np.ndarray) -> np.ndarray:
        """World (…, 2) metres -> map frame (u, v) metres along the image axes (see module doc)."""
        xy = np.asarray(xy, dtype=np.float64)
        dx = xy[..., 0] - self.origin[0]
        dy = xy[..., 1] - self.origin[1]
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)

    def map_to_world(self, uv: np.ndarray) -> np.ndarray:
        """Map frame (…, 2) metres (u, v) -> world (…, 2) metres."""
        uv = np.asarray(uv, dtype=np.float64)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        x = self.origin[0] + c * uv[..., 0] - s * uv[..., 1]
        y = self.origin[1] + s * uv[..., 0] + c * uv[..., 1]
        return np.stack([x, y], axis=-1)

    def world_to_grid(self, xy: np.ndarray) -> np.ndarray:
        """World points (…, 2) metres -> integer cells (…, 2) as [row, col] (grid frame).

        Cells may lie outside the image; use `in_bounds()` to check.
        """
        uv = self.world_to_map(xy)
        col = np.floor(uv[..., 0] / self.resolution).astype(np.int64)
        row = self.height - 1 - np.floor(uv[..., 1] / self.resolution).astype(np.int64)
        return np.stack([row, col], axis=-1)

    def grid_to_world(self, rc: np.ndarray) -> np.ndarray:
        """Cells (…, 2) as [row, col] -> world (…, 2) metres of the cell *centres*."""
        rc = np.asarray(rc, dtype=np.float64)
        u = (rc[..., 1] + 0.5) * self.resolution
        v = (self.height - 1 - rc[..., 0] + 0.5) * self.resolution
        return self.map_to_world(np.stack([u, v], axis=-1))

    def in_bounds(self, rc: np.ndarray) -> np.ndarray:
        """bool (…,): whether cells [row, col] lie inside the image."""
        rc = np.asarray(rc)
        return (
            (rc[..., 0] >= 0)
            & (rc[..., 0] < self.height)
            & (rc[..., 1] >= 0)
            & (rc[..., 1] < self.width)
        )

    def is_free(self, xy: np.ndarray) -> np.ndarray:
        """bool (…,): whether world points (…, 2) lie in a free cell inside the map."""
        rc = self.world_to_grid(xy)
        inside = self.in_bounds(rc)
        out = np.zeros(rc.shape[:-1], dtype=bool)
        r = rc[..., 0][inside]
        c = rc[..., 1][inside]
        out[inside] = ~self.occupied[r, c]
        return out

    # ------------------------------------------------------------------ distance field
    @property
    def distance(self) -> np.ndarray:
        """float64 (H, W): metres from each cell's centre to the nearest occupied cell's centre.

        Cells beyond the image border count as occupied, so free cells at the edge are 1 cell away
        from a wall. Occupied cells hold 0. Computed once (OpenCV exact Euclidean transform).
        """
        if self._distance is None:
            padded = np.pad(~self.occupied, 1, constant_values=False).astype(np.uint8)
            dist = cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
            dist = dist[1:-1, 1:-1].astype(np.float64) * self.resolution
            dist.setflags(write=False)
            object.__setattr__(self, "_distance", dist)
        assert self._distance is not None
        return self._distance

    def distance_at(self, xy: np.ndarray) -> np.ndarray:
        """Distance field (metres) at world points (…, 2), nearest cell; 0 outside the map."""
        rc = self.world_to_grid(xy)
        inside = self.in_bounds(rc)
        out = np.zeros(rc.shape[:-1], dtype=np.float64)
        out[inside] = self.distance[rc[..., 0][inside], rc[..., 1][inside]]
        return out

    # ------------------------------------------------------------------ sampling
    def free_cells(self) -> np.ndarray:
        """int64 (K, 2) [row, col] of every free cell."""
        return np.argwhere(~self.occupied)

    def _free_cells_with(self, clearance: float) -> np.ndarray:
        """int64 (K, 2) [row, col] of the free cells whose distance field is at least
        ``clearance`` metres (any free cell for 0), found once per clearance (the grid never
        changes) and read-only: recovery draws from them at every resampling while lost."""
        cells = self._free_by_clearance.get(clearance)
        if cells is None:
            mask = ~self.occupied
            if clearance > 0:
                mask = mask & (self.distance >= clearance)
            cells = np.argwhere(mask)
            cells.setflags(write=False)
            self._free_by_clearance[clearance] = cells
        return cells

    def sample_free_poses(
        self, rng: np.random.Generator, n: int, clearance: float = 0.0
    ) -> np.ndarray:
        """``n`` poses (n, 3) [x, y, theta] uniform over free space (world frame), theta in [-pi, pi).

        Args:
            rng: source of randomness.
            n: number of poses.
            clearance: minimum distance field value (metres) of the chosen cells; 0 allows any free
                cell. Positions are uniform within each chosen cell.
        """
        cells = self._free_cells_with(float(clearance))
        if len(cells) == 0:
            raise MapError(f"map {self.name!r}: no free cell with clearance >= {clearance} m")
        pick = cells[rng.integers(0, len(cells), size=n)]
        u = (pick[:, 1] + rng.random(n)) * self.resolution
        v = (self.height - 1 - pick[:, 0] + rng.random(n)) * self.resolution
        xy = self.map_to_world(np.stack([u, v], axis=-1))
        theta = rng.uniform(-math.pi, math.pi, size=n)
        return np.column_stack([xy, theta])
