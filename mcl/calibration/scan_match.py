"""Reference poses for recorded scans: a brute-force search of the whole map, then local scan
matching against exact ray casts.

Without ground truth, a real scan's "true" pose is taken as the lidar pose where the scan agrees
best with the map: a robust (Geman-McClure, scale ``scale`` metres) sum over the valid beams of
``measured - cast`` range residuals, casts exact ([`RayCaster`][racecar_sim.raycast.RayCaster]
``"exact"``). The global search scores poses on a coarse lattice with the map's distance field at
the beam end points (a likelihood field); the best few are then refined by pattern search on the
cast residuals. Poses here are *lidar* poses [x, y, theta] in the map's world frame (metres,
radians).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numba as nb
import numpy as np

from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import RayCaster

__all__ = ["MatchParams", "ScanMatcher", "robust_loss"]


@dataclass(frozen=True)
class MatchParams:
    """Settings of the scan matcher.

    Attributes:
        scale: metres, scale of the robust loss (residuals much larger count as outliers).
        lattice_step: metres between the global search's positions.
        lattice_headings: number of headings tried at each position.
        lattice_beams: beams used by the global search (spread over the scan).
        lattice_sigma: metres, width of the global search's likelihood field.
        candidates: how many lattice maxima are refined.
        step0: (metres, radians) first pattern-search step.
        step_min: metres, the search stops when the position step falls below this.
    """

    scale: float = 0.05
    lattice_step: float = 0.2
    lattice_headings: int = 180
    lattice_beams: int = 90
    lattice_sigma: float = 0.25
    candidates: int = 40
    step0: tuple[float, float] = (0.1, 0.03)
    step_min: float = 0.002


def robust_loss(residual: np.ndarray, scale: float) -> np.ndarray:
    """Geman-McClure loss r² / (r² + scale²) per residual (NaN counts as a full outlier, 1)."""
    r2 = np.square(residual)
    out = r2 / (r2 + scale * scale)
    return np.where(np.isfinite(out), out, 1.0)


@nb.njit(cache=True, parallel=True)
def _lattice_scores(dist, res, ox, oy, yaw, xy, headings, angles, ranges, sigma, out):
    """out[p, a] = mean over beams of exp(-d²/2σ²), d = distance field at the beam's end point."""
    h, w = dist.shape
    c0, s0 = math.cos(yaw), math.sin(yaw)
    inv = -0.5 / (sigma * sigma)
    for p in nb.prange(xy.shape[0]):
        for a in range(headings.shape[0]):
            acc = 0.0
            for b in range(angles.shape[0]):
                th = headings[a] + angles[b]
                ex = xy[p, 0] + ranges[b] * math.cos(th) - ox
                ey = xy[p, 1] + ranges[b] * math.sin(th) - oy
                u = c0 * ex + s0 * ey
                v = -s0 * ex + c0 * ey
                col = int(math.floor(u / res))
                row = h - 1 - int(math.floor(v / res))
                if 0 <= row < h and 0 <= col < w:
                    d = dist[row, col]
                    acc += math.exp(inv * d * d)
            out[p, a] = acc / angles.shape[0]


