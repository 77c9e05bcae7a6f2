"""Whether two consecutive scans agree with the odometry between them: how a filter tells that its
car was carried away (kidnapped) from how it tells that the map is out of date.

A scan's points, moved by the odometry's motion since that scan into the next scan's lidar frame,
should be found again by the next scan: the world does not change between two scans 25 ms apart,
whatever the map says. The *continuity* is the fraction of the earlier scan's points (``beams``
of them, evenly spaced) that the later scan sees within ``tolerance`` metres (plus
``tolerance_per_m`` per metre of range: a small error of the odometry's heading moves far points
more) at the bearing where they should be now. A point that the later scan sees *short* of where
it should be is left out (something now stands in front of it, or the car's own motion hides
it), as is a point outside the later scan's field of view or range. After a kidnap almost
no point is found again (the later scan comes from another place); in a world that is not its
map, or among people and furniture, nearly all are. No map is involved, so the check does not
depend on how out of date the filter's map is.

Frames and units: car frame (x forward, y left, origin at the rear axle) and lidar frame (the
lidar's mount pose in the car frame, given by the sensor model); metres, radians, seconds.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from mcl.filter.motion_model import twist_to_odometry

__all__ = [
    "ScanContinuity",
    "both_ways",
    "compose",
    "even_subset",
    "invert",
    "scan_bearings",
    "scan_continuity",
]


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The pose ``b`` (in ``a``'s frame) expressed in ``a``'s parent frame: ``a ∘ b`` for SE(2)
    poses [x m, y m, theta rad]."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def invert(a: np.ndarray) -> np.ndarray:
    """The inverse SE(2) pose of ``a`` = [x m, y m, theta rad]."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]])


def scan_continuity(
    before: np.ndarray,
    before_angles: np.ndarray,
    after: np.ndarray,
    after_angles: np.ndarray,
    motion: np.ndarray,
    max_range: float,
    tolerance: float,
    tolerance_per_m: float,
) -> float:
    """Fraction of ``before``'s points that ``after`` finds again (module docstring); NaN when
    fewer than 10 points count.

    Args:
        before: (K,) ranges of the earlier scan (metres; non-finite or at ``max_range``: no point).
        before_angles: (K,) their bearings in the earlier lidar frame (radians).
        after: (N,) ranges of the later scan (metres).
        after_angles: (N,) its bearings, evenly spaced, ascending (radians).
        motion: the later lidar pose in the earlier lidar frame [x m, y m, theta rad].
        max_range: metres; ranges at or beyond it are no return.
        tolerance: metres.
        tolerance_per_m: extra metres of tolerance per metre of range.
    """
    r = np.asarray(before, dtype=np.float64)
    ok = np.isfinite(r) & (r < max_range)
    if np.count_nonzero(ok) < 10 or after_angles.size < 2:
        return math.nan
    r, a = r[ok], np.asarray(before_angles, dtype=np.float64)[ok]
    c, s = math.cos(motion[2]), math.sin(motion[2])
    px, py = r * np.cos(a) - motion[0], r * np.sin(a) - motion[1]
    qx, qy = c * px + s * py, -s * px + c * py  # in the later lidar frame
    rho = np.hypot(qx, qy)
    a0 = float(after_angles[0])
    step = (float(after_angles[-1]) - a0) / (after_angles.size - 1)
    j = np.rint((np.arctan2(qy, qx) - a0) / step).astype(np.int64)
    seen = (j >= 0) & (j < after_angles.size)
    j, rho = j[seen], rho[seen]
    z = np.asarray(after, dtype=np.float64)[j]
    seen = np.isfinite(z) & (z < max_range) & (rho < max_range)
    z, rho = z[seen], rho[seen]
    diff = z - rho
    tol = tolerance + tolerance_per_m * rho
    counted = diff >= -tol  # a point seen short of where it should be is hidden: left out
    n = int(np.count_nonzero(counted))
    if n < 10:
        return math.nan
    return float(np.count_nonzero(diff[counted] <= tol[counted]) / n)


def scan_bearings(sensor_model: Any, n: int) -> np.ndarray:
    """(n,) the bearings of a scan's ``n`` beams in the lidar frame (radians): the sensor model's
    own when it has them for ``n`` beams, else evenly over its field of view."""
    angles = sensor_model.beam_angles
    if angles is not None and angles.size == n:
        return np.asarray(angles, dtype=np.float64)
    fov = float(sensor_model.params.fov)
    return np.linspace(-fov / 2, fov / 2, n) if n > 1 else np.zeros(1)


