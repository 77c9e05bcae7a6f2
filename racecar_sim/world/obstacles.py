"""Unmapped obstacles: static boxes and walking people that block both the car and the lidar.

They are what the map does not show, so that short returns come from geometry rather than from a
coin flip. Boxes stand near walls (so hallways stay passable) as static pymunk polygons; people
walk straight lines between random free points at a walking pace as kinematic pymunk circles,
and stop while the car is close to them. The lidar, at knee height on a 1/10 car, sees a person
as two legs (circles) that swing with the gait. Both take part in the car's collisions like
walls (contact is reported, and ends the episode when the env terminates on collision).

Placement draws only from the generator given to `Obstacles.spawn()` (the env derives it
from its seed), so the same seed gives the same obstacles; nothing is placed within
``keep_out`` metres of the car's start. Frames: world (metres, radians).
"""

from __future__ import annotations

import math
from typing import Any

import numba as nb
import numpy as np
import pymunk

from racecar_sim.maps import MapError, OccupancyMap
from racecar_sim.world.obstacle_params import ObstacleParams
from racecar_sim.world.wall_features import (
    WallPoints,
    opening_ranges,
    place_furniture,
    place_openings,
)

__all__ = ["Obstacles", "obstacle_ranges", "ray_segment"]

_WALL_COLLISION_TYPE = 2  # racecar_sim.car.physics.WALL_COLLISION_TYPE (imported lazily there)
_TRIES = 2000


@nb.njit(cache=True, inline="always")
def ray_segment(ox, oy, dx, dy, x0, y0, x1, y1, best):
    """The nearer of ``best`` and the distance along the ray from (ox, oy) in unit direction
    (dx, dy) to the segment (x0, y0)-(x1, y1) (world metres); ``best`` when the ray misses it."""
    ex, ey = x1 - x0, y1 - y0
    den = dx * ey - dy * ex
    if abs(den) < 1e-12:
        return best
    wx, wy = x0 - ox, y0 - oy
    t = (wx * ey - wy * ex) / den
    s = (wx * dy - wy * dx) / den
    if 0.0 < t < best and 0.0 <= s <= 1.0:
        return t
    return best


@nb.njit(cache=True)
def obstacle_ranges(ox, oy, heading, angles, circles, segments, max_range, out):
    """out[i] = min(out[i], distance along beam i to the nearest circle or segment), metres.

    ox, oy, heading: the lidar's world pose; angles (B,) beam angles; circles (K, 3) [cx, cy, r];
    segments (M, 4) [x0, y0, x1, y1].
    """
    for i in range(angles.size):
        a = heading + angles[i]
        dx, dy = math.cos(a), math.sin(a)
        best = out[i]
        for k in range(circles.shape[0]):
            fx, fy = circles[k, 0] - ox, circles[k, 1] - oy
            t_c = fx * dx + fy * dy
            if t_c <= 0.0:
                continue
            d2 = fx * fx + fy * fy - t_c * t_c
            r2 = circles[k, 2] * circles[k, 2]
            if d2 > r2:
                continue
            t = t_c - math.sqrt(r2 - d2)
            if 0.0 < t < best:
                best = t
        for k in range(segments.shape[0]):
            best = ray_segment(
                ox, oy, dx, dy, segments[k, 0], segments[k, 1], segments[k, 2], segments[k, 3], best
            )
        out[i] = min(best, max_range)


