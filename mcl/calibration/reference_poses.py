"""Reference poses for a whole recording: one global search, then scan-to-map tracking with the
odometry as the prediction, forwards and backwards from the searched scan.

Also the motion helpers the calibration shares: SE(2) composition, twist integration between two
times (zero-order hold of the odometry's twists), and de-skewing a sweep (each beam of a scanning
lidar is measured at its own time, ``time_increment`` apart, while the car moves).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcl.calibration.scan_match import ScanMatcher
from mcl.io.bag_reader import BagData

__all__ = [
    "ReferencePoses",
    "compose",
    "deskew",
    "integrate_twist",
    "poses_from_trajectory",
    "relative",
    "track_recording",
]


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """SE(2) a ⊕ b for poses (..., 3) [x, y, theta]: b expressed in a's frame, returned in a's parent."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    th = (a[..., 2] + b[..., 2] + np.pi) % (2 * np.pi) - np.pi
    return np.stack([x, y, th], axis=-1)


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """SE(2) a⁻¹ ⊕ b: pose b (..., 3) in the frame of pose a."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    th = (b[..., 2] - a[..., 2] + np.pi) % (2 * np.pi) - np.pi
    return np.stack([c * dx + s * dy, -s * dx + c * dy, th], axis=-1)


def _exp(v: float, w: float, dt: float) -> np.ndarray:
    """Motion (3,) of constant car-frame speed v (m/s) and turn rate w (rad/s) for dt seconds."""
    th = w * dt
    if abs(th) < 1e-9:
        return np.array([v * dt, 0.0, 0.0])
    r = v / w
    return np.array([r * math.sin(th), r * (1 - math.cos(th)), th])


def integrate_twist(times: np.ndarray, twist: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """Car-frame motion (3,) from t0 to t1 (seconds, t1 >= t0) holding each twist (K, 3) [vx, vy,
    omega] from its time until the next (the first one also before its time)."""
    out = np.zeros(3)
    if t1 <= t0:
        return out
    i = max(int(np.searchsorted(times, t0, side="right")) - 1, 0)
    t = t0
    while t < t1:
        t_next = times[i + 1] if i + 1 < len(times) else math.inf
        seg_end = min(t_next, t1)
        out = compose(out, _exp(twist[i, 0], twist[i, 2], seg_end - t))
        t = seg_end
        i += 1
    return out


def deskew(
    ranges: np.ndarray, angles: np.ndarray, dt_beam: float, v: float, w: float, mount: float
) -> tuple[np.ndarray, np.ndarray]:
    """Ranges and angles (B,) as seen from the lidar's pose at the first beam's time.

    Beam i is measured ``i * dt_beam`` seconds after the first while the car (rear axle) moves at
    speed ``v`` (m/s) and turn rate ``w`` (rad/s); the lidar sits ``mount`` metres ahead of the
    axle. Each end point is moved into the first beam's lidar frame; NaN ranges stay NaN.
    """
    t = np.arange(ranges.size) * dt_beam
    th = w * t
    small = np.abs(w) < 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        bx = np.where(small, v * t, v / np.where(small, 1.0, w) * np.sin(th))
        by = np.where(small, 0.0, v / np.where(small, 1.0, w) * (1 - np.cos(th)))
    # lidar motion = mount⁻¹ ⊕ base motion ⊕ mount
    lx = -mount + bx + mount * np.cos(th)
    ly = by + mount * np.sin(th)
    px = lx + ranges * np.cos(angles + th)
    py = ly + ranges * np.sin(angles + th)
    ok = np.isfinite(ranges)
    return np.where(ok, np.hypot(px, py), np.nan), np.where(ok, np.arctan2(py, px), angles)


@dataclass(frozen=True)
class ReferencePoses:
    """Per-scan lidar poses of a recording.

    Attributes:
        lidar: (S, 3) lidar pose [x, y, theta] at each scan's stamp, map world frame.
        base: (S, 3) the base_link (rear axle) pose, ``mount`` metres behind the lidar.
        loss: (S,) mean robust loss of the scan at its pose (lower = better fit).
        fit5, fit15: (S,) fractions of valid beams within 0.05 m / 0.15 m of the exact cast.
        start: index of the scan found by the global search.
        deskewed: whether the sweeps were de-skewed with the odometry.
    """

    lidar: np.ndarray
    base: np.ndarray
    loss: np.ndarray
    fit5: np.ndarray
    fit15: np.ndarray
    start: int
    deskewed: bool


def scan_twist(rec: BagData, k: int) -> tuple[float, float]:
    """(v m/s, omega rad/s) of the odometry message last before scan ``k``'s stamp."""
    i = max(int(np.searchsorted(rec.odom_stamps, rec.scan_stamps[k], side="right")) - 1, 0)
    return float(rec.odom_twist[i, 0]), float(rec.odom_twist[i, 2])


