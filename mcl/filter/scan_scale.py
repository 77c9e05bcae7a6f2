"""The odometry's forward speed scale measured by the scans alone: two scans half a metre apart,
matched to each other, say how far the car drove, whatever the map says.

The MIT racecar's VESC reports about 5 % less speed than the car drives (``docs/honest_noise.md``).
[OdometryScale][mcl.filter.odometry_scale.OdometryScale] learns that from the filter's own
estimate, between poses the scan confirms against the map; where the map is out of date the scan
confirms few poses, and the ones it confirms may lie where the old map drags the estimate
(``docs/localization_changing_world.md``). Two scans of the world, on the other hand, agree with
each other wherever the world stands still, map or no map.

[ScanScale][mcl.filter.scan_scale.ScanScale] keeps a reference scan and integrates the odometry
from it. Once the odometry has driven ``spacing`` metres, the newest scan is matched to the
reference: the car's motion is taken as the odometry's with its forward component times a scale
``s``, its sideways component moved by up to ``lateral`` metres and its turn by up to ``heading``
radians, and the reference's points (``beams`` of them, evenly spaced), moved by that motion into
the newest lidar frame, are scored against the newest scan at their bearings (a Gaussian of the
range difference, ``tolerance`` metres plus ``tolerance_per_m`` per metre of range; points the
newest scan sees well short of them, hidden behind something, are left out). A coarse grid over
``s`` from ``low`` to ``high`` finds the best motion and a fine one refines it
([match_forward_scale][mcl.filter.scan_scale.match_forward_scale]). Along a corridor whose walls
look the same, every ``s`` scores alike: a pair counts only when the best coarse score beats every
scale at least 0.08 away by ``min_sharpness`` (0 by default), and never when the best motion lies
on the grid's edge (a pinned car whose wheels spin). Pairs whose odometry turned more than it drove
straight (forward displacement under half the path) are not matched.

The scale is the counted pairs' matched forward travel over their odometry's (each pair's ``s``
weighted by the metres its odometry drove forward), with the prior (1, the wheels as read)
counted as ``prior_metres`` of pairs. One pair's own ratio of true to reported travel spreads
from 0.8 to 1.4 over half a metre (the VESC's noise), so a pair says little alone; summed over
pairs, that noise averages out (a median of the pairs' scales, tried first, needed 20 s to settle;
``docs/localization_changing_world.md``).

Measured on the honest world's recorded drives (2026-12-07, ``docs/localization_changing_world.md``):
the matched scale of a pair is within 0.03 of that pair's true ratio (median; 90 % within
0.07-0.11); the learned scale is within 0.03 of the drive's true ratio after 10 s in five of six
drives looked at, and within 0.02 after 40 s in all six.

Frames and units: car frame (x forward, y left, origin at the rear axle) and lidar frame (the
lidar's mount pose in the car frame); metres, radians, seconds; the scale is dimensionless (1 =
trust the wheels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from mcl.filter.scan_continuity import even_subset
from racecar_sim.settings.validation import check_number, short

__all__ = ["ScanScale", "ScanScaleParams", "lidar_motion", "match_forward_scale", "point_score", "scan_points"]

COARSE_STEPS = (0.04, 0.03, 0.04)
"""The coarse grid's steps: scale, heading (rad), lateral (m); the fine grid's are a quarter, a
third and a half of them."""


@dataclass(frozen=True)
class ScanScaleParams:
    """Settings of the scan-matched forward speed scale (module docstring).

    Attributes:
        spacing: metres of odometry travel between the two scans matched.
        beams: points of the earlier scan matched (evenly spaced).
        low: smallest scale tried (dimensionless).
        high: largest scale tried.
        heading: radians; the matched turn lies within this of the odometry's.
        lateral: metres; the matched sideways motion lies within this of the odometry's.
        tolerance: metres; the width of a point's score (the fine grid; the coarse one doubles it).
        tolerance_per_m: extra metres of width per metre of range.
        min_sharpness: a pair counts when its best coarse score beats every scale 0.08 or more
            away by this (a share of the points, 0-1).
        prior_metres: metres of pairs that the prior scale counts as.
    """

    spacing: float = 0.5
    beams: int = 200
    low: float = 0.8
    high: float = 1.3
    heading: float = 0.3
    lateral: float = 0.08
    tolerance: float = 0.05
    tolerance_per_m: float = 0.01
    min_sharpness: float = 0.0
    prior_metres: float = 2.0

    def __post_init__(self) -> None:
        owner = "ScanScaleParams"
        for name in ("spacing", "heading", "lateral", "tolerance", "low", "high"):
            value = check_number(owner, name, getattr(self, name), low=0.0, low_open=True)
            object.__setattr__(self, name, value)
        for name in ("tolerance_per_m", "min_sharpness", "prior_metres"):
            object.__setattr__(self, name, check_number(owner, name, getattr(self, name), low=0.0))
        object.__setattr__(self, "beams", check_number(owner, "beams", self.beams, low=20, integer=True))
        if self.high - self.low < 2 * COARSE_STEPS[0]:
            raise ValueError(
                f"ScanScaleParams.high = {short(self.high)} must be at least"
                f" {2 * COARSE_STEPS[0]:g} above low ({self.low:g})"
            )


@nb.njit(cache=True)
def point_score(px, py, after, a0, step, motion_x, motion_y, motion_t, max_range, tol, tol_per_m):
    """Mean Gaussian score of the points (px, py) (earlier lidar frame) moved into the later lidar
    frame at (motion_x, motion_y, motion_t) and compared with ``after`` at their bearings; NaN
    under 20 points."""
    c, s = math.cos(motion_t), math.sin(motion_t)
    total, count = 0.0, 0
    for b in range(px.shape[0]):
        dx, dy = px[b] - motion_x, py[b] - motion_y
        qx, qy = c * dx + s * dy, -s * dx + c * dy
        rho = math.hypot(qx, qy)
        if rho >= max_range:
            continue
        j = int(round((math.atan2(qy, qx) - a0) / step))
        if j < 0 or j >= after.shape[0]:
            continue
        z = after[j]
        if not z < max_range:  # no return (or NaN)
            continue
        width = tol + tol_per_m * rho
        diff = z - rho
        if diff < -3.0 * width:  # seen well short: hidden behind something
            continue
        total += math.exp(-0.5 * (diff / width) ** 2)
        count += 1
    return total / count if count >= 20 else np.nan


@nb.njit(cache=True)
def scan_points(before, before_angles, after_angles, max_range):
    """The earlier scan's returns as points (x, y) in its lidar frame (metres; no-returns left
    out), and the later scan's first bearing and bearing step (radians): what `point_score`
    takes."""
    keep = np.zeros(before.shape[0], dtype=np.bool_)
    for b in range(before.shape[0]):
        keep[b] = before[b] < max_range
    r, a = before[keep], before_angles[keep]
    a0 = after_angles[0]
    step = (after_angles[-1] - a0) / (after_angles.shape[0] - 1)
    return r * np.cos(a), r * np.sin(a), a0, step


@nb.njit(cache=True)
def lidar_motion(car_x, car_y, car_t, mount):
    """The later lidar pose in the earlier lidar frame: mount⁻¹ ∘ car ∘ mount."""
    c, s = math.cos(car_t), math.sin(car_t)
    dx = car_x + c * mount[0] - s * mount[1] - mount[0]
    dy = car_y + s * mount[0] + c * mount[1] - mount[1]
    cm, sm = math.cos(mount[2]), math.sin(mount[2])
    return cm * dx + sm * dy, -sm * dx + cm * dy, car_t


@nb.njit(cache=True)
def _grid(px, py, after, a0, step, odometry, mount, max_range, tol, tol_per_m,
          s0, ns, ds, t0, nt, dt, y0, ny, dy, profile):  # fmt: skip
    best, bi, bj, bk = -1.0, 0, 0, 0
    for i in range(ns):
        for j in range(nt):
            for k in range(ny):
                car_x = odometry[0] * (s0 + ds * i)
                car_t = odometry[2] + t0 + dt * j
                mx, my, mt = lidar_motion(car_x, odometry[1] + y0 + dy * k, car_t, mount)
                value = point_score(px, py, after, a0, step, mx, my, mt, max_range, tol, tol_per_m)
                if value == value:
                    if value > profile[i]:
                        profile[i] = value
                    if value > best:
                        best, bi, bj, bk = value, i, j, k
    return best, s0 + ds * bi, t0 + dt * bj, y0 + dy * bk


@nb.njit(cache=True)
def match_forward_scale(before, before_angles, after, after_angles, odometry, mount, max_range,
                        low, high, heading, lateral, tolerance, tolerance_per_m):  # fmt: skip
    """The forward scale that best matches two scans (module docstring).

    The result is ``(scale, score, sharpness)``: the best scale, its fine score (a share of the
    points, 0-1) and how much the best coarse score beats every scale 0.08 or more away; NaNs
    when too few points could be compared (on the coarse grid, or on the fine one, whose narrower
    width counts more of them as hidden) or the best coarse scale is ``low`` or the highest tried
    (the motion lies outside the grid: a car pinned while its wheels spin). The fine grid spans
    one coarse step either side of the coarse best, so from the second coarse point it may end on
    ``low`` or ``high`` itself (27 of the 15 782 matches of the honest and ideal recorded drives,
    2026-12-07); such a scale counts.

    Args:
        before (np.ndarray): (K,) ranges of the earlier scan, metres (``max_range`` or more, or
            NaN: no return).
        before_angles (np.ndarray): (K,) their bearings in the lidar frame, radians.
        after (np.ndarray): (N,) ranges of the later scan, metres.
        after_angles (np.ndarray): (N,) its bearings, evenly spaced and ascending, radians.
        odometry (np.ndarray): the car's motion between the scans by its odometry, in the earlier
            car frame [x m, y m, theta rad].
        mount (np.ndarray): the lidar's pose in the car frame [x m, y m, theta rad].
        max_range (float): metres.
        low (float): smallest scale tried.
        high (float): largest scale tried.
        heading (float): radians the turn may differ from the odometry's.
        lateral (float): metres the sideways motion may differ from the odometry's.
        tolerance (float): metres of score width (fine grid).
        tolerance_per_m (float): extra metres of width per metre of range.
    """
    px, py, a0, step = scan_points(before, before_angles, after_angles, max_range)
    ds, dt, dy = COARSE_STEPS
    ns = int(math.floor((high - low) / ds + 1e-9)) + 1
    nt = 2 * int(math.floor(heading / dt + 1e-9)) + 1
    ny = 2 * int(math.floor(lateral / dy + 1e-9)) + 1
    profile = np.full(ns, -1.0)
    best, scale, turn, side = _grid(px, py, after, a0, step, odometry, mount, max_range,
                                    2.0 * tolerance, tolerance_per_m, low, ns, ds,
                                    -dt * (nt // 2), nt, dt, -dy * (ny // 2), ny, dy, profile)  # fmt: skip
    if best < 0.0 or scale < low + 0.5 * ds or scale > low + ds * (ns - 1.5):
        return np.nan, np.nan, np.nan  # nothing to compare, or the best on the grid's edge
    far = -1.0
    for i in range(ns):
        if abs(low + ds * i - scale) >= 2 * ds - 1e-9 and profile[i] > far:
            far = profile[i]
    sharpness = best - max(far, 0.0)
    fine = np.full(9, -1.0)
    odometry_fine = np.array([odometry[0], odometry[1] + side, odometry[2] + turn])
    value, scale, _, _ = _grid(px, py, after, a0, step, odometry_fine, mount, max_range,
                               tolerance, tolerance_per_m, scale - ds, 9, ds / 4,
                               -dt, 7, dt / 3, -dy, 5, dy / 2, fine)  # fmt: skip
    if value < 0.0:  # the fine grid's narrower width left too few points anywhere
        return np.nan, np.nan, np.nan
    return scale, value, sharpness


class ScanScale:
    """The scan-matched forward scale of one car's odometry (module docstring): fed the odometry
    every step (``observe``) and each scan as it comes (``observe_scan``).

    Args:
        params: the settings.
        prior: the scale before any pair (1: the wheels as read; a calibration's scale).

    Attributes:
        scale: the scale now (dimensionless; ``prior`` at the start).
        pairs_used: pairs of scans that counted.
        pairs_matched: pairs of scans matched.
    """

    def __init__(self, params: ScanScaleParams | None = None, prior: float = 1.0) -> None:
        self.params = params or ScanScaleParams()
        self.prior = float(prior)
        self.scale = self.prior
        self.pairs_used = 0
        self.pairs_matched = 0
        self._weighted, self._metres = 0.0, 0.0  # sum of scale x odometry metres, and of metres
        self._reference: np.ndarray | None = None  # ranges of the reference scan, metres
        self._reference_angles: np.ndarray | None = None
        self._motion = np.zeros(3)  # odometry since the reference, its car frame [x, y, theta]
        self._path = 0.0  # metres driven since the reference

    def restart(self) -> None:
        """Forget the reference scan (a new episode, a jump); what was learned is kept."""
        self._reference = None

    @property
    def evidence(self) -> tuple[float, float]:
        """What the scale was learned from: (sum of the counted pairs' scales times the metres
        their odometry drove forward, sum of those metres), the prior not included."""
        return self._weighted, self._metres

    def take(self, other: ScanScale) -> None:
        """Start from what ``other`` learned (its scale and pairs), e.g. a search filter beside
        the filter."""
        self.scale, self.pairs_used = other.scale, other.pairs_used
        self._weighted, self._metres = other.evidence

    def observe(self, twist: np.ndarray, dt: float) -> None:
        """Account for one step of odometry ``twist`` [vx m/s, vy m/s, omega rad/s] (car frame,
        as the filter takes it before any scale) held ``dt`` seconds."""
        if self._reference is None:
            return
        vx, vy, omega = float(twist[0]), float(twist[1]), float(twist[2])
        theta = self._motion[2] + 0.5 * omega * dt
        c, s = math.cos(theta), math.sin(theta)
        self._motion[0] += (vx * c - vy * s) * dt
        self._motion[1] += (vx * s + vy * c) * dt
        self._motion[2] += omega * dt
        self._path += math.hypot(vx, vy) * dt

    def observe_scan(
        self, ranges: np.ndarray, angles: np.ndarray, mount: np.ndarray, max_range: float
    ) -> bool:
        """A new scan (``ranges`` metres at ``angles`` radians, lidar frame, evenly spaced and
        ascending; the lidar's ``mount`` pose in the car frame): matched to the reference once
        the odometry has driven ``spacing`` metres since it, then the new reference. Whether the
        scale changed."""
        p = self.params
        z = np.asarray(ranges, dtype=np.float64).reshape(-1)
        if self._reference is None or z.size != self._reference.size:
            self._new_reference(z, angles)
            return False
        if self._path < p.spacing:
            return False
        changed = False
        if abs(self._motion[0]) >= 0.5 * self._path:  # mostly straight: the scale is what counts
            idx = even_subset(z.size, p.beams)
            scale, _, sharpness = match_forward_scale(
                self._reference[idx], self._reference_angles[idx], z,
                np.asarray(angles, dtype=np.float64), self._motion.copy(),
                np.asarray(mount, dtype=np.float64), float(max_range), p.low, p.high,
                p.heading, p.lateral, p.tolerance, p.tolerance_per_m,
            )  # fmt: skip
            self.pairs_matched += 1
            if sharpness >= p.min_sharpness:  # NaN (too few points) never counts
                self.pairs_used += 1
                travel = abs(float(self._motion[0]))  # metres the odometry drove forward
                self._weighted += float(scale) * travel
                self._metres += travel
                prior = p.prior_metres
                self.scale = (self._weighted + self.prior * prior) / (self._metres + prior)
                changed = True
        self._new_reference(z, angles)
        return changed

    def _new_reference(self, ranges: np.ndarray, angles: np.ndarray) -> None:
        self._reference = ranges.copy()
        self._reference_angles = np.asarray(angles, dtype=np.float64).copy()
        self._motion[:] = 0.0
        self._path = 0.0
