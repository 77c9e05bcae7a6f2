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
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml

__all__ = [
    "DEFAULT_MAP",
    "MapError",
    "OccupancyMap",
    "bundled",
    "bundled_names",
    "load_map",
    "resolve_map",
]

DEFAULT_MAP = "basement_loop"
"""Name of the bundled map used when none is given."""


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

        Cells may lie outside the image; use :meth:`in_bounds` to check.
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
        mask = ~self.occupied
        if clearance > 0:
            mask = mask & (self.distance >= clearance)
        cells = np.argwhere(mask)
        if len(cells) == 0:
            raise MapError(f"map {self.name!r}: no free cell with clearance >= {clearance} m")
        pick = cells[rng.integers(0, len(cells), size=n)]
        u = (pick[:, 1] + rng.random(n)) * self.resolution
        v = (self.height - 1 - pick[:, 0] + rng.random(n)) * self.resolution
        xy = self.map_to_world(np.stack([u, v], axis=-1))
        theta = rng.uniform(-math.pi, math.pi, size=n)
        return np.column_stack([xy, theta])


# ---------------------------------------------------------------------- loading
_REQUIRED = ("image", "resolution", "origin")


def _fail(path: Path, problem: str) -> MapError:
    return MapError(f"map {path}: {problem}")


def _read_yaml(path: Path) -> dict:
    if not path.is_file():
        raise _fail(path, "file not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise _fail(path, f"not valid YAML ({exc})") from exc
    if not isinstance(data, dict):
        raise _fail(path, "expected a YAML mapping with image, resolution and origin")
    for key in _REQUIRED:
        if key not in data:
            raise _fail(path, f"missing required key {key!r}")
    return data


def _number(path: Path, data: dict, key: str, default: float | None = None) -> float:
    value = data.get(key, default)
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise _fail(path, f"{key!r} must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise _fail(path, f"{key!r} must be finite, got {value!r}")
    return out


def _read_image(path: Path, image_path: Path) -> np.ndarray:
    if not image_path.is_file():
        raise _fail(path, f"image {image_path} not found")
    img = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED)
    if img is None or img.size == 0:
        raise _fail(path, f"image {image_path} could not be read as PNG/PGM")
    if img.ndim == 3:
        # map_server averages the colour channels; an alpha channel is ignored.
        img = img[..., :3].mean(axis=2)
    if img.dtype == np.uint16:
        img = img / 257.0
    return img.astype(np.float64)


def load_map(path: str | os.PathLike[str]) -> OccupancyMap:
    """Load a ROS map_server YAML and its image into an :class:`OccupancyMap`.

    Honoured keys: ``image`` (relative to the YAML), ``resolution`` (m/cell), ``origin`` [x, y, yaw]
    (metres, radians), ``negate``, ``occupied_thresh``, ``free_thresh``, ``mode`` (``trinary``
    (default), ``scale`` or ``raw``). Unknown cells count as occupied.

    Raises:
        MapError: the file is missing, a key is missing or invalid, the image is missing or unreadable,
            the thresholds are not 0 <= free < occupied <= 1, or the map has no free cell.
    """
    path = Path(path)
    data = _read_yaml(path)
    resolution = _number(path, data, "resolution")
    if resolution <= 0:
        raise _fail(path, f"'resolution' must be positive, got {resolution}")
    origin = data["origin"]
    if not isinstance(origin, list | tuple) or len(origin) != 3:
        raise _fail(path, f"'origin' must be [x, y, yaw], got {origin!r}")
    try:
        origin_f = tuple(float(v) for v in origin)
    except (TypeError, ValueError):
        raise _fail(path, f"'origin' must be three numbers, got {origin!r}") from None
    if not all(math.isfinite(v) for v in origin_f):
        raise _fail(path, f"'origin' must be finite, got {origin!r}")
    occ_t = _number(path, data, "occupied_thresh", 0.65)
    free_t = _number(path, data, "free_thresh", 0.196)
    for key, val in (("occupied_thresh", occ_t), ("free_thresh", free_t)):
        if not 0.0 <= val <= 1.0:
            raise _fail(path, f"{key!r} must be in [0, 1], got {val}")
    if free_t >= occ_t:
        raise _fail(path, f"free_thresh ({free_t}) must be below occupied_thresh ({occ_t})")
    negate = data.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise _fail(path, f"'negate' must be 0 or 1, got {negate!r}")
    mode = str(data.get("mode", "trinary"))
    if mode not in ("trinary", "scale", "raw"):
        raise _fail(path, f"'mode' must be trinary, scale or raw, got {mode!r}")
    image_name = data["image"]
    if not isinstance(image_name, str) or not image_name:
        raise _fail(path, f"'image' must be a file name, got {image_name!r}")
    image_path = Path(image_name)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    img = _read_image(path, image_path)

    if mode == "raw":
        known = img <= 100
        p = np.where(known, img / 100.0, 0.5)
        occupied = ~(known & (p < free_t))
    else:
        p = img / 255.0 if negate else (255.0 - img) / 255.0
        free = p < free_t
        occupied = ~free  # occupied and unknown alike
    if occupied.all():
        raise _fail(path, "the map has no free cell (check negate and the thresholds)")
    return OccupancyMap(
        occupied=occupied,
        resolution=resolution,
        origin=origin_f,  # type: ignore[arg-type]
        name=path.name.split(".")[0],
        path=path,
    )


# ---------------------------------------------------------------------- bundled maps
def _bundled_dir() -> Path:
    env = os.environ.get("RACECAR_SIM_MAPS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parent.parent / "maps"


def bundled_names() -> list[str]:
    """Names of the maps shipped in the repository's ``maps/`` folder (sorted)."""
    folder = _bundled_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.glob("*.yaml"))


def bundled(name: str = DEFAULT_MAP) -> Path:
    """Path of a bundled map's YAML by name (e.g. ``"basement_loop"``).

    Raises:
        MapError: no bundled map has that name; the message lists the ones there are.
    """
    path = _bundled_dir() / f"{name}.yaml"
    if not path.is_file():
        raise MapError(f"no bundled map named {name!r}; bundled maps: {', '.join(bundled_names())}")
    return path


def resolve_map(spec: str | os.PathLike[str] | OccupancyMap | None) -> OccupancyMap:
    """A map from a bundled name, a YAML path, an :class:`OccupancyMap`, or None (the default)."""
    if isinstance(spec, OccupancyMap):
        return spec
    if spec is None:
        return load_map(bundled(DEFAULT_MAP))
    text = os.fspath(spec)
    if text.endswith((".yaml", ".yml")) or os.sep in text or Path(text).is_file():
        return load_map(text)
    return load_map(bundled(text))
