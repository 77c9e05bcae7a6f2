"""What every driver shares: the driver protocol, the action, and scan helpers (lidar frame, metres)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

__all__ = ["Driver", "as_action", "beam_step", "despeckle", "fit_line", "scan_of"]


class Driver(Protocol):
    """What the env's drive loops call: observation (and optional true pose) -> action."""

    def __call__(self, obs: Mapping[str, Any], pose: np.ndarray | None = None) -> np.ndarray: ...


def scan_of(obs: Mapping[str, Any] | np.ndarray) -> np.ndarray:
    scan = obs["scan"] if isinstance(obs, Mapping) else obs
    scan = np.asarray(scan, dtype=np.float64).reshape(-1)
    if scan.size < 8:
        raise ValueError(f"obs['scan'] must hold at least 8 beams, got {scan.size}")
    return scan


def despeckle(scan: np.ndarray) -> np.ndarray:
    """The scan with isolated outliers removed: runs of at most two beams that are shorter (short
    or random returns) or longer (drop-outs) than both neighbours take their neighbours' range.

    A morphological closing then opening with a three-beam window; true edges stay in place.
    """
    closed = _erode3(_dilate3(scan))
    return _dilate3(_erode3(closed))


def _dilate3(s: np.ndarray) -> np.ndarray:
    p = np.concatenate([s[:1], s, s[-1:]])
    return np.maximum(np.maximum(p[:-2], p[1:-1]), p[2:])


def _erode3(s: np.ndarray) -> np.ndarray:
    p = np.concatenate([s[:1], s, s[-1:]])
    return np.minimum(np.minimum(p[:-2], p[1:-1]), p[2:])


def fit_line(
    px: np.ndarray, py: np.ndarray, rank: np.ndarray
) -> tuple[float, float, float, float, float] | None:
    """Total least squares line through points (lidar frame, metres), or None below 5 points.

    Returns (distance from the origin, direction ux, uy, normal nx, ny): the direction points
    the way ``rank`` grows along the points, the normal away from the origin.
    """
    if px.size < 5:
        return None
    cx, cy = px.mean(), py.mean()
    dx, dy = px - cx, py - cy
    sxx, syy, sxy = (dx * dx).mean(), (dy * dy).mean(), (dx * dy).mean()
    theta = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # principal direction
    ux, uy = math.cos(theta), math.sin(theta)
    if np.dot(rank - rank.mean(), dx * ux + dy * uy) < 0:
        ux, uy = -ux, -uy
    nx, ny = -uy, ux
    offset = cx * nx + cy * ny
    if offset < 0:
        nx, ny, offset = -nx, -ny, -offset
    return float(offset), ux, uy, nx, ny


def beam_step(fov: float, n: int) -> int:
    """Stride through n beams over fov radians keeping them at most half a degree apart."""
    spacing = fov / max(n - 1, 1)
    return max(1, int(math.radians(0.5) / spacing))


def as_action(steer: float, speed: float) -> np.ndarray:
    return np.array([steer, speed], dtype=np.float32)
