"""Geometry along the map's walls that the map does not show: furniture standing against a wall,
and openings in it (glass, open doors) through which the lidar sees past the mapped wall.

Both are placed by the share of the map's wall they cover, so a scene means the same on a small
map and a large one, and on any route through it. A wall point is a free cell next to an occupied one; its outward
normal comes from the distance field, its surface lies the cell's distance behind it.

* **Furniture**: a box of width ``furniture_width`` along the wall and depth ``furniture_depth``
  out of it, its back against the wall (a gap of 2 cm); static, it blocks the car and the lidar
  like the other boxes of [`racecar_sim.world.obstacles`][racecar_sim.world.obstacles].
* **Openings**: a segment of the wall's face, ``opening_width`` long. A beam whose mapped wall
  point lies within ``_FACE`` metres of the segment returns from behind it: true range plus the
  opening's depth (0.15 m plus an exponential of mean ``opening_depth``, one per opening, like the
  back wall of a room seen through a door).

Frames: world (metres). Everything is drawn from the generator passed in.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.maps import OccupancyMap

__all__ = ["WallPoints", "opening_ranges", "place_furniture", "place_openings"]

_FACE = 0.08
"""Metres: a beam's end point this close to an opening's segment passes through it."""
_GAP = 0.02
"""Metres between a piece of furniture and its wall."""


class WallPoints:
    """The free cells next to a wall of ``occupancy_map``, with their outward normals.

    Attributes:
        xy: (N, 2) world centres of the cells.
        normal: (N, 2) unit normals pointing away from the wall (world).
        depth: (N,) metres from the cell centre to the wall's face.
        length: metres of wall face, about N x resolution.
    """

    def __init__(self, occupancy_map: OccupancyMap) -> None:
        m = occupancy_map
        dist = m.distance
        res = m.resolution
        cells = np.argwhere((dist > 0) & (dist <= 1.01 * res))
        xy = m.grid_to_world(cells)
        # outward normal: the distance field's gradient at two cells' reach (world frame)
        h = 2.0 * res
        ex, ey = np.array([h, 0.0]), np.array([0.0, h])
        gx = m.distance_at(xy + ex) - m.distance_at(xy - ex)
        gy = m.distance_at(xy + ey) - m.distance_at(xy - ey)
        norm = np.hypot(gx, gy)
        keep = norm > 1e-9
        self.xy = xy[keep]
        self.normal = np.stack([gx[keep], gy[keep]], axis=1) / norm[keep, None]
        self.depth = dist[cells[keep, 0], cells[keep, 1]] - 0.5 * res
        self.length = float(len(self.xy) * res)
        self.map = m
        self._cells = cells[keep]
        self._index = np.full(dist.shape, -1, dtype=np.int64)
        self._index[self._cells[:, 0], self._cells[:, 1]] = np.arange(len(self.xy))

    def near(self, i: int, radius: float) -> np.ndarray:
        """Indices of the wall points within about ``radius`` metres of point ``i`` (the grid
        cells of a square around it)."""
        k = int(math.ceil(radius / self.map.resolution))
        r, c = self._cells[i]
        block = self._index[max(r - k, 0) : r + k + 1, max(c - k, 0) : c + k + 1]
        return block[block >= 0]

    def straight(self, i: int, half: float) -> bool:
        """Whether the wall at point ``i`` runs straight for ``half`` metres to either side (the
        distance field stays at one cell along the tangent)."""
        res = self.map.resolution
        t = np.array([-self.normal[i, 1], self.normal[i, 0]])
        s = np.linspace(-half, half, max(3, int(2 * half / res) + 1))
        pts = self.xy[i] + s[:, None] * t
        d = self.map.distance_at(pts)
        return bool((np.abs(d - self.map.distance_at(self.xy[i][None])[0]) <= 0.6 * res).all())


def _count(cover: float, length: float, mean_width: float) -> int:
    return round(cover * length / mean_width)


def _on_segments(pts: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """bool (N,): which points (N, 2) lie within ``_FACE`` of segment ``seg`` [x0, y0, x1, y1]
    with their projection on it (the test of `opening_ranges()`)."""
    a, d = seg[:2], seg[2:4] - seg[:2]
    rel = pts - a
    s = rel @ d / float(d @ d)
    off = rel - s[:, None] * d
    return (s >= 0.0) & (s <= 1.0) & ((off * off).sum(axis=1) <= _FACE * _FACE)


def place_openings(
    walls: WallPoints,
    rng: np.random.Generator,
    cover: float,
    width: tuple[float, float],
    depth_mean: float,
) -> np.ndarray:
    """(K, 5) openings [x0, y0, x1, y1, depth] on wall faces (world metres), until ``cover`` of
    the wall's face points lie on one.

    Each opening is centred on a face point drawn uniformly, along the wall's tangent there, and
    the share is counted on the face points that the beam test of `opening_ranges()`
    passes (overlaps count once, a segment that leaves a bent wall counts only where it meets
    it). So every stretch of wall is an opening with about the same probability, ``cover``,
    and the expected share of *beams* whose mapped end point is an opening is ``cover`` on any
    route, however the beams fall on the walls (a wall beside the car takes many of them).
    """
    n_pts = len(walls.xy)
    if cover <= 0.0 or n_pts == 0:
        return np.zeros((0, 5))
    face = walls.xy - walls.normal * walls.depth[:, None]
    covered = np.zeros(n_pts, dtype=bool)
    need = cover * n_pts
    reach = 0.5 * width[1] + _FACE
    out = []
    for _ in range(20 * _count(cover, walls.length, 0.5 * (width[0] + width[1])) + 20):
        if covered.sum() >= need:
            break
        i = int(rng.integers(n_pts))
        w = float(rng.uniform(*width))
        depth = 0.15 + rng.exponential(depth_mean)
        if covered[i]:
            continue
        nrm = walls.normal[i]
        t = np.array([-nrm[1], nrm[0]])
        seg = np.r_[face[i] - 0.5 * w * t, face[i] + 0.5 * w * t]
        near = walls.near(i, reach)
        hit = near[_on_segments(face[near], seg)]
        covered[hit] = True
        out.append([*seg, depth])
    return np.asarray(out, dtype=np.float64).reshape(-1, 5)


def place_furniture(
    walls: WallPoints,
    rng: np.random.Generator,
    cover: float,
    width: tuple[float, float],
    depth: tuple[float, float],
    car_xy: np.ndarray,
    keep_out: float,
) -> np.ndarray:
    """(K, 4, 2) world corners of boxes standing with their backs against walls until ``cover``
    of the wall's face points lie behind one (as `place_openings()` counts them), none
    within ``keep_out`` metres of ``car_xy``, none overlapping, each in free space."""
    n_pts = len(walls.xy)
    if cover <= 0.0 or n_pts == 0:
        return np.zeros((0, 4, 2))
    face_pts = walls.xy - walls.normal * walls.depth[:, None]
    covered = np.zeros(n_pts, dtype=bool)
    need = cover * n_pts
    boxes: list[np.ndarray] = []
    centres: list[np.ndarray] = []
    radii: list[float] = []
    m = walls.map
    for _ in range(20 * _count(cover, walls.length, 0.5 * (width[0] + width[1])) + 20):
        if covered.sum() >= need:
            break
        i = int(rng.integers(n_pts))
        w, d = float(rng.uniform(*width)), float(rng.uniform(*depth))
        if covered[i]:
            continue
        nrm = walls.normal[i]
        t = np.array([-nrm[1], nrm[0]])
        face = face_pts[i]
        c = face + nrm * (_GAP + 0.5 * d)
        r = 0.5 * math.hypot(w, d)
        if np.hypot(*(c - car_xy)) < keep_out + r:
            continue
        if any(np.hypot(*(c - o)) < r + ro + 0.05 for o, ro in zip(centres, radii, strict=True)):
            continue
        corners = np.array([c + sx * 0.5 * w * t + sy * 0.5 * d * nrm
                            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])  # fmt: skip
        # the box must stand in free space (not across a corner or another wall)
        inner = c + 0.45 * (corners - c)
        if not (m.distance_at(np.vstack([c[None], inner])) > 0).all():
            continue
        if m.distance_at(c[None])[0] < 0.5 * d:
            continue
        near = walls.near(i, 0.5 * w + _FACE)
        back = np.r_[face - 0.5 * w * t, face + 0.5 * w * t]
        covered[near[_on_segments(face_pts[near], back)]] = True
        boxes.append(corners)
        centres.append(c)
        radii.append(r)
    return np.asarray(boxes, dtype=np.float64).reshape(-1, 4, 2)


@nb.njit(cache=True)
def opening_ranges(ox, oy, heading, angles, openings, max_range, ranges):
    """ranges[i] += the depth of the opening that beam i's mapped end point lies on (in place).

    ox, oy, heading: the lidar's world pose; angles (B,) beam angles; openings (K, 5)
    [x0, y0, x1, y1, depth]; ranges (B,) true ranges to the mapped walls, metres (clipped to
    ``max_range``; a beam with no wall in range is left alone).
    """
    for i in range(angles.size):
        r = ranges[i]
        if r >= max_range:
            continue
        a = heading + angles[i]
        ex, ey = ox + r * math.cos(a), oy + r * math.sin(a)
        for k in range(openings.shape[0]):
            x0, y0 = openings[k, 0], openings[k, 1]
            sx, sy = openings[k, 2] - x0, openings[k, 3] - y0
            ll = sx * sx + sy * sy
            s = ((ex - x0) * sx + (ey - y0) * sy) / ll
            if s < 0.0 or s > 1.0:
                continue
            px, py = x0 + s * sx - ex, y0 + s * sy - ey
            if px * px + py * py <= _FACE * _FACE:
                ranges[i] = min(r + openings[k, 4], max_range)
                break