class Obstacles:
    """The boxes and people of one env, living in its pymunk space.

    Args:
        params: counts and sizes.
        occupancy_map: the world map (free space, distance field).
        space: the physics' pymunk space (shapes are added to it and removed on respawn).
    """

    def __init__(self, params: ObstacleParams, occupancy_map: OccupancyMap, space: pymunk.Space):
        self.params = params
        self.map = occupancy_map
        self.space = space
        self._shapes: list[Any] = []
        self._bodies: list[pymunk.Body] = []
        self.boxes = np.zeros((0, 4, 2))  # world corners of each box
        self.people = np.zeros((0, 2))  # world positions
        self._goals = np.zeros((0, 2))
        self._phase = np.zeros(0)
        self._heading = np.zeros(0)
        self._rng: np.random.Generator | None = None
        self._segments = np.zeros((0, 4))
        self._box_shapes: list[Any] = []
        self._cells: dict[tuple[float, float], np.ndarray] = {}
        self._walls: WallPoints | None = None
        self.openings = np.zeros((0, 5))  # [x0, y0, x1, y1, depth] per opening (world)

    # ------------------------------------------------------------------ placement
    def _free_points(self, rng: np.random.Generator, n: int, low: float, high: float) -> np.ndarray:
        key = (round(low, 3), round(high, 3) if math.isfinite(high) else high)
        cells = self._cells.get(key)
        if cells is None:
            dist = self.map.distance
            cells = np.argwhere((dist >= low) & (dist <= high))
            self._cells[key] = cells
        if len(cells) == 0:
            raise MapError(f"map {self.map.name!r}: no room for obstacles")
        pick = cells[rng.integers(0, len(cells), size=n)]
        jitter = (rng.random((n, 2)) - 0.5) * self.map.resolution
        return self.map.grid_to_world(pick) + jitter

    def _line_free(self, a: np.ndarray, b: np.ndarray, clearance: float) -> bool:
        n = max(2, int(np.hypot(*(b - a)) / self.map.resolution))
        pts = a + (b - a) * np.linspace(0, 1, n)[:, None]
        return bool((self.map.distance_at(pts) >= clearance).all())

    def spawn(self, rng: np.random.Generator, car_pose: np.ndarray) -> None:
        """(Re)place every obstacle, ``keep_out`` metres or more from the car at ``car_pose``."""
        for shape in self._shapes:
            self.space.remove(shape)
        for body in self._bodies:
            self.space.remove(body)
        self._shapes, self._bodies = [], []
        p = self.params
        car = np.asarray(car_pose, dtype=np.float64)[:2]
        boxes = []
        lo, hi = p.box_size
        for _ in range(p.boxes):
            for _ in range(_TRIES):
                w, h = rng.uniform(lo, hi, size=2)
                half = 0.5 * math.hypot(w, h)
                c = self._free_points(rng, 1, 0.05 * math.ceil(half / 0.05) + 0.05, half + 0.6)[0]
                if np.hypot(*(c - car)) < p.keep_out + half:
                    continue
                if any(np.hypot(*(c - b.mean(axis=0))) < half + 0.6 for b in boxes):
                    continue
                th = rng.uniform(-math.pi, math.pi)
                rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
                local = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2
                boxes.append(c + local @ rot.T)
                break
        boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4, 2)
        if p.furniture or p.openings:
            if self._walls is None:
                self._walls = WallPoints(self.map)
            keep = max(0.6, min(p.keep_out, 1.0))  # the car starts beside furniture in a corridor
            furniture = place_furniture(self._walls, rng, p.furniture, p.furniture_width,
                                        p.furniture_depth, car, keep)  # fmt: skip
            boxes = np.concatenate([boxes, furniture])
            self.openings = place_openings(self._walls, rng, p.openings, p.opening_width,
                                           p.opening_depth)  # fmt: skip
        self._set_boxes(boxes)
        people = []
        n_people = p.people + round(p.crowd * self.map.free_area / 100.0)
        for _ in range(n_people):
            for _ in range(_TRIES):
                c = self._free_points(rng, 1, p.person_radius + 0.15, np.inf)[0]
                if np.hypot(*(c - car)) >= p.keep_out + p.person_radius:
                    people.append(c)
                    break
        self.people = np.asarray(people, dtype=np.float64).reshape(-1, 2)
        self._rng = rng
        self._goals = self.people.copy()
        self._heading = rng.uniform(-math.pi, math.pi, size=len(self.people))
        self._phase = rng.uniform(0, 2 * math.pi, size=len(self.people))
        for c in self.people:
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.position = (float(c[0]), float(c[1]))
            shape = pymunk.Circle(body, p.person_radius)
            shape.collision_type = _WALL_COLLISION_TYPE
            self.space.add(body, shape)
            self._bodies.append(body)
            self._shapes.append(shape)

    def _set_boxes(self, boxes: np.ndarray) -> None:
        self.boxes = boxes
        self._box_shapes = []
        for corners in self.boxes:
            shape = pymunk.Poly(self.space.static_body, [tuple(v) for v in corners.tolist()])
            shape.collision_type = _WALL_COLLISION_TYPE
            shape.friction = 0.2
            self.space.add(shape)
            self._shapes.append(shape)
            self._box_shapes.append(shape)
        seg = [np.r_[b[i], b[(i + 1) % 4]] for b in self.boxes for i in range(4)]
        self._segments = np.asarray(seg, dtype=np.float64).reshape(-1, 4)

    def move_box(self, i: int, corners: np.ndarray) -> None:
        """Put box ``i`` at world ``corners`` (4, 2) (tests, scripted scenes)."""
        old = self._box_shapes[i]
        self.space.remove(old)
        self._shapes.remove(old)
        boxes = self.boxes.copy()
        boxes[i] = np.asarray(corners, dtype=np.float64)
        keep = [s for s in self._shapes if s not in self._box_shapes]
        for shape in self._box_shapes:
            if shape is not old:
                self.space.remove(shape)
        self._shapes = keep
        self._set_boxes(boxes)

    def move_person(self, i: int, xy: np.ndarray, goal: np.ndarray | None = None) -> None:
        """Put person ``i`` at world ``xy`` (2,) walking to ``goal`` (default: stay)."""
        self.people[i] = np.asarray(xy, dtype=np.float64)
        self._goals[i] = self.people[i] if goal is None else np.asarray(goal, dtype=np.float64)
        self._bodies[i].position = (float(self.people[i, 0]), float(self.people[i, 1]))

    # ------------------------------------------------------------------ motion
    def _new_goal(self, i: int) -> None:
        assert self._rng is not None
        p = self.params
        for _ in range(50):
            g = self._free_points(self._rng, 1, p.person_radius + 0.15, np.inf)[0]
            if 2.0 <= np.hypot(*(g - self.people[i])) <= 12.0 and self._line_free(
                self.people[i], g, p.person_radius + 0.1
            ):
                self._goals[i] = g
                return
        self._goals[i] = self.people[i]

    def step(self, dt: float, car_pose: np.ndarray) -> None:
        """Walk every person ``dt`` seconds (stopped while the car is near)."""
        p = self.params
        car = np.asarray(car_pose, dtype=np.float64)[:2]
        for i, body in enumerate(self._bodies):
            pos = self.people[i]
            to_goal = self._goals[i] - pos
            d = float(np.hypot(*to_goal))
            if d < 0.1:
                self._new_goal(i)
                to_goal = self._goals[i] - pos
                d = float(np.hypot(*to_goal))
            v = np.zeros(2)
            if d > 1e-9 and np.hypot(*(pos - car)) > p.stop_distance:
                v = to_goal / d * min(p.person_speed, d / dt)
                self._heading[i] = math.atan2(to_goal[1], to_goal[0])
                self._phase[i] += 2 * math.pi * 1.8 * dt * (np.hypot(*v) / max(p.person_speed, 1e-9))
            self.people[i] = pos + v * dt
            body.position = (float(self.people[i, 0]), float(self.people[i, 1]))
            body.velocity = (float(v[0]), float(v[1]))

    def near(self, xy: np.ndarray, reach: float) -> bool:
        """Whether any obstacle lies within ``reach`` metres of world point ``xy``."""
        xy = np.asarray(xy, dtype=np.float64)[:2]
        if len(self.people) and (np.hypot(*(self.people - xy).T) < reach + self.params.person_radius).any():
            return True
        if len(self.boxes):
            c = self.boxes.mean(axis=1)
            half = np.hypot(*(self.boxes[:, 0] - c).T)
            return bool((np.hypot(*(c - xy).T) < reach + half).any())
        return False

    # ------------------------------------------------------------------ drawing
    def draw(self, img: np.ndarray, renderer: Any) -> None:
        """Draw boxes (brown), openings (cyan lines) and people (purple discs) on a
        `MapRenderer` frame in place."""
        import cv2

        for seg in self.openings:
            ends = renderer.world_to_pixel(seg[:4].reshape(2, 2)).reshape(-1, 2)
            cv2.line(img, tuple(int(v) for v in ends[0]), tuple(int(v) for v in ends[1]),
                     (230, 200, 0), 2)  # fmt: skip

        for corners in self.boxes:
            cv2.fillPoly(img, [renderer.world_to_pixel(corners)], (150, 90, 40))
        if len(self.people):
            px = renderer.world_to_pixel(self.people)
            scale = float(np.hypot(*(renderer.world_to_pixel(np.array([[1.0, 0.0]]))
                                     - renderer.world_to_pixel(np.array([[0.0, 0.0]])))[0]))
            radius = max(2, round(self.params.person_radius * scale))
            for x, y in px.reshape(-1, 2).tolist():
                cv2.circle(img, (int(x), int(y)), radius, (160, 60, 200), -1)

    # ------------------------------------------------------------------ sensing
    def legs(self) -> np.ndarray:
        """(2 P, 3) leg circles [x, y, r] of the people (world), swinging with the gait."""
        p = self.params
        out = np.zeros((2 * len(self.people), 3))
        for i, c in enumerate(self.people):
            h = self._heading[i]
            fwd = np.array([math.cos(h), math.sin(h)])
            left = np.array([-fwd[1], fwd[0]])
            swing = 0.15 * math.sin(self._phase[i])
            out[2 * i, :2] = c + 0.1 * left + swing * fwd
            out[2 * i + 1, :2] = c - 0.1 * left - swing * fwd
            out[2 * i : 2 * i + 2, 2] = p.leg_radius
        return out

    def clip_ranges(self, lidar_pose: np.ndarray, angles: np.ndarray, ranges: np.ndarray,
                    max_range: float) -> np.ndarray:  # fmt: skip
        """``ranges`` (B,) lengthened where a beam's mapped wall is an opening, then shortened where
        a beam from ``lidar_pose`` hits an obstacle first."""
        out = np.array(ranges, dtype=np.float64)
        x, y, th = (float(v) for v in lidar_pose)
        if len(self.openings):
            opening_ranges(x, y, th, np.asarray(angles, dtype=np.float64), self.openings,
                           float(max_range), out)  # fmt: skip
        obstacle_ranges(x, y, th, np.asarray(angles, dtype=np.float64), self.legs(),
                        self._segments, float(max_range), out)  # fmt: skip
        return out
