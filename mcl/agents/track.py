"""The loop an agent drives: a closed polyline, arc length along it, and what lies ahead of a pose.

Progress along the loop (the agent's reward and its lap times) is the arc length ``s`` of the
point of the loop nearest the car, in metres from the loop's first point, increasing in the
driving direction. Frames: ``world`` (the map's) for the loop and poses, ``car`` (x forward,
y left, origin at the rear axle) for the look-ahead points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

__all__ = ["Track", "loop_maps", "track_for_map"]

_LOOP_START: dict[str, tuple[float, float, float]] = {
    "basement_loop": (9.0, 2.5, 0.0),  # south hallway, driving east (island on the left)
    "office": (11.5, 6.1, 0.0),
}
"""Where the wall follower starts recording the loop of a bundled map (world x m, y m, theta)."""


@dataclass(frozen=True, eq=False)
class Track:
    """A closed loop of world points (metres), in driving order.

    Attributes:
        points: (K, 2) world x, y; the segment from the last point back to the first closes it.
    """

    points: np.ndarray

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3 or not np.isfinite(pts).all():
            raise ValueError(f"Track.points must be (K >= 3, 2) finite metres, got {pts.shape}")
        nxt = np.roll(pts, -1, axis=0)
        seg = nxt - pts
        lengths = np.hypot(seg[:, 0], seg[:, 1])
        if (lengths <= 0).any():
            raise ValueError("Track.points has repeated consecutive points")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "_seg", seg)
        object.__setattr__(self, "_seg_len2", lengths**2)
        object.__setattr__(self, "_start_s", np.concatenate(([0.0], np.cumsum(lengths)[:-1])))
        object.__setattr__(self, "length", float(lengths.sum()))

    length: float = field(init=False, default=0.0)
    """Metres round the loop (set from the points)."""

    def project(self, xy: np.ndarray) -> tuple[float, float]:
        """Arc length ``s`` (m, in [0, length)) of the loop point nearest ``xy``, and the signed
        lateral offset (m, positive when ``xy`` lies left of the driving direction)."""
        p = np.asarray(xy, dtype=np.float64)[:2]
        rel = p - self.points
        t = np.clip((rel * self._seg).sum(axis=1) / self._seg_len2, 0.0, 1.0)
        d = rel - t[:, None] * self._seg
        dist2 = (d * d).sum(axis=1)
        i = int(np.argmin(dist2))
        seg = self._seg[i]
        cross = seg[0] * rel[i, 1] - seg[1] * rel[i, 0]
        lateral = math.copysign(math.sqrt(dist2[i]), cross) if cross != 0 else 0.0
        s = float(self._start_s[i] + t[i] * math.sqrt(self._seg_len2[i]))
        return s % self.length, lateral

    def point_at(self, s: np.ndarray | float) -> np.ndarray:
        """World points (..., 2) at arc lengths ``s`` (metres, taken modulo the length)."""
        s = np.mod(np.asarray(s, dtype=np.float64), self.length)
        i = np.clip(np.searchsorted(self._start_s, s, side="right") - 1, 0, len(self.points) - 1)
        frac = (s - self._start_s[i]) / np.sqrt(self._seg_len2[i])
        return self.points[i] + frac[..., None] * self._seg[i]

    def heading_at(self, s: float) -> float:
        """Direction of the loop (radians, world) at arc length ``s``."""
        s = float(np.mod(s, self.length))
        i = int(
            np.clip(np.searchsorted(self._start_s, s, side="right") - 1, 0, len(self.points) - 1)
        )
        return math.atan2(self._seg[i, 1], self._seg[i, 0])

    def ahead(self, pose: np.ndarray, s: float, distances: np.ndarray) -> np.ndarray:
        """Car-frame points (len(distances), 2) of the loop ``distances`` metres beyond ``s``,
        seen from ``pose`` = world [x, y, theta]."""
        pts = self.point_at(s + np.asarray(distances, dtype=np.float64)) - np.asarray(pose[:2])
        c, sn = math.cos(pose[2]), math.sin(pose[2])
        return np.stack([c * pts[:, 0] + sn * pts[:, 1], -sn * pts[:, 0] + c * pts[:, 1]], axis=1)

    def advance(self, s_from: float, s_to: float) -> float:
        """Signed metres from ``s_from`` to ``s_to`` the short way round (across the seam too)."""
        d = (s_to - s_from) % self.length
        return d - self.length if d > self.length / 2 else d


def loop_maps() -> list[str]:
    """The bundled maps whose loop start is known (:func:`track_for_map` needs no ``start``)."""
    return sorted(_LOOP_START)


@lru_cache(maxsize=4)
def track_for_map(map_name: str, start: tuple[float, float, float] | None = None) -> Track:
    """The loop the wall follower drives on ``map_name`` from ``start`` (default: the map's loop
    start), 0.25 m between points, oriented along the start heading; computed once per process.

    Raises:
        ValueError: no start is known for the map and none is given, or the drive closes no loop.
    """
    from racecar_sim.drivers import WallFollower, waypoints_from_drive
    from racecar_sim.env import RacecarEnv

    if start is None:
        if map_name not in _LOOP_START:
            raise ValueError(
                f"no loop start known for map {map_name!r}; give start=(x, y, theta) "
                f"(known: {sorted(_LOOP_START)})"
            )
        start = _LOOP_START[map_name]
    env = RacecarEnv(map_name)
    try:
        points = waypoints_from_drive(env, WallFollower(), start_pose=np.array(start), seed=0)
    except RuntimeError as exc:
        raise ValueError(f"map {map_name!r}: the wall follower closes no loop: {exc}") from exc
    return Track(points)
