"""Replay a recording ([`mcl.io.BagData`][mcl.io.BagData]) through the particle filter, in recorded order.

Each odometry message's twist is held until the next message (or scan) and integrated exactly
([`mcl.filter.motion_model.twist_to_odometry()`][mcl.filter.motion_model.twist_to_odometry]); at every scan the filter moves by the odometry
gathered since the previous scan, held as one constant twist over the time between the scans
([`ParticleFilter.predict()`][mcl.filter.particle_filter.ParticleFilter.predict]: one predict per
scan, as in the simulator, 40 Hz; the learned odometry scale and the standstill check see the
motion as they do online), then weighs the scan. After every scan one row: the base_link
estimate in the map's world frame, the cloud's size and spread, the ambiguity flag and
``scan_fit``, the fraction of valid beams within ``fit_tolerance`` (0.15 m) of an exact cast from
the estimate (a measure of how well the pose explains the scan that needs no ground truth). When the bag carries ``/ground_truth`` (a recorded
simulated drive), also the position and heading error against it.

The filter is `unknown_start_localization()` (`ReplayConfig.localization`, e.g. with
`racecar-sim replay --filter`):
[`mcl.filter.adaptive.AdaptiveParticleFilter`][mcl.filter.adaptive.AdaptiveParticleFilter],
which searches from a global start and tracks once converged, without switching anything.

No-returns (NaN from [`mcl.io.read_bag()`][mcl.io.read_bag]) are given to the beam model as max-range readings by
default (``no_return="max"``, the table's ``p_max`` term, which is what the model's max-range
component stands for): on the Stata basement bags they are the beams whose wall is 10-30 m away,
and dropping them (``"drop"``) loses information that tells the corridors apart.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from mcl.filter.adaptive import AdaptiveParams, AdaptiveParticleFilter
from mcl.filter.angles import wrap_angle
from mcl.filter.augmented import AugmentedParams
from mcl.filter.kld import KLDParams
from mcl.filter.motion_model import MotionModel, compose, odometry_to_twist, twist_to_odometry
from mcl.filter.params import ParticleFilterParams
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from mcl.io.bag_reader import BagData
from mcl.wrappers.localization import TRACKING_INIT_SPREAD, LocalizationConfig
from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import RayCaster

__all__ = [
    "COLUMNS",
    "FIT_WINDOW_S",
    "FOUND_SD",
    "GOOD_FIT",
    "NO_RETURN",
    "ReplayConfig",
    "ReplayResult",
    "replay",
    "unknown_start_localization",
]

COLUMNS: tuple[str, ...] = (
    "time",
    "x",
    "y",
    "theta",
    "n_particles",
    "position_sd",
    "heading_sd",
    "ambiguous",
    "scan_fit",
)
"""Columns of `ReplayResult.rows` and of trajectory.csv."""

NO_RETURN: tuple[str, ...] = ("max", "drop")

GOOD_FIT = 0.6
"""A replay has found the car once ``scan_fit`` averages at least this over `FIT_WINDOW_S`
while the cloud is tight (position sd < `FOUND_SD` m). Tracking on the right map fits
0.80-0.92 (the Stata bags, 2026-12-02; 0.52-0.56 while bag 2 waits among unmapped furniture, for a
second or two); the wrong map (bag 1 on ``office``) fits at most 0.39 over any second, with the
cloud tight on a wrong pose."""
FIT_WINDOW_S = 1.0
"""Seconds of scans `GOOD_FIT` is averaged over."""
FOUND_SD = 0.5
"""Metres of position sd below which the cloud counts as tight (one pose, not a search)."""


def unknown_start_localization() -> LocalizationConfig:
    """The one filter for an unknown start on real scans (module docstring of `mcl.filter.adaptive`).

    Global start with 300 particles per m² of free floor (capped at 300 000), KLD-sampling (at
    most 20 000; 5 000 at least while searching, 1 000 once tracking), augmented MCL (0.001, 0.1),
    the lab's beam model (squash 1/2.2 while tracking, 0.05 while searching) on one numba thread,
    and `AdaptiveParams` (searching, then tracking).
    """
    return LocalizationConfig(
        init="global",
        sensor=SensorModelParams(parallel=False),
        filter=ParticleFilterParams(
            n_particles=1000,
            global_density=300.0,
            global_max_particles=300_000,
            augmented=AugmentedParams(alpha_slow=0.001, alpha_fast=0.1),
            kld=KLDParams(enabled=True, epsilon=0.02, min_particles=1000, max_particles=20_000),
        ),
        adaptive=AdaptiveParams(),
    )


@dataclass(frozen=True)
class ReplayConfig:
    """How to replay a bag.

    Attributes:
        init: ``"global"`` (particles over the whole map) or a base_link pose (x m, y m, theta rad)
            in the map's world frame, spread by ``init_spread``.
        init_spread: standard deviations (m, m, rad) around a given start pose.
        seed: the filter's random seed.
        no_return: ``"max"`` (no-returns weigh as max-range readings) or ``"drop"``.
        fit_tolerance: metres, a beam within this of the exact cast counts in ``scan_fit``.
        localization: the filter (default `unknown_start_localization()`); without
            ``adaptive`` settings it is a plain [`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter].
    """

    init: str | tuple[float, float, float] = "global"
    init_spread: tuple[float, float, float] = TRACKING_INIT_SPREAD
    seed: int = 0
    no_return: str = "max"
    fit_tolerance: float = 0.15
    localization: LocalizationConfig = field(default_factory=lambda: unknown_start_localization())

    def __post_init__(self) -> None:
        if isinstance(self.init, str):
            if self.init != "global":
                raise ValueError(f"ReplayConfig.init = {self.init!r}: 'global' or (x, y, theta)")
        else:
            pose = tuple(float(v) for v in self.init)
            if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
                raise ValueError(f"ReplayConfig.init = {self.init!r}: three finite numbers")
            object.__setattr__(self, "init", pose)
        if self.no_return not in NO_RETURN:
            raise ValueError(f"ReplayConfig.no_return = {self.no_return!r}: one of {NO_RETURN}")
        if not (self.fit_tolerance > 0 and math.isfinite(self.fit_tolerance)):
            raise ValueError(f"ReplayConfig.fit_tolerance = {self.fit_tolerance!r} must be > 0")


@dataclass
class ReplayResult:
    """What `replay()` produced.

    Attributes:
        rows: (S, len(COLUMNS)) one row per scan (see `COLUMNS`).
        particles: per scan, a subsample (at most 300) of the particles (for the video).
        wall_time: wall-clock seconds of the whole replay: the filter's setup, then every scan's
            update and ``scan_fit`` (not reading the bag, not writing the outputs).
        setup_time: the part of ``wall_time`` spent building the filter: the map's lookup table
            (once per process and map) and the start's particles (236 k on the Stata floor).
        duration: seconds of recording. position_error, heading_error: (S,) against
            ``/ground_truth`` (None without it).
        data: the bag that was replayed.
    """

    rows: np.ndarray
    particles: list[np.ndarray]
    wall_time: float
    duration: float
    data: BagData
    position_error: np.ndarray | None = None
    heading_error: np.ndarray | None = None
    setup_time: float = 0.0

    def column(self, name: str) -> np.ndarray:
        """One column of `rows` by name."""
        return self.rows[:, COLUMNS.index(name)]

    @property
    def real_time_factor(self) -> float:
        """Seconds of recording per second of wall time (> 1: faster than real time)."""
        return self.duration / self.wall_time if self.wall_time > 0 else math.inf

    def _windows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per scan ``i``: the end (exclusive) of the `FIT_WINDOW_S` of scans starting at it,
        whether that window is whole (not cut by the bag's end), and its mean ``scan_fit``."""
        t = self.column("time")
        fit = np.nan_to_num(self.column("scan_fit"), nan=0.0)
        end = np.searchsorted(t, t + FIT_WINDOW_S, side="right")  # window i: scans [i, end)
        whole = t[end - 1] - t >= 0.9 * FIT_WINDOW_S
        fit_sum = np.concatenate([[0.0], np.cumsum(fit)])
        return end, whole, (fit_sum[end] - fit_sum[:-1]) / (end - np.arange(len(t)))

    def found_at(self) -> float | None:
        """Seconds since the bag's start when the filter had found the car: the first scan fitting
        at least `GOOD_FIT` in the first `FIT_WINDOW_S` of scans in which ``scan_fit``
        averaged at least that with the cloud tight throughout (position sd < `FOUND_SD`
        m); None when that never happened (a wrong map, frame or
        start: the estimate then explains the scans no better than chance)."""
        if len(self.rows) == 0:
            return None
        end, whole, mean_fit = self._windows()
        loose = np.concatenate([[0], np.cumsum(self.column("position_sd") >= FOUND_SD)])
        ok = whole & (loose[end] == loose[:-1]) & (mean_fit >= GOOD_FIT)
        if not ok.any():
            return None
        first = int(np.argmax(ok))
        fits = np.nan_to_num(self.column("scan_fit")[first : end[first]], nan=0.0) >= GOOD_FIT
        return float(self.column("time")[first + int(np.argmax(fits))])

    def best_fit(self) -> float:
        """The highest ``scan_fit`` averaged over any whole `FIT_WINDOW_S` of scans (0 when
        the bag is shorter than that)."""
        if len(self.rows) == 0:
            return 0.0
        _, whole, mean_fit = self._windows()
        return float(mean_fit[whole].max()) if whole.any() else 0.0

    def not_found_warning(self) -> str | None:
        """One line saying that the filter never found the car (None when it did)."""
        if self.found_at() is not None:
            return None
        return (
            f"the filter never fitted the scans to the map (scan_fit at most "
            f"{self.best_fit():.2f} over any {FIT_WINDOW_S:g} s, {GOOD_FIT:g} once found): a wrong "
            "map, frame or start (--map, --init)? trajectory.png shows the estimate as not found"
        )

    def summary(self) -> str:
        """A few lines: duration, scans, real-time factor, scan_fit, when the car was found,
        errors when known."""
        fit = self.column("scan_fit")
        last = self.rows[-1]
        lines = [
            f"replayed {self.data.path.name}: {self.duration:.1f} s, {len(self.rows)} scans in "
            f"{self.wall_time:.1f} s of wall time (real-time factor {self.real_time_factor:.2f}, "
            f"{self.setup_time:.1f} s of it the filter's setup: the map's lookup table and the "
            "start)",
            f"scan_fit: mean {np.nanmean(fit):.3f}, last second "
            f"{np.nanmean(fit[self.column('time') >= self.duration - 1.0]):.3f}; final pose "
            f"({last[1]:.2f}, {last[2]:.2f}, {last[3]:.2f}), {int(last[4])} particles, "
            f"position sd {last[5]:.3f} m",
        ]
        found_at = self.found_at()
        if found_at is not None:
            lines.append(
                f"found the car at {found_at:.2f} s (scan_fit >= {GOOD_FIT:g} over "
                f"{FIT_WINDOW_S:g} s, position sd < {FOUND_SD:g} m)"
            )
        if self.position_error is not None and self.heading_error is not None:
            e = self.position_error
            lines.append(
                f"error vs /ground_truth: position mean {np.mean(e):.3f} m, median "
                f"{np.median(e):.3f} m, p95 {np.percentile(e, 95):.3f} m, max {np.max(e):.3f} m; "
                f"heading mean |error| {math.degrees(np.mean(np.abs(self.heading_error))):.2f} deg"
            )
        return "\n".join(lines)


def scan_fit(
    caster: RayCaster,
    pose: np.ndarray,
    ranges: np.ndarray,
    angles: np.ndarray,
    mount_offset: float,
    tolerance: float = 0.15,
) -> float:
    """Fraction of the valid (finite) beams within ``tolerance`` metres of an exact cast from the
    lidar of a base_link ``pose``; NaN when no beam is valid."""
    ok = np.isfinite(ranges)
    if not ok.any():
        return math.nan
    x, y, th = (float(v) for v in pose)
    lidar = np.array([x + mount_offset * math.cos(th), y + mount_offset * math.sin(th), th])
    expected = caster.cast(lidar, angles[ok])[0]
    return float(np.mean(np.abs(expected - ranges[ok]) <= tolerance))


def build_filter(
    occupancy_map: OccupancyMap, data: BagData, config: ReplayConfig
) -> ParticleFilter:
    """The filter of ``config`` on the bag's beams and mount, initialised."""
    loc = config.localization
    sensor = SensorModel(
        occupancy_map,
        replace(loc.sensor, mount_offset=data.mount_offset),
        beam_angles=data.angles,
    )
    kwargs = {} if loc.adaptive is None else {"adaptive": loc.adaptive}
    cls = ParticleFilter if loc.adaptive is None else AdaptiveParticleFilter
    pf = cls(
        occupancy_map,
        motion_model=MotionModel(loc.motion),
        sensor_model=sensor,
        params=loc.filter,
        rng=np.random.default_rng(config.seed),
        **kwargs,
    )
    if config.init == "global":
        pf.initialize_global()
    else:
        pf.initialize(np.asarray(config.init), config.init_spread)
    return pf


def _truth_errors(data: BagData, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    if data.truth is None or data.truth_times is None or data.truth.size == 0:
        return None
    idx = np.clip(np.searchsorted(data.truth_times, rows[:, 0], side="right") - 1, 0, None)
    truth = data.truth[idx]
    pos = np.hypot(rows[:, 1] - truth[:, 0], rows[:, 2] - truth[:, 1])
    head = np.abs(wrap_angle(rows[:, 3] - truth[:, 2]))
    return pos, head


def replay(
    data: BagData,
    occupancy_map: OccupancyMap,
    config: ReplayConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    on_scan: Callable[[int, float, np.ndarray, ParticleFilter], None] | None = None,
) -> ReplayResult:
    """Run the filter over the bag (module docstring); ``progress(i, n)`` after each scan, and
    ``on_scan(i, t, moved, pf)`` after its correction: ``t`` its time (s), ``moved`` the odometry's
    motion since the scan before (car frame, m, m, rad), ``pf`` the filter (e.g.
    [`mcl.io.replay_stream.ReplayStream`][mcl.io.replay_stream.ReplayStream], the live view)."""
    config = config if config is not None else ReplayConfig()
    caster = RayCaster(occupancy_map, max(float(data.range_max), 1.0), method="exact")
    start = time.perf_counter()
    pf = build_filter(occupancy_map, data, config)
    setup = time.perf_counter() - start
    no_return_range = pf.sensor_model.max_range * 2.0
    n = data.n_scans
    rows = np.full((n, len(COLUMNS)), np.nan)
    particles: list[np.ndarray] = []
    odom_t, odom_tw = data.odom_times, data.odom_twist
    k = 0  # next odometry message
    twist: np.ndarray | None = None
    t_last = 0.0
    # the scan before (s); the first scan's motion runs from the first odometry message
    t_prev = min((float(t) for t in (*data.scan_times[:1], *odom_t[:1])), default=0.0)
    moved = np.zeros(3)
    for i in range(n):
        t_scan = float(data.scan_times[i])
        while k < odom_t.size and odom_t[k] <= t_scan:
            if twist is not None:
                moved = compose(moved[None], twist_to_odometry(twist, odom_t[k] - t_last))[0]
            twist, t_last = odom_tw[k], float(odom_t[k])
            k += 1
        if twist is not None:
            moved = compose(moved[None], twist_to_odometry(twist, t_scan - t_last))[0]
            t_last = t_scan
        if t_scan > t_prev:  # as one twist held since the scan before, as online
            pf.predict(odometry_to_twist(moved, t_scan - t_prev), t_scan - t_prev)
        step, moved, t_prev = moved, np.zeros(3), t_scan
        scan = data.scans[i]
        if config.no_return == "max":
            scan = np.where(np.isnan(scan), no_return_range, scan)
        pf.correct(scan)
        est = pf.estimate()
        unc = pf.uncertainty()
        fit = scan_fit(
            caster, est, data.scans[i], data.angles, data.mount_offset, config.fit_tolerance
        )
        rows[i] = (
            t_scan,
            est[0],
            est[1],
            est[2],
            pf.n_particles,
            unc.position_sd,
            unc.heading_sd,
            float(unc.ambiguous),
            fit,
        )
        p = pf.particles
        particles.append(p[:: max(1, math.ceil(len(p) / 300))].copy())
        if on_scan is not None:
            on_scan(i, t_scan, step, pf)
        if progress is not None:
            progress(i + 1, n)
    wall = time.perf_counter() - start
    result = ReplayResult(
        rows=rows, particles=particles, wall_time=wall, duration=data.duration, data=data,
        setup_time=setup,
    )  # fmt: skip
    errors = _truth_errors(data, rows)
    if errors is not None:
        result.position_error, result.heading_error = errors
    return result