def scan_beams(
    rec: BagData, k: int, mount: float, use_deskew: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Ranges and angles of scan ``k``, de-skewed to its stamp when ``use_deskew``."""
    if not use_deskew:
        return rec.scans[k], rec.angles
    v, w = scan_twist(rec, k)
    return deskew(rec.scans[k], rec.angles, rec.time_increment, v, w, mount)


def track_recording(
    rec: BagData,
    matcher: ScanMatcher,
    mount: float = 0.275,
    start: int | None = None,
    use_deskew: bool = True,
    start_guess: np.ndarray | None = None,
) -> ReferencePoses:
    """Reference poses of every scan of ``rec``.

    The scan ``start`` (default: the one at a third of the recording) is located by a global
    search (or refined from ``start_guess``, a lidar pose, when given); every other scan is predicted from its neighbour with the odometry and refined.
    """
    n = len(rec.scans)
    start = n // 3 if start is None else start
    mount_pose = np.array([mount, 0.0, 0.0])
    lidar = np.zeros((n, 3))
    loss = np.zeros(n)

    def refine(k: int, guess: np.ndarray, step=(0.05, 0.02)) -> None:
        r, a = scan_beams(rec, k, mount, use_deskew)
        matcher.angles = a
        lidar[k], loss[k] = matcher.refine(guess, r, step)

    r0, a0 = scan_beams(rec, start, mount, use_deskew)
    matcher.angles = a0
    if start_guess is None:
        lidar[start], loss[start] = matcher.global_search(r0)
    else:
        lidar[start], loss[start] = matcher.refine(np.asarray(start_guess, float), r0, (0.1, 0.05))
    for order in (range(start + 1, n), range(start - 1, -1, -1)):
        for k in order:
            prev = k - 1 if k > start else k + 1
            t_a, t_b = sorted((rec.scan_stamps[prev], rec.scan_stamps[k]))
            motion = integrate_twist(rec.odom_stamps, rec.odom_twist, t_a, t_b)
            if k < start:
                motion = relative(motion, np.zeros(3))
            base_prev = compose(lidar[prev], relative(mount_pose, np.zeros(3)))
            guess = compose(compose(base_prev, motion), mount_pose)
            refine(k, guess)
    base = compose(lidar, relative(mount_pose, np.zeros(3)))
    fit5 = np.zeros(n)
    fit15 = np.zeros(n)
    for k in range(n):
        r, a = scan_beams(rec, k, mount, use_deskew)
        matcher.angles = a
        res = matcher.residuals(lidar[k], r)
        ok = np.isfinite(res)
        fit5[k] = np.mean(np.abs(res[ok]) < 0.05)
        fit15[k] = np.mean(np.abs(res[ok]) < 0.15)
    matcher.angles = rec.angles
    return ReferencePoses(lidar, base, loss, fit5, fit15, start, use_deskew)


def poses_from_trajectory(
    rec: BagData, matcher: ScanMatcher, path, mount: float = 0.275
) -> ReferencePoses:
    """Reference poses read from a replay's ``trajectory.csv`` (``racecar-sim replay``: one row per
    scan, base_link ``x,y,theta`` in the map frame) instead of scan matching.

    Raises:
        ValueError: the file has no x, y, theta columns or not one row per scan.
    """
    import csv
    from pathlib import Path

    with Path(path).open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or not {"x", "y", "theta"} <= set(rows[0]):
        raise ValueError(f"{path}: expected a trajectory CSV with x, y, theta columns")
    if len(rows) != len(rec.scans):
        raise ValueError(f"{path}: {len(rows)} rows for {len(rec.scans)} scans of {rec.name}")
    base = np.array([[float(r["x"]), float(r["y"]), float(r["theta"])] for r in rows])
    lidar = compose(base, np.array([mount, 0.0, 0.0]))
    fit5 = np.zeros(len(base))
    fit15 = np.zeros(len(base))
    loss = np.zeros(len(base))
    for k in range(len(base)):
        res = matcher.residuals(lidar[k], rec.scans[k])
        ok = np.isfinite(res)
        fit5[k] = np.mean(np.abs(res[ok]) < 0.05)
        fit15[k] = np.mean(np.abs(res[ok]) < 0.15)
        loss[k] = float(matcher.losses(lidar[k][None, :], rec.scans[k])[0])
    return ReferencePoses(lidar, base, loss, fit5, fit15, 0, False)
