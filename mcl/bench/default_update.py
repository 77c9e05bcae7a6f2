"""The default filter's per-scan work, for timing against the benchmarks' bare update.

The benchmarks' [`mcl_update()`][mcl.bench.mcl.mcl_update] times the filter's core steps (predict,
the sensor model's evaluation, the weight update, resampling, the mean and covariance) and
resamples after every scan, as the peers do. The single-car wrapper
([`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper]) does more per scan with the
default settings, and what its ``update_s`` times is what [`DefaultUpdate`][mcl.bench.default_update.DefaultUpdate]
times: ``ParticleFilter.predict`` (with the odometry scale learning), the lost flag's odometry,
``ParticleFilter.correct`` (the search decision, the sensor model, the Bayes update, augmented
MCL's averages, resampling only when the effective sample size is at most half the count), the
lost flag's fit and scan continuity ([`LostDetector.observe`][mcl.filter.lost.LostDetector.observe],
as [`correct_with_scan()`][mcl.wrappers.localization.correct_with_scan] calls it) and the estimate.

A fixed scan would raise the lost flag (the cloud drifts away from the one pose that scan fits,
and the scan does not continue itself as the odometry says) and the recovery it asks for would be
timed instead of tracking; so the scans are the simulator's, taken along the odometry's path.

Frames and units: world poses [x, y, theta] of the rear axle (metres, radians); seconds.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable

import numpy as np

from mcl.filter.lost import LostDetector
from mcl.filter.motion_model import twist_to_odometry
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.scan_continuity import compose
from mcl.filter.sensor_model import SensorModel
from mcl.wrappers.localization import LocalizationConfig
from racecar_sim.maps import OccupancyMap
from racecar_sim.sensors.lidar import Lidar

__all__ = ["DEFAULT_STAGES", "DefaultUpdate", "odometry_path"]

DEFAULT_STAGES = ("predict", "correct", "lost", "estimate")
"""Stages of [`DefaultUpdate.step()`][mcl.bench.default_update.DefaultUpdate.step]."""


def odometry_path(start: np.ndarray, twist: np.ndarray, dt: float, n: int) -> np.ndarray:
    """(n, 3) world poses: ``start`` then each one ``twist`` [vx m/s, vy m/s, omega rad/s] held for
    ``dt`` seconds after the one before (the exact arc of
    [`twist_to_odometry()`][mcl.filter.motion_model.twist_to_odometry])."""
    step = twist_to_odometry(twist, dt)
    out = np.empty((n, 3))
    out[0] = start
    for k in range(1, n):  # a loop over the steps of one path, not over particles
        out[k] = compose(out[k - 1], step)
        out[k, 2] = math.remainder(out[k, 2], 2 * math.pi)
    return out


class DefaultUpdate:
    """The wrapper's per-scan work with the default settings on ``n_particles`` (module docstring).

    Args:
        grid: the map (world and filter's).
        sensor_model: the sensor model (may be shared with another filter).
        n_particles: particles.
        start: the first true pose (world); the path runs from it.
        twist: the odometry of every step [vx m/s, vy m/s, omega rad/s].
        dt: seconds per step.
        steps: scans to simulate (one per `step()`).
        spread: standard deviations (m, m, rad) of the initial cloud around ``start``.
        seed: the filter's and the lidar noise's seed.

    Raises:
        ValueError: the path leaves the free space.
    """

    def __init__(
        self,
        grid: OccupancyMap,
        sensor_model: SensorModel,
        n_particles: int,
        start: np.ndarray,
        twist: np.ndarray,
        dt: float,
        steps: int,
        spread: tuple[float, float, float],
        seed: int,
    ) -> None:
        config = LocalizationConfig().with_particles(n_particles)
        self.twist = np.asarray(twist, dtype=np.float64)
        self.dt = float(dt)
        path = odometry_path(np.asarray(start, dtype=np.float64), self.twist, self.dt, steps + 1)
        if not grid.is_free(path[:, :2]).all():
            raise ValueError("the odometry's path from start leaves the free space")
        lidar = Lidar(grid)
        rng = np.random.default_rng(seed)
        self.scans = [lidar.measure(pose, rng).astype(np.float64) for pose in path[1:]]
        self.lidar_max_range = float(lidar.params.max_range)
        self.filter = ParticleFilter(
            grid, sensor_model=sensor_model, params=config.filter, rng=seed
        )
        self.filter.initialize(path[0], spread)
        self.detector = LostDetector(config.lost)
        first = self._scan(lidar.measure(path[0], rng))  # the reset's scan, as the wrapper's
        self.filter.correct(first)
        self.detector.observe(self.filter, first)
        self.steps = 0
        self.resampled = 0
        self.lost = 0
        self.searching = 0

    def _scan(self, scan: np.ndarray) -> np.ndarray:
        """``scan`` with its no-returns at the sensor model's range, as the wrapper passes it."""
        z = np.asarray(scan, dtype=np.float64)
        return np.where(z >= self.lidar_max_range, self.filter.sensor_model.max_range, z)

    def step(self) -> dict[str, float]:
        """The next scan's update; seconds per stage of `DEFAULT_STAGES`."""
        pf, detector = self.filter, self.detector
        scan = self.scans[self.steps]
        t0 = time.perf_counter()
        pf.predict(self.twist, self.dt)
        detector.advance(self.dt, self.twist)
        t1 = time.perf_counter()
        z = self._scan(scan)
        resampled = pf.correct(z)
        t2 = time.perf_counter()
        detector.observe(pf, z)
        t3 = time.perf_counter()
        pf.estimate()
        t4 = time.perf_counter()
        self.steps += 1
        self.resampled += int(resampled)
        self.lost += int(detector.lost)
        self.searching += int(pf.searching)
        return dict(zip(DEFAULT_STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True))

    def report(
        self,
        runs: list[dict[str, float]],
        cpu: list[float],
        glt_s: float,
        glt_cpu_s: float,
        out: Callable[[str], object] = print,
    ) -> dict[str, float]:
        """Print (through ``out``) the median ms per stage of the timed ``runs`` (`step()`'s),
        the wall and ``cpu`` (process seconds per update) ratios against the peer's ``glt_s`` and
        ``glt_cpu_s`` seconds, and what the filter did; returns the headline numbers."""
        med = {s: 1e3 * statistics.median(r[s] for r in runs) for s in DEFAULT_STAGES}
        total = 1e3 * statistics.median(sum(r.values()) for r in runs)
        cpu_ms = 1e3 * statistics.median(cpu)
        out(
            "default filter (1 thr; the wrapper's per-scan work, scans along the odometry's path): "
            + ", ".join(f"{s} {v:.2f}" for s, v in med.items())
            + f", total {total:.2f} ms, x GLT {1e3 * glt_s / total:.2f}; cpu {cpu_ms:.2f} ms, "
            f"x GLT {1e3 * glt_cpu_s / cpu_ms:.2f}; of {self.steps} updates {self.resampled} "
            f"resampled, lost flag up in {self.lost}, searching in {self.searching}"
        )
        return {"default_ms": total, "default_ratio": 1e3 * glt_s / total, "default_cpu_ms": cpu_ms}