@functools.lru_cache(maxsize=16)
def even_subset(n: int, k: int) -> np.ndarray:
    """Indices of ``min(k, n)`` evenly spaced beams of ``n`` (read-only)."""
    idx = np.unique(np.rint(np.linspace(0, n - 1, min(k, n))).astype(np.int64))
    idx.setflags(write=False)
    return idx


def both_ways(
    before: np.ndarray,
    before_angles: np.ndarray,
    after: np.ndarray,
    after_angles: np.ndarray,
    motion: np.ndarray,
    beams: int,
    max_range: float,
    tolerance: float,
    tolerance_per_m: float,
) -> float:
    """The smaller of [scan_continuity][mcl.filter.scan_continuity.scan_continuity] one way
    (``beams`` evenly spaced points of ``before`` found in ``after``) and the other (``after``'s
    in ``before``, by the inverse ``motion``): a point hidden one way is a point missing the other
    way. ``motion`` is the later lidar pose in the earlier lidar frame [x m, y m, theta rad]; NaN
    when too few points count either way."""
    args = (max_range, tolerance, tolerance_per_m)
    ib, ia = even_subset(before.size, beams), even_subset(after.size, beams)
    forward = scan_continuity(before[ib], before_angles[ib], after, after_angles, motion, *args)
    backward = scan_continuity(after[ia], after_angles[ia], before, before_angles,
                               invert(motion), *args)  # fmt: skip
    both = [f for f in (forward, backward) if not math.isnan(f)]
    return min(both) if both else math.nan


class ScanContinuity:
    """The continuity of one car's consecutive scans (module docstring): fed the odometry every
    step and each scan as it comes. Both ways are checked (the earlier scan's points in the later
    scan, and the later's in the earlier), and the smaller fraction counts: a point hidden one way
    is a point missing the other way.

    Args:
        mount: the lidar's pose in the car frame [x m, y m, theta rad].
        max_range: metres; ranges at or beyond it are no return.
        beams: points of each scan compared (evenly spaced).
        tolerance: metres.
        tolerance_per_m: extra metres per metre of range.

    Attributes:
        continuity: the last pair's fraction (NaN before the second scan, or when too few points
            count either way).
    """

    def __init__(
        self,
        mount: np.ndarray,
        max_range: float,
        beams: int = 100,
        tolerance: float = 0.1,
        tolerance_per_m: float = 0.03,
    ) -> None:
        self.mount = np.asarray(mount, dtype=np.float64).reshape(3)
        self.max_range = float(max_range)
        self.beams = int(beams)
        self.tolerance = float(tolerance)
        self.tolerance_per_m = float(tolerance_per_m)
        self.continuity = math.nan
        self._motion = np.zeros(3)  # the car's motion since the last scan, in its frame then
        self._before: tuple[np.ndarray, np.ndarray] | None = None

    def restart(self) -> None:
        """Forget the last scan and the motion since (a new belief)."""
        self.continuity = math.nan
        self._motion = np.zeros(3)
        self._before = None

    def advance(self, odometry: np.ndarray, dt: float) -> None:
        """The car drove the car-frame ``odometry`` twist [vx m/s, vy m/s, omega rad/s] for
        ``dt`` seconds."""
        self._motion = compose(self._motion, twist_to_odometry(odometry, dt))

    def observe(self, scan: np.ndarray, angles: np.ndarray) -> float:
        """Compare ``scan`` (metres, at bearings ``angles`` in radians, evenly spaced, ascending)
        with the last one; returns the continuity (NaN for the first scan)."""
        z = np.asarray(scan, dtype=np.float64).reshape(-1).copy()
        angles = np.asarray(angles, dtype=np.float64).reshape(-1)
        if self._before is not None:
            before, before_angles = self._before
            motion = compose(compose(invert(self.mount), self._motion), self.mount)
            self.continuity = both_ways(
                before, before_angles, z, angles, motion, self.beams, self.max_range,
                self.tolerance, self.tolerance_per_m,
            )  # fmt: skip
        self._before = (z, angles.copy())
        self._motion = np.zeros(3)
        return self.continuity