class ScanMatcher:
    """Finds lidar poses of scans on ``occupancy_map``.

    Args:
        occupancy_map: the map (world frame).
        angles: (B,) beam angles in the lidar frame, radians.
        max_range: metres; casts are clipped to it and measured ranges beyond it are ignored.
        params: the matcher's settings.
    """

    def __init__(
        self,
        occupancy_map: OccupancyMap,
        angles: np.ndarray,
        max_range: float,
        params: MatchParams | None = None,
    ) -> None:
        self.map = occupancy_map
        self.angles = np.asarray(angles, dtype=np.float64)
        self.max_range = float(max_range)
        self.params = params or MatchParams()
        self.caster = RayCaster(occupancy_map, self.max_range, method="exact")
        self._edge_distance: np.ndarray | None = None

    @property
    def edge_distance(self) -> np.ndarray:
        """float64 (H, W) metres to the nearest *wall* cell: an occupied cell next to a free one.

        Unlike the map's distance field this keeps unknown space (occupied in the map) far from
        everything, so end points falling outside the building do not score.
        """
        if self._edge_distance is None:
            occ = self.map.occupied
            free = (~occ).astype(np.uint8)
            near_free = cv2.dilate(free, np.ones((3, 3), np.uint8)).astype(bool)
            wall = occ & near_free
            d = cv2.distanceTransform((~wall).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
            self._edge_distance = d.astype(np.float64) * self.map.resolution
        return self._edge_distance

    # ------------------------------------------------------------------ scoring
    def residuals(self, pose: np.ndarray, ranges: np.ndarray) -> np.ndarray:
        """(B,) measured minus exact cast range at lidar ``pose`` (NaN where measured is NaN)."""
        return ranges - self.caster.cast(np.asarray(pose, dtype=np.float64), self.angles)[0]

    def losses(self, poses: np.ndarray, ranges: np.ndarray) -> np.ndarray:
        """(N,) mean robust loss of ``ranges`` at each of ``poses`` (N, 3)."""
        cast = self.caster.cast(poses, self.angles)
        ok = np.isfinite(ranges) & (ranges < self.max_range)
        res = ranges[ok][None, :] - cast[:, ok]
        return robust_loss(res, self.params.scale).mean(axis=1)

    # ------------------------------------------------------------------ search
    def refine(self, pose: np.ndarray, ranges: np.ndarray, step0=None) -> tuple[np.ndarray, float]:
        """Pattern search from ``pose``: (best lidar pose (3,), its mean robust loss)."""
        p = self.params
        best = np.asarray(pose, dtype=np.float64).copy()
        dxy, dth = step0 if step0 is not None else p.step0
        best_loss = float(self.losses(best[None, :], ranges)[0])
        offsets = np.array(
            [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if i or j or k],
            dtype=np.float64,
        )
        while dxy >= p.step_min:
            cand = best[None, :] + offsets * np.array([dxy, dxy, dth])
            loss = self.losses(cand, ranges)
            i = int(np.argmin(loss))
            if loss[i] < best_loss - 1e-12:
                best, best_loss = cand[i], float(loss[i])
            else:
                dxy, dth = dxy / 2, dth / 2
        best[2] = (best[2] + math.pi) % (2 * math.pi) - math.pi
        return best, best_loss

    def global_search(
        self, ranges: np.ndarray, clearance: float = 0.15
    ) -> tuple[np.ndarray, float]:
        """The best lidar pose of one scan over the whole map: (pose (3,), mean robust loss)."""
        p = self.params
        m = self.map
        ok = np.flatnonzero(np.isfinite(ranges) & (ranges < min(self.max_range, 15.0)))
        pick = ok[np.linspace(0, ok.size - 1, min(p.lattice_beams, ok.size)).astype(np.int64)]
        stride = max(1, round(p.lattice_step / m.resolution))
        mask = np.zeros(m.shape, dtype=bool)
        mask[::stride, ::stride] = True
        cells = np.argwhere(mask & (m.distance >= clearance))
        xy = m.grid_to_world(cells)
        headings = np.linspace(-math.pi, math.pi, p.lattice_headings, endpoint=False)
        scores = np.empty((xy.shape[0], headings.size))
        dist = np.ascontiguousarray(self.edge_distance)
        _lattice_scores(
            dist, m.resolution, m.origin[0], m.origin[1], m.yaw, np.ascontiguousarray(xy),
            headings, self.angles[pick], ranges[pick], p.lattice_sigma, scores,
        )  # fmt: skip
        order = np.argsort(scores, axis=None)[::-1]
        chosen: list[np.ndarray] = []
        for flat in order:
            i, a = divmod(int(flat), headings.size)
            pose = np.array([xy[i, 0], xy[i, 1], headings[a]])
            if all(
                np.hypot(*(pose[:2] - c[:2])) > 1.0
                or abs((pose[2] - c[2] + math.pi) % (2 * math.pi) - math.pi) > 0.3
                for c in chosen
            ):
                chosen.append(pose)
            if len(chosen) >= p.candidates:
                break
        coarse = np.full_like(ranges, np.nan)
        coarse[::4] = ranges[::4]
        step = (p.lattice_step, 2 * math.pi / p.lattice_headings)
        refined = [self.refine(c, coarse, step) for c in chosen]
        best = min(refined, key=lambda t: t[1])[0]
        return self.refine(best, ranges, (0.02, 0.01))
