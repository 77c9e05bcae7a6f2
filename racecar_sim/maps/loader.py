"""Reading ROS map_server YAML + image files into an [`OccupancyMap`][racecar_sim.maps.grid.OccupancyMap]."""

from __future__ import annotations

import math
import os
from pathlib import Path

import cv2
import numpy as np
import yaml

from racecar_sim.maps.grid import MapError, OccupancyMap
from racecar_sim.maps.limits import (
    MAX_ORIGIN,
    MAX_RESOLUTION,
    MIN_RESOLUTION,
    check_cells,
    image_size,
)
from racecar_sim.settings.validation import load_yaml, read_text, short, yaml_problem

__all__ = ["load_map"]

_REQUIRED = ("image", "resolution", "origin")


def _fail(path: Path, problem: str) -> MapError:
    return MapError(f"map {path}: {problem}")


def _read_yaml(path: Path) -> dict:
    if not path.is_file():
        raise _fail(path, "file not found")
    try:
        data = load_yaml(read_text(path))
    except yaml.YAMLError as exc:
        raise _fail(path, f"not valid YAML ({yaml_problem(exc)})") from exc
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
        raise _fail(path, f"{key!r} must be a number, got {short(value)}") from None
    if not math.isfinite(out):
        raise _fail(path, f"{key!r} must be finite, got {short(value)}")
    return out


def _read_image(path: Path, image_path: Path, max_cells: int | None) -> np.ndarray:
    if not image_path.is_file():
        raise _fail(path, f"image {image_path} not found")
    size = image_size(image_path)
    if size is not None:  # checked before the image is decoded (nothing allocated yet)
        check_cells(f"map {path}: image {image_path.name}", size[0], size[1], max_cells)
    img = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED)
    if img is None or img.size == 0:
        raise _fail(path, f"image {image_path} could not be read as PNG/PGM")
    if img.ndim == 3:
        # map_server averages the colour channels; an alpha channel is ignored.
        img = img[..., :3].mean(axis=2)
    if img.dtype == np.uint16:
        img = img / 257.0
    return img.astype(np.float64)


def load_map(path: str | os.PathLike[str], max_cells: int | None = None) -> OccupancyMap:
    """Load a ROS map_server YAML and its image into an `OccupancyMap`.

    Honoured keys: ``image`` (relative to the YAML), ``resolution`` (m/cell), ``origin`` [x, y, yaw]
    (metres, radians), ``negate``, ``occupied_thresh``, ``free_thresh``, ``mode`` (``trinary``
    (default), ``scale`` or ``raw``). Unknown cells count as occupied.

    The YAML is read without anchors or aliases; the image's size is read from its header and
    checked against ``max_cells`` (None: `racecar_sim.maps.limits.max_map_cells()`) before
    it is decoded; ``resolution`` must lie in [MIN_RESOLUTION, MAX_RESOLUTION] and the origin's
    x and y within +-MAX_ORIGIN metres (`racecar_sim.maps.limits`).

    Raises:
        MapError: the file is missing, a key is missing or invalid, the image is missing or unreadable,
            the thresholds are not 0 <= free < occupied <= 1, or the map has no free cell.
    """
    path = Path(path)
    data = _read_yaml(path)
    resolution = _number(path, data, "resolution")
    if not MIN_RESOLUTION <= resolution <= MAX_RESOLUTION:
        raise _fail(
            path,
            f"'resolution' must be in [{MIN_RESOLUTION:g}, {MAX_RESOLUTION:g}] metres per cell, "
            f"got {resolution:g}",
        )
    origin = data["origin"]
    if not isinstance(origin, list | tuple) or len(origin) != 3:
        raise _fail(path, f"'origin' must be [x, y, yaw], got {short(origin)}")
    try:
        origin_f = tuple(float(v) for v in origin)
    except (TypeError, ValueError):
        raise _fail(path, f"'origin' must be three numbers, got {short(origin)}") from None
    if not all(math.isfinite(v) for v in origin_f):
        raise _fail(path, f"'origin' must be finite, got {short(origin)}")
    if max(abs(origin_f[0]), abs(origin_f[1])) > MAX_ORIGIN:
        raise _fail(path, f"'origin' x and y must be within +-{MAX_ORIGIN:g} m, got {short(origin)}")
    occ_t = _number(path, data, "occupied_thresh", 0.65)
    free_t = _number(path, data, "free_thresh", 0.196)
    for key, val in (("occupied_thresh", occ_t), ("free_thresh", free_t)):
        if not 0.0 <= val <= 1.0:
            raise _fail(path, f"{key!r} must be in [0, 1], got {val}")
    if free_t >= occ_t:
        raise _fail(path, f"free_thresh ({free_t}) must be below occupied_thresh ({occ_t})")
    negate = data.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise _fail(path, f"'negate' must be 0 or 1, got {short(negate)}")
    mode = data.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise _fail(path, f"'mode' must be trinary, scale or raw, got {short(mode)}")
    image_name = data["image"]
    if not isinstance(image_name, str) or not image_name:
        raise _fail(path, f"'image' must be a file name, got {short(image_name)}")
    image_path = Path(image_name)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    img = _read_image(path, image_path, max_cells)
    check_cells(f"map {path}: image {image_path.name}", img.shape[1], img.shape[0], max_cells)

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
