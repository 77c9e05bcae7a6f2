"""The lidar wall follower: keeps a wall at a set distance on one side, from the scan alone.

Frames: scans are in the lidar frame (x forward, y left, at the lidar); metres, radians.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from racecar_sim.drivers.base import as_action, beam_step, despeckle, fit_line, scan_of
from racecar_sim.settings.config import CarParams, LidarParams, nested

__all__ = ["WallFollower"]


@dataclass(frozen=True)
class WallFollower:
    """PD wall follower on the lidar scan, with look-ahead, a collision check and slowing down.

    Each call, on a scan cleaned of isolated outliers (`despeckle()`):

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
       the driver's only state; `reset()` clears it.

    Beams are assumed spread evenly over ``lidar.fov`` (radians, centred on the heading) for
    whatever length the scan has; the lidar sits ``lidar.mount_offset`` metres ahead of the rear
    axle. The car's geometry comes from ``car`` (one source of truth with the env).

    Attributes:
        side: ``"right"`` or ``"left"``, the wall to follow.
        distance: metres to keep from the wall (measured from the lidar).
        speed: metres per second on a clear straight.
        kp: radians of steering per metre of distance error.
        kd: radians of steering per unit of sin(wall angle).
        lookahead: metres ahead at which the distance is predicted.
        window: (near, far) radians from the front on ``side`` whose beams fit the wall.
        fit_range: metres; farther hits are ignored when fitting the wall.
        trim: metres from a line within which a hit counts as lying on it.
        n_segments: runs of neighbouring hits whose lines are the candidates for the wall.
        car_width: metres, width of the swept corridor checked for obstacles (car plus margin).
        n_arcs: steering angles tried when the wanted arc is blocked.
        brake: metres per second squared of planned braking.
        stop_distance: metres of clear arc kept in front of the bumper when stopped.
        check_distance: metres of clear arc wanted beyond the braking distance; arcs into places
            too small to drive out of again (alcoves, narrow doors) are blocked within it.
        min_speed: metres per second, the crawl speed near obstacles.
        reverse_speed: metres per second of backing out when every arc ahead is blocked within
            ``stop_distance`` (0 never reverses); the car backs up, nose turning away from the
            wall, until an arc ahead is clear for ``check_distance``.
        car: the car's geometry and limits (wheelbase, max_steer, length, rear_overhang), as the
            env's [`CarParams`][racecar_sim.settings.config.CarParams]; `for_env()` takes the env's own.
        lidar: the lidar's ``fov`` (radians) and ``mount_offset`` (metres ahead of the rear axle),
            as the env's [`LidarParams`][racecar_sim.settings.config.LidarParams].
    """

    side: str = "right"
    distance: float = 0.8
    speed: float = 2.0
    kp: float = 1.0
    kd: float = 1.2
    lookahead: float = 0.8
    window: tuple[float, float] = (math.radians(15.0), math.radians(115.0))
    fit_range: float = 3.0
    trim: float = 0.15
    n_segments: int = 8
    car_width: float = 0.5
    n_arcs: int = 15
    brake: float = 3.0
    stop_distance: float = 0.4
    check_distance: float = 1.5
    min_speed: float = 0.3
    reverse_speed: float = 0.6
    car: CarParams = field(default_factory=CarParams)
    lidar: LidarParams = field(default_factory=LidarParams)
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _state: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.side not in ("right", "left"):
            raise ValueError(f"WallFollower.side must be 'right' or 'left', got {self.side!r}")
        positive = (
            "distance",
            "kp",
            "fit_range",
            "trim",
            "car_width",
            "brake",
        )
        non_negative = (
            "speed",
            "kd",
            "lookahead",
            "stop_distance",
            "check_distance",
            "min_speed",
            "reverse_speed",
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
        for name, cls in (("car", CarParams), ("lidar", LidarParams)):
            object.__setattr__(self, name, nested(getattr(self, name), cls, f"WallFollower.{name}"))
        steers = np.linspace(-self.max_steer, self.max_steer, self.n_arcs)
        object.__setattr__(self, "_steers", steers)

    @classmethod
    def for_env(cls, env: Any, **settings: Any) -> WallFollower:
        """A wall follower with the geometry of ``env`` (a RacecarSim env, wrapped or not)."""
        base = env.unwrapped
        return cls(car=base.car_params, lidar=base.lidar_params, **settings)

    @property
    def fov(self) -> float:
        """Radians covered by the scan (the lidar's)."""
        return float(self.lidar.fov)

    @property
    def mount_offset(self) -> float:
        """Metres from the rear axle forwards to the lidar."""
        return float(self.lidar.mount_offset)

    @property
    def max_steer(self) -> float:
        """Radians, limit of the steering command (the car's)."""
        return float(self.car.max_steer)

    @property
    def wheelbase(self) -> float:
        """Metres between the axles (for the arcs of the collision check)."""
        return float(self.car.wheelbase)

    @property
    def car_front(self) -> float:
        """Metres from the rear axle forwards to the front bumper."""
        return float(self.car.length - self.car.rear_overhang)

    @property
    def car_rear(self) -> float:
        """Metres from the rear axle back to the rear bumper."""
        return float(self.car.rear_overhang)

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
            line = fit_line(px[keep], py[keep], rank[keep])
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
        step = self._cache.setdefault(("step", scan.size), beam_step(self.fov, scan.size))
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
        raw = scan_of(obs)
        last = self._state.get("scan")
        if last is not None and last.shape == raw.shape and np.array_equal(last, raw):
            return self._state["action"].copy()
        action = self._decide(despeckle(self.without_body(raw)))
        self._state["scan"] = raw
        self._state["action"] = action
        return action.copy()

    def without_body(self, scan: np.ndarray) -> np.ndarray:
        """``scan`` with the readings whose end points lie inside the car's own outline (the car's
        body seen by its lidar, as the real racecar's rear wheel is) set to the lidar's maximum
        range (no return): nothing else can be there."""
        cos_a, sin_a = self._geometry(scan.size)[:2]
        r = np.asarray(scan, dtype=np.float64)
        x = r * cos_a + self.mount_offset  # rear-axle frame, metres
        y = r * sin_a
        inside = (x >= -self.car_rear) & (x <= self.car_front) & (np.abs(y) <= 0.5 * float(self.car.width))
        if not inside.any():
            return scan
        out = np.array(scan, dtype=np.float64)
        out[inside] = float(self.lidar.max_range)
        return out

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
                return as_action(wanted, min(v_want, math.sqrt(2.0 * self.brake * max(room, 0.0))))
        steers = np.concatenate([[wanted], self._steers])
        clear = self._arc_clearance(scan, steers, need)
        if reversing:
            if clear.max() < need and self._can_reverse(scan):
                return self._reverseas_action()
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
            return self._reverseas_action()
        speed = min(v_want, math.sqrt(2.0 * self.brake * max(room, 0.0)))
        if clear[k] > 0.5 * self.stop_distance:
            speed = max(speed, min(self.min_speed, self.speed))  # creep on, else stand still
        return as_action(float(steers[k]), speed)

    def _reverseas_action(self) -> np.ndarray:
        return as_action(self.sign * self.max_steer, -self.reverse_speed)

    def _can_reverse(self, scan: np.ndarray) -> bool:
        """Whether the reversing arc is clear for ``stop_distance`` (as far as the beams see)."""
        back = np.array([self.sign * self.max_steer])
        return bool(self._arc_clearance(scan, back, 1.0, backwards=True)[0] >= self.stop_distance)
