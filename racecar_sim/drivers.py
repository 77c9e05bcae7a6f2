"""Autopilots for headless drives: a lidar wall follower and a pure-pursuit waypoint follower.

A driver is a callable ``driver(obs, pose=None) -> np.ndarray`` returning the action
``float32 [steer, speed]`` (front wheel angle in radians, positive to the left; speed in m/s along the
car's x axis). ``obs`` is the env's observation dict (``scan``, ``odom`` and, under
``mcl.LocalizationWrapper``, ``pose_estimate``); ``pose`` is a world pose [x, y, theta] of the rear
axle when the caller knows it.

Frames: scans are in the lidar frame (x forward, y left, at the lidar); the wall follower works in
it directly. Waypoints and poses are in the world frame (metres, radians).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

__all__ = [
    "Driver",
    "PurePursuit",
    "WallFollower",
    "despeckle",
    "resample_polyline",
    "waypoints_from_drive",
]


class Driver(Protocol):
    """What the env's drive loops call: observation (and optional true pose) -> action."""

    def __call__(self, obs: Mapping[str, Any], pose: np.ndarray | None = None) -> np.ndarray: ...


def _scan_of(obs: Mapping[str, Any] | np.ndarray) -> np.ndarray:
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


def _fit_line(
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


def _beam_step(fov: float, n: int) -> int:
    """Stride through n beams over fov radians keeping them at most half a degree apart."""
    spacing = fov / max(n - 1, 1)
    return max(1, int(math.radians(0.5) / spacing))


def _action(steer: float, speed: float) -> np.ndarray:
    return np.array([steer, speed], dtype=np.float32)


# ---------------------------------------------------------------------- wall follower
@dataclass(frozen=True)
class WallFollower:
    """PD wall follower on the lidar scan, with look-ahead, a collision check and slowing down.

    Each call, on a scan cleaned of isolated outliers (:func:`despeckle`):

    1. **Fit the wall.** The hits on ``side`` between ``window[0]`` and ``window[1]`` radians
       from the front and nearer than ``fit_range`` are cut into ``n_segments`` runs of
       neighbouring beams; each run's line is a candidate, and the one with the most hits within
       ``trim`` of it wins (beams bunch up on nearer walls, so the nearer wall wins), so a doorway
       or a recess beside the car does not pull the wall away. A total least squares line through
       the winner's hits gives the distance ``d`` from the lidar and the wall's angle ``phi`` to
       the heading, the line oriented from the rear beams to the front beams.
    2. **PD on the distance.** The distance predicted ``lookahead`` metres ahead,
       ``d_L = d + s L sin(phi)`` (``s`` = +1 left, -1 right), is steered towards ``distance``::

           steer = s * kp * (d_L - distance) + kd * sin(phi)

       ``sin(phi)`` is the change of ``d`` per metre driven, so ``kd`` is a derivative gain that
       needs no time step. When nothing is within ``fit_range`` abeam on ``side`` (the wall turns
       away round a corner, or the car is in the open) the car steers towards the nearest hit on
       ``side``, at full lock when that is abeam or behind.
    3. **Collision check.** The arc of that steering angle is checked against every hit for a
       car ``car_width`` wide over the distance needed to brake plus ``check_distance``; if it is
       blocked, the nearest steering angle (of ``n_arcs`` spread over the steering range) whose arc
       is clear is taken, else the one with the longest clear arc.
    4. **Speed.** ``speed``, less in sharp turns, and no more than what stops within the clear
       length of the chosen arc at ``brake`` m/s², never below ``min_speed`` unless the arc is
       blocked within half of ``stop_distance`` (then it stops).
    5. **Backing out.** When even the best arc is blocked within ``stop_distance`` (a dead end
       too tight to turn in), the car reverses at ``reverse_speed`` with full lock towards the
       wall side (so the nose swings away from it) until an arc ahead is clear again. This is
       the driver's only state; :meth:`reset` clears it.

    Beams are assumed spread evenly over ``fov`` (radians, centred on the heading) for whatever
    length the scan has; the lidar sits ``mount_offset`` metres ahead of the rear axle.

    Attributes:
        side: ``"right"`` or ``"left"``, the wall to follow.
        distance: metres to keep from the wall (measured from the lidar).
        speed: metres per second on a clear straight.
        kp: radians of steering per metre of distance error.
        kd: radians of steering per unit of sin(wall angle).
        fov: radians covered by the scan.
        lookahead: metres ahead at which the distance is predicted.
        window: (near, far) radians from the front on ``side`` whose beams fit the wall.
        fit_range: metres; farther hits are ignored when fitting the wall.
        trim: metres from a line within which a hit counts as lying on it.
        n_segments: runs of neighbouring hits whose lines are the candidates for the wall.
        max_steer: radians, limit of the steering command.
        wheelbase: metres between the axles (for the arcs of the collision check).
        mount_offset: metres from the rear axle forwards to the lidar.
        car_width: metres, width of the swept corridor checked for obstacles (car plus margin).
        car_front: metres from the rear axle forwards to the front bumper.
        n_arcs: steering angles tried when the wanted arc is blocked.
        brake: metres per second squared of planned braking.
        stop_distance: metres of clear arc kept in front of the bumper when stopped.
        check_distance: metres of clear arc wanted beyond the braking distance; arcs into places
            too small to drive out of again (alcoves, narrow doors) are blocked within it.
        min_speed: metres per second, the crawl speed near obstacles.
        reverse_speed: metres per second of backing out when every arc ahead is blocked within
            ``stop_distance`` (0 never reverses); the car backs up, nose turning away from the
            wall, until an arc ahead is clear for ``check_distance``.
        car_rear: metres from the rear axle back to the rear bumper.
    """

    side: str = "right"
    distance: float = 0.8
    speed: float = 2.0
    kp: float = 1.0
    kd: float = 1.2
    fov: float = 4.71
    lookahead: float = 0.8
    window: tuple[float, float] = (math.radians(15.0), math.radians(115.0))
    fit_range: float = 3.0
    trim: float = 0.15
    n_segments: int = 8
    max_steer: float = 0.42
    wheelbase: float = 0.33
    mount_offset: float = 0.275
    car_width: float = 0.5
    car_front: float = 0.44
    n_arcs: int = 15
    brake: float = 3.0
    stop_distance: float = 0.4
    check_distance: float = 1.5
    min_speed: float = 0.3
    reverse_speed: float = 0.6
    car_rear: float = 0.11
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _state: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.side not in ("right", "left"):
            raise ValueError(f"WallFollower.side must be 'right' or 'left', got {self.side!r}")
        positive = (
            "distance",
            "kp",
            "fov",
            "fit_range",
            "trim",
            "max_steer",
            "wheelbase",
            "car_width",
            "brake",
        )
        non_negative = (
            "speed",
            "kd",
            "lookahead",
            "car_front",
            "stop_distance",
            "check_distance",
            "min_speed",
            "reverse_speed",
            "car_rear",
        )
        for name in positive + non_negative:
            value = getattr(self, name)
            ok = value > 0 if name in positive else value >= 0
            if not (isinstance(value, int | float) and math.isfinite(value) and ok):
                sense = "positive" if name in positive else "non-negative"
                raise ValueError(f"WallFollower.{name} = {value!r} must be {sense}")
        if not isinstance(self.n_arcs, int) or self.n_arcs < 3:
            raise ValueError(f"WallFollower.n_arcs = {self.n_arcs!r} must be an integer >= 3")
        if not isinstance(self.n_segments, int) or self.n_segments < 1:
            raise ValueError(f"WallFollower.n_segments = {self.n_segments!r} must be >= 1")
        near, far = (float(v) for v in self.window)
        if not 0 <= near < far <= math.pi:
            raise ValueError(f"WallFollower.window = {self.window!r} must be 0 <= near < far <= pi")
        object.__setattr__(self, "window", (near, far))
        steers = np.linspace(-self.max_steer, self.max_steer, self.n_arcs)
        object.__setattr__(self, "_steers", steers)

    @property
    def sign(self) -> int:
        """+1 when following the left wall, -1 for the right wall (car-frame y direction)."""
        return 1 if self.side == "left" else -1

    def _geometry(self, n: int) -> tuple[np.ndarray, ...]:
        """cos, sin of the n beam angles, side-window mask, abeam mask, angles (cached per n)."""
        if n not in self._cache:
            angles = np.linspace(-self.fov / 2, self.fov / 2, n)
            rel = self.sign * angles
            side = (rel >= self.window[0]) & (rel <= self.window[1])
            abeam = (rel >= math.radians(60.0)) & (rel <= math.radians(120.0))
            self._cache[n] = (np.cos(angles), np.sin(angles), side, abeam, angles)
        return self._cache[n]

    def fit_wall(self, scan: np.ndarray) -> tuple[float, float] | None:
        """(distance d in metres, angle phi in radians) of the wall on ``side``, or None.

        ``phi`` is the wall direction relative to the heading (lidar frame), oriented from the
        hits of the rear beams towards those of the front beams; positive turns left. None when
        fewer than 5 hits qualify or none of them is abeam (60°-120° on ``side``).
        """
        cos_a, sin_a, side, abeam = self._geometry(scan.size)[:4]
        near = (scan < self.fit_range) & (scan > 0.02)
        use = side & near
        if np.count_nonzero(use) < 5 or not np.any(abeam & near):
            return None
        px = scan[use] * cos_a[use]
        py = scan[use] * sin_a[use]
        # Beam order from the rear to the front of the side: index order for the right side.
        rank = np.arange(px.size, dtype=np.float64)
        if self.sign > 0:
            rank = rank[::-1]
        # Candidate lines through runs of neighbouring hits; the wall is the one most hits lie on.
        n_runs = min(self.n_segments, px.size // 5)
        m = px.size // n_runs
        sx = px[: n_runs * m].reshape(n_runs, m)
        sy = py[: n_runs * m].reshape(n_runs, m)
        dx = sx - sx.mean(axis=1, keepdims=True)
        dy = sy - sy.mean(axis=1, keepdims=True)
        theta = 0.5 * np.arctan2(2.0 * (dx * dy).sum(axis=1), (dx * dx - dy * dy).sum(axis=1))
        nx, ny = -np.sin(theta), np.cos(theta)
        offset = sx.mean(axis=1) * nx + sy.mean(axis=1) * ny
        gap = np.abs(px[None, :] * nx[:, None] + py[None, :] * ny[:, None] - offset[:, None])
        score = (gap < self.trim).sum(axis=1) - np.abs(offset) * 1e-6
        keep = gap[int(np.argmax(score))] < self.trim
        line = None
        for _ in range(2):  # refit on the chosen line's hits, then once more
            line = _fit_line(px[keep], py[keep], rank[keep])
            if line is None:
                return None
            off, _, _, lnx, lny = line
            keep = np.abs(px * lnx + py * lny - off) < self.trim
        assert line is not None
        return float(line[0]), math.atan2(line[2], line[1])

    def _arc_clearance(
        self, scan: np.ndarray, steers: np.ndarray, reach: float, backwards: bool = False
    ) -> np.ndarray:
        """Metres the front (rear) bumper can drive forwards (``backwards``) along each arc.

        Capped at ``reach``. Arcs are circles about the rear axle (kinematic bicycle); a hit is
        any scan point within ``car_width / 2`` of the arc swept by the rear axle. Backwards the
        check only sees what the beams see (nothing within ``2 pi - fov`` straight behind).
        """
        cos_a, sin_a = self._geometry(scan.size)[:2]
        step = self._cache.setdefault(("step", scan.size), _beam_step(self.fov, scan.size))
        bumper = self.car_rear if backwards else self.car_front
        r = scan[::step]
        near = r < reach + bumper + self.car_width + self.mount_offset
        x = r[near] * cos_a[::step][near] + self.mount_offset  # rear-axle frame
        if backwards:
            x = -x  # driving backwards on a circle = driving forwards on its mirror image
        y = r[near] * sin_a[::step][near]
        ahead = x > 0.0
        x, y = x[ahead], y[ahead]
        if x.size == 0:
            return np.full(steers.shape, reach)
        kappa = np.tan(steers)[:, None] / self.wheelbase  # (K, 1) 1/metres
        radius = 1.0 / np.maximum(np.abs(kappa), 1e-6)
        # Mirror right turns onto left turns: the centre of every arc is then (0, radius).
        towards = radius - np.where(kappa < 0, -y, y)  # (K, P) centre-to-point along -y
        rho2 = x * x + towards * towards
        half = self.car_width / 2
        hit = (rho2 < (radius + half) ** 2) & (rho2 > np.maximum(radius - half, 0.0) ** 2)
        psi = np.full(hit.shape, np.inf)
        np.arctan2(np.broadcast_to(x, hit.shape), towards, out=psi, where=hit)  # in (0, pi)
        travel = radius * psi - bumper
        return np.clip(travel.min(axis=1), 0.0, reach)

    def reset(self) -> None:
        """Forget the driving state (whether the car is backing out of a dead end)."""
        self._state.clear()

    def wanted_steer(self, scan: np.ndarray) -> float:
        """Radians of steering the PD law asks for on a (despeckled) scan, before the check."""
        s = self.sign
        wall = self.fit_wall(scan)
        if wall is None:
            return self._seek_wall(scan)
        d, phi = wall
        d_ahead = d + s * self.lookahead * math.sin(phi)
        wanted = s * self.kp * (d_ahead - self.distance) + self.kd * math.sin(phi)
        return min(max(wanted, -self.max_steer), self.max_steer)

    def _seek_wall(self, scan: np.ndarray) -> float:
        """Steering towards the nearest hit on ``side`` (full lock when it is abeam or behind)."""
        angles = self._geometry(scan.size)[4]
        on_side = self.sign * angles >= 0.0
        k = int(np.argmin(np.where(on_side, scan, np.inf)))
        return min(max(float(angles[k]), -self.max_steer), self.max_steer)

    def __call__(self, obs: Mapping[str, Any] | np.ndarray, pose: np.ndarray | None = None):
        """Action float32 [steer rad, speed m/s] from ``obs["scan"]`` (``pose`` is unused).

        The same scan again (the env repeats it between lidar scans) gives the same action.
        """
        raw = _scan_of(obs)
        last = self._state.get("scan")
        if last is not None and last.shape == raw.shape and np.array_equal(last, raw):
            return self._state["action"].copy()
        action = self._decide(despeckle(raw))
        self._state["scan"] = raw
        self._state["action"] = action
        return action.copy()

    def _decide(self, scan: np.ndarray) -> np.ndarray:
        """The action for a despeckled scan (updates the backing-out state)."""
        wanted = self.wanted_steer(scan)
        v_want = self.speed * (1.0 - 0.5 * abs(wanted) / self.max_steer)
        need = self.check_distance + v_want**2 / (2.0 * self.brake)
        reversing = self._state.get("reversing", False)
        if not reversing:  # the usual case: the wanted arc is clear, no need to look further
            clear_wanted = float(self._arc_clearance(scan, np.array([wanted]), need)[0])
            if clear_wanted >= need:
                room = clear_wanted - self.stop_distance
                return _action(wanted, min(v_want, math.sqrt(2.0 * self.brake * max(room, 0.0))))
        steers = np.concatenate([[wanted], self._steers])
        clear = self._arc_clearance(scan, steers, need)
        if reversing:
            if clear.max() < need and self._can_reverse(scan):
                return self._reverse_action()
            self._state["reversing"] = False
        ok = clear >= need
        if ok[0]:
            k = 0
        elif ok.any():
            k = int(np.argmin(np.where(ok, np.abs(steers - wanted), np.inf)))
        else:
            best = clear.max()
            k = int(np.argmin(np.where(clear >= best - 1e-6, np.abs(steers - wanted), np.inf)))
        room = float(clear[k]) - self.stop_distance
        if room <= 0.0 and self.reverse_speed > 0 and self._can_reverse(scan):
            self._state["reversing"] = True  # boxed in: back out, nose turning off the wall
            return self._reverse_action()
        speed = min(v_want, math.sqrt(2.0 * self.brake * max(room, 0.0)))
        if clear[k] > 0.5 * self.stop_distance:
            speed = max(speed, min(self.min_speed, self.speed))  # creep on, else stand still
        return _action(float(steers[k]), speed)

    def _reverse_action(self) -> np.ndarray:
        return _action(self.sign * self.max_steer, -self.reverse_speed)

    def _can_reverse(self, scan: np.ndarray) -> bool:
        """Whether the reversing arc is clear for ``stop_distance`` (as far as the beams see)."""
        back = np.array([self.sign * self.max_steer])
        return bool(self._arc_clearance(scan, back, 1.0, backwards=True)[0] >= self.stop_distance)


# ---------------------------------------------------------------------- pure pursuit
def resample_polyline(points: np.ndarray, spacing: float, loop: bool = False) -> np.ndarray:
    """Points (K, 2) every ``spacing`` metres along the polyline through ``points`` (world).

    With ``loop`` the polyline closes from the last point back to the first.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.isfinite(pts).all():
        raise ValueError(f"points must be finite (K >= 2, 2), got shape {pts.shape}")
    if not spacing > 0:
        raise ValueError(f"spacing must be positive metres, got {spacing}")
    if loop:
        pts = np.vstack([pts, pts[:1]])
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        raise ValueError("points must not all coincide")
    n = max(int(round(s[-1] / spacing)), 2)
    t = np.linspace(0.0, s[-1], n, endpoint=not loop)
    return np.column_stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])])


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
        wheelbase: metres between the axles.
        loop: whether the path closes from the last waypoint back to the first.
        max_steer: radians, limit of the steering command.
    """

    def __init__(
        self,
        waypoints: np.ndarray,
        lookahead: float = 1.0,
        speed: float = 2.0,
        wheelbase: float = 0.33,
        loop: bool = True,
        max_steer: float = 0.42,
    ) -> None:
        pts = np.asarray(waypoints, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError(f"waypoints must have shape (K >= 2, 2), got {pts.shape}")
        if not np.isfinite(pts).all():
            raise ValueError("waypoints must be finite")
        for name, value in (("lookahead", lookahead), ("wheelbase", wheelbase)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"PurePursuit.{name} = {value!r} must be positive")
        if not (math.isfinite(speed) and speed >= 0):
            raise ValueError(f"PurePursuit.speed = {speed!r} must be non-negative")
        if not 0 < max_steer < math.pi / 2:
            raise ValueError(f"PurePursuit.max_steer = {max_steer!r} must be in (0, pi/2)")
        self.waypoints = pts
        self.lookahead = float(lookahead)
        self.speed = float(speed)
        self.wheelbase = float(wheelbase)
        self.loop = bool(loop)
        self.max_steer = float(max_steer)
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
        return _action(steer, speed)


# ---------------------------------------------------------------------- waypoints
def waypoints_from_drive(
    env: Any,
    driver: Callable[..., np.ndarray],
    *,
    seed: int | None = None,
    start_pose: np.ndarray | None = None,
    spacing: float = 0.25,
    max_steps: int = 100_000,
    close_radius: float = 1.0,
    min_length: float = 10.0,
    close_heading: float = math.pi / 4,
    check_every: int = 10,
) -> np.ndarray:
    """Drive ``driver`` in ``env`` until its path repeats; that cycle as a waypoint loop.

    ``env`` is a RacecarSim env (``reset(seed=, options={"pose": ...})``, ``step(action)`` with the
    true pose in ``info["pose"]``). The loop closes when the car, after covering ``min_length``
    more metres, comes back within ``close_radius`` metres of a point of its path *heading the same
    way* (within ``close_heading`` radians); the loop is the path since that point. Passing a point
    the other way (an out-and-back round a pillar) is not a loop, and a driver that settles into a
    cycle which never passes its start again (the wall follower started in a side room) still closes
    one. The path is checked every ``check_every`` steps.

    Returns:
        (K, 2) world metres, one point every ``spacing`` metres, for ``PurePursuit(loop=True)``,
        ordered so that a car at the start pose drives along it forwards (the cycle may run the
        other way, e.g. when the wall follower turned round a pillar before settling).

    Raises:
        RuntimeError: the car collided or did not close a loop within ``max_steps``.
    """
    options = {"pose": list(map(float, start_pose))} if start_pose is not None else None
    reset = getattr(driver, "reset", None)
    if callable(reset):
        reset()  # a driver with state (the wall follower backing out) starts afresh
    obs, info = env.reset(seed=seed, options=options)
    poses = np.empty((max_steps + 1, 3))
    covered = np.zeros(max_steps + 1)  # metres driven up to each pose
    poses[0] = info["pose"]
    for k in range(1, max_steps + 1):
        obs, _, terminated, truncated, info = env.step(driver(obs, info["pose"]))
        poses[k] = info["pose"]
        covered[k] = covered[k - 1] + float(np.hypot(*(poses[k, :2] - poses[k - 1, :2])))
        if info.get("collision", False):
            raise RuntimeError(
                f"the car collided at {poses[k, :2].round(2).tolist()} after {covered[k]:.1f} m"
            )
        if k % check_every == 0 or terminated or truncated:
            j = _earlier_pass(
                poses[: k + 1], covered[: k + 1], close_radius, min_length, close_heading
            )
            if j is not None:
                loop = resample_polyline(poses[j:k, :2], spacing, loop=True)
                return _oriented_along(loop, poses[0])
        if terminated or truncated:
            break
    raise RuntimeError(f"the drive did not return to its start (covered {covered[k]:.1f} m)")


def _oriented_along(loop: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``loop`` (K, 2), reversed if needed so that it runs forwards for a car at ``pose`` [x, y, theta].

    The direction is judged at the waypoint nearest the pose: a car started against it would need
    a U-turn in a hallway, which pure pursuit does not plan.
    """
    i = int(np.argmin(np.hypot(*(loop - pose[:2]).T)))
    tangent = loop[(i + 1) % len(loop)] - loop[i - 1]
    if tangent @ np.array([math.cos(pose[2]), math.sin(pose[2])]) < 0:
        return loop[::-1].copy()
    return loop


def _earlier_pass(
    poses: np.ndarray,
    covered: np.ndarray,
    radius: float,
    min_length: float,
    max_turn: float,
) -> int | None:
    """Index of the earlier pose the last pose closes a loop on, or None (see waypoints_from_drive).

    Candidates lie at least ``min_length`` metres of driving back, within ``radius`` metres and
    ``max_turn`` radians of heading; of the most recent pass through them, the nearest is chosen.
    """
    last = poses[-1]
    old = covered <= covered[-1] - min_length
    gap = np.hypot(poses[:, 0] - last[0], poses[:, 1] - last[1])
    turn = np.abs(np.remainder(poses[:, 2] - last[2] + np.pi, 2 * np.pi) - np.pi)
    hits = np.flatnonzero(old & (gap < radius) & (turn < max_turn))
    if hits.size == 0:
        return None
    recent = hits[covered[hits] >= covered[hits[-1]] - 2 * radius]
    return int(recent[np.argmin(gap[recent])])
