"""Pure pursuit on a waypoint loop (world frame, metres), on the true or the estimated pose."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from racecar_sim.drivers.base import as_action
from racecar_sim.settings.config import CarParams
from racecar_sim.world.track import resample_polyline

__all__ = ["PurePursuit", "resample_polyline"]


class PurePursuit:
    """Pure pursuit on a polyline of waypoints (world frame), for a car steered about its rear axle.

    Each call finds the car's nearest point on the path (searching near the previous one, so a path
    that passes close to itself is not confused), takes the point ``lookahead`` metres further along
    the path, and steers on the circle through it: ``steer = atan(2 wheelbase sin(alpha) / l)``,
    ``alpha`` the target's bearing and ``l`` its distance from the rear axle.

    Args:
        waypoints: (K, 2) world metres, K >= 2.
        lookahead: metres along the path ahead of the nearest point.
        speed: metres per second; without ``loop`` it falls to 0 over the last ``lookahead`` metres.
        loop: whether the path closes from the last waypoint back to the first.
        car: the car's ``wheelbase`` (metres) and ``max_steer`` (radians), as the env's
            [`CarParams`][racecar_sim.settings.config.CarParams] (default: the default car).
    """

    def __init__(
        self,
        waypoints: np.ndarray,
        lookahead: float = 1.0,
        speed: float = 2.0,
        loop: bool = True,
        car: CarParams | None = None,
    ) -> None:
        car = car if car is not None else CarParams()
        pts = np.asarray(waypoints, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError(f"waypoints must have shape (K >= 2, 2), got {pts.shape}")
        if not np.isfinite(pts).all():
            raise ValueError("waypoints must be finite")
        if not (math.isfinite(lookahead) and lookahead > 0):
            raise ValueError(f"PurePursuit.lookahead = {lookahead!r} must be positive")
        if not (math.isfinite(speed) and speed >= 0):
            raise ValueError(f"PurePursuit.speed = {speed!r} must be non-negative")
        self.waypoints = pts
        self.lookahead = float(lookahead)
        self.speed = float(speed)
        self.wheelbase = float(car.wheelbase)
        self.loop = bool(loop)
        self.max_steer = float(car.max_steer)
        path = np.vstack([pts, pts[:1]]) if self.loop else pts
        self._a = path[:-1]
        self._v = np.diff(path, axis=0)
        seg = np.hypot(self._v[:, 0], self._v[:, 1])
        if seg.sum() <= 0:
            raise ValueError("waypoints must not all coincide")
        self._len2 = np.maximum(seg**2, 1e-18)
        self._s0 = np.concatenate([[0.0], np.cumsum(seg)[:-1]])  # arc length at segment starts
        self.length = float(seg.sum())
        """Metres along the whole path (closed when ``loop``)."""
        self._path_x = path[:, 0]
        self._path_y = path[:, 1]
        self._path_s = np.concatenate([[0.0], np.cumsum(seg)])
        self._s: float | None = None

    def reset(self) -> None:
        """Forget the progress along the path (the next call searches the whole path)."""
        self._s = None

    @property
    def progress(self) -> float | None:
        """Metres along the path of the last nearest point, or None before the first call."""
        return self._s

    def _nearest(self, xy: np.ndarray) -> tuple[float, float]:
        """(arc length, distance) of the path point nearest to ``xy``, near the last one if known."""
        rel = xy - self._a
        t = np.clip((rel[:, 0] * self._v[:, 0] + rel[:, 1] * self._v[:, 1]) / self._len2, 0.0, 1.0)
        near = self._a + t[:, None] * self._v
        dist = np.hypot(near[:, 0] - xy[0], near[:, 1] - xy[1])
        s_all = self._s0 + t * np.sqrt(self._len2)
        if self._s is not None:
            ahead = s_all - self._s
            if self.loop:
                ahead = (ahead + self.length / 2) % self.length - self.length / 2
            window = (ahead > -self.lookahead) & (ahead < 2 * self.lookahead + 1.0)
            if window.any():
                k = int(np.argmin(np.where(window, dist, np.inf)))
                if dist[k] < 2 * self.lookahead + 1.0:
                    return float(s_all[k]), float(dist[k])
        k = int(np.argmin(dist))
        return float(s_all[k]), float(dist[k])

    def _point_at(self, s: float) -> np.ndarray:
        if self.loop:
            s %= self.length
        else:
            s = min(max(s, 0.0), self.length)
        return np.array(
            [np.interp(s, self._path_s, self._path_x), np.interp(s, self._path_s, self._path_y)]
        )

    def target(self, pose: np.ndarray) -> np.ndarray:
        """World point (2,) the car at rear-axle ``pose`` steers to (updates the progress)."""
        xy = np.asarray(pose[:2], dtype=np.float64)
        s, _ = self._nearest(xy)
        self._s = s
        return self._point_at(s + self.lookahead)

    def __call__(self, obs: Mapping[str, Any] | None, pose: np.ndarray | None = None) -> np.ndarray:
        """Action float32 [steer rad, speed m/s] for the rear-axle world ``pose``.

        The pose comes from ``pose``, else from ``obs["pose_estimate"]``.

        Raises:
            ValueError: no pose is given, or it is not three finite numbers.
        """
        if pose is None:
            if isinstance(obs, Mapping) and "pose_estimate" in obs:
                pose = obs["pose_estimate"]
            else:
                raise ValueError(
                    "PurePursuit needs the car's pose: pass pose=[x, y, theta] or an obs with "
                    "'pose_estimate' (e.g. under mcl.LocalizationWrapper)"
                )
        p = np.asarray(pose, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ValueError(f"pose must be three finite numbers [x, y, theta], got {pose!r}")
        goal = self.target(p)
        dx, dy = goal[0] - p[0], goal[1] - p[1]
        c, s = math.cos(p[2]), math.sin(p[2])
        lx, ly = c * dx + s * dy, -s * dx + c * dy  # target in the car frame
        dist2 = max(lx * lx + ly * ly, 1e-9)
        steer = math.atan(2.0 * self.wheelbase * ly / dist2)
        steer = min(max(steer, -self.max_steer), self.max_steer)
        speed = self.speed
        if not self.loop:
            assert self._s is not None
            remaining = self.length - self._s
            speed *= min(max(remaining / self.lookahead, 0.0), 1.0)
        return as_action(steer, speed)
