"""The range_libc peer: a kctess5-style MCL update on range_libc's giant lookup table (GLT).

range_libc (Walsh & Karaman, the MIT RSS particle filter's caster) is an *optional* peer: it is
imported only here, only when installed (``pip install "cython<3" setuptools wheel`` then
``pip install --no-build-isolation pyrangelibc-danieldugas``); `available()` says whether it is.
None of its code is copied here; this module calls its Python API.

Frames. range_libc's ``PyOMap(array)`` reads ``array[y, x]`` and casts in that array's pixel frame:
``x`` along columns, ``y`` along rows, heading 0 = +x, pi/2 = +y, ranges in pixels. We hand it the
occupancy grid with row 0 at the *bottom* (the map frame's v axis up), so a world pose becomes
``(u / res, v / res, theta - yaw)`` with ``(u, v)`` the map-frame metres of
[`world_to_map()`][racecar_sim.maps.OccupancyMap.world_to_map] (the Stata basement's origin yaw 3.14 rotates
the heading, the grid stays as is). `accuracy()` checks this against the exact caster.

The PyPI build (``pyrangelibc-danieldugas`` 0.0.2) compiles range_libc without its ROS helpers:
``calc_range_repeat_angles`` and ``eval_sensor_model`` are empty (they leave their output arrays
untouched), so the update builds its (N K, 3) queries with numpy and calls ``calc_range_many`` as
kctess5's ``particle_filter.py`` does in its ``calc_range_many`` variant, and evaluates the sensor
table with a numba kernel doing what range_libc's C++ ``eval_sensor_model`` does (product over beams
of ``table[int(z), int(d)]``), so the peer is measured at its best rather than with numpy indexing.
"""

from __future__ import annotations

import importlib.util
import math
import statistics
import time

import numba as nb
import numpy as np

from mcl.filter.sensor_model import SensorModelParams, beam_table
from racecar_sim.maps import OccupancyMap

__all__ = [
    "INSTALL_HINT",
    "THETA_DISC",
    "GltUpdate",
    "accuracy",
    "available",
    "compare",
    "pixel_poses",
    "range_libc_omap",
]

THETA_DISC = 112
"""GLT heading bins: kctess5's particle filter default (``theta_discretization``)."""

INSTALL_HINT = (
    'range_libc is not installed: .venv/bin/pip install "cython<3" setuptools wheel && '
    ".venv/bin/pip install --no-build-isolation pyrangelibc-danieldugas"
)

STAGES = ("predict", "cast", "weigh", "resample", "estimate")


_ROUND_PAUSE_S = 0.03
"""Seconds of pause after each round of timed updates, as between a lidar's scans (see
`compare()`)."""


def available() -> bool:
    """Whether ``range_libc`` can be imported."""
    return importlib.util.find_spec("range_libc") is not None


def range_libc_omap(grid: OccupancyMap):
    """A ``range_libc.PyOMap`` of ``grid``'s occupied cells (unknown counts as occupied), row 0 at
    the bottom (see the module docstring)."""
    import range_libc

    return range_libc.PyOMap(np.ascontiguousarray(grid.occupied[::-1]).astype(bool))


def pixel_poses(grid: OccupancyMap, poses: np.ndarray) -> np.ndarray:
    """(N, 3) world poses -> float64 range_libc pixel poses ``[x px, y px, heading rad]``."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    uv = grid.world_to_map(poses[:, :2]) / grid.resolution
    return np.column_stack([uv, poses[:, 2] - grid.yaw])


def _queries(px: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(N K, 3) float32 queries: each pixel pose repeated for every beam angle (kctess5's way)."""
    n, k = px.shape[0], angles.shape[0]
    q = np.empty((n * k, 3), dtype=np.float32)
    q[:, 0] = np.repeat(px[:, 0], k)
    q[:, 1] = np.repeat(px[:, 1], k)
    q[:, 2] = np.repeat(px[:, 2], k)
    q[:, 2] += np.tile(angles, n)
    return q


@nb.njit(cache=True)
def _eval_sensor_model(obs_px, ranges_px, table, out):
    """range_libc's ``eval_sensor_model``: out[i] = prod_j table[int(z_j), int(d_ij)], clamped."""
    n = out.shape[0]
    k = obs_px.shape[0]
    top = table.shape[0] - 1.0
    for i in range(n):
        w = 1.0
        for j in range(k):
            r = min(max(obs_px[j], 0.0), top)
            d = min(max(ranges_px[i * k + j], 0.0), top)
            w *= table[int(r), int(d)]
        out[i] = w


def accuracy(
    grid: OccupancyMap,
    method,
    exact_caster,
    poses: np.ndarray,
    angles: np.ndarray,
) -> np.ndarray:
    """|range_libc range - exact range| (N, K) metres for world ``poses`` and car-frame ``angles``.

    ``method`` is a built range_libc caster (``PyGiantLUTCast``, ``PyRayMarching``, ...);
    ``exact_caster`` a [`racecar_sim.raycast.RayCaster`][racecar_sim.raycast.RayCaster] with method ``"exact"`` whose
    ``max_range`` equals the range_libc caster's max range times the resolution.
    """
    px = pixel_poses(grid, poses)
    q = _queries(px, np.asarray(angles, dtype=np.float64))
    out = np.empty(q.shape[0], dtype=np.float32)
    method.calc_range_many(q, out)
    ours = exact_caster.cast(poses, angles)
    return np.abs(out.reshape(ours.shape).astype(np.float64) * grid.resolution - ours)


class GltUpdate:
    """A kctess5-style particle filter update on range_libc's GLT, one thread.

    Stages (seconds each, returned by `step()`): ``predict`` (odometry composed with Gaussian
    noise in numpy), ``cast`` (queries in numpy + ``calc_range_many``), ``weigh`` (the sensor table
    as range_libc evaluates it, ``** squash``, normalised), ``resample`` (``Generator.choice``, the
    lab's multinomial), ``estimate`` (weighted mean pose, kctess5's ``expected_pose``).

    Args:
        grid: the map.
        params: the beam model (the same table as ours; ``z_max`` pixels of range).
        theta_disc: GLT heading bins.
        rng: the generator for the motion noise and the resampling.
        method: ``"glt"`` (default), ``"rm"`` (ray marching) or ``"cddt"``.
    """

    def __init__(
        self,
        grid: OccupancyMap,
        params: SensorModelParams,
        rng: np.random.Generator,
        theta_disc: int = THETA_DISC,
        method: str = "glt",
    ) -> None:
        import range_libc

        self.grid = grid
        self.params = params
        self.rng = rng
        self.m_per_px = grid.resolution * params.lidar_scale_to_map_scale
        start = time.perf_counter()
        self.omap = range_libc_omap(grid)
        if method == "glt":
            self.caster = range_libc.PyGiantLUTCast(self.omap, float(params.z_max), theta_disc)
        elif method == "cddt":
            self.caster = range_libc.PyCDDTCast(self.omap, float(params.z_max), theta_disc)
        elif method == "rm":
            self.caster = range_libc.PyRayMarching(self.omap, float(params.z_max))
        else:
            raise ValueError(f"method must be glt, cddt or rm, got {method!r}")
        self.build_seconds = time.perf_counter() - start
        self.table = np.ascontiguousarray(beam_table(params))
        self.noise = np.array([0.05, 0.025, 0.1])  # kctess5's motion dispersion x, y, theta

    def step(
        self, particles: np.ndarray, odometry: np.ndarray, scan: np.ndarray, angles: np.ndarray
    ) -> tuple[np.ndarray, dict[str, float]]:
        """One update; returns the resampled particles and the seconds per stage.

        Args:
            particles: (N, 3) world poses.
            odometry: car-frame displacement ``[dx, dy, dtheta]`` (metres, radians).
            scan: (K,) measured ranges (metres) of the beams at ``angles``.
            angles: (K,) car-frame beam angles (radians).
        """
        p = self.params
        n = particles.shape[0]
        t0 = time.perf_counter()
        c, s = np.cos(particles[:, 2]), np.sin(particles[:, 2])
        moved = np.empty_like(particles)
        moved[:, 0] = particles[:, 0] + c * odometry[0] - s * odometry[1]
        moved[:, 1] = particles[:, 1] + s * odometry[0] + c * odometry[1]
        moved[:, 2] = particles[:, 2] + odometry[2]
        moved += self.rng.normal(0.0, self.noise, size=(n, 3))
        t1 = time.perf_counter()
        lidar = moved.copy()
        lidar[:, 0] += p.mount_offset * np.cos(moved[:, 2])
        lidar[:, 1] += p.mount_offset * np.sin(moved[:, 2])
        q = _queries(pixel_poses(self.grid, lidar), angles)
        ranges = np.empty(q.shape[0], dtype=np.float32)
        self.caster.calc_range_many(q, ranges)
        t2 = time.perf_counter()
        weights = np.empty(n)
        _eval_sensor_model(scan / self.m_per_px, ranges, self.table, weights)
        weights **= p.squash_exponent
        weights /= weights.sum()
        t3 = time.perf_counter()
        out = moved[self.rng.choice(n, n, p=weights)]
        t4 = time.perf_counter()
        np.dot(moved.T, weights)
        t5 = time.perf_counter()
        return out, dict(zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True))


# ---------------------------------------------------------------------------- the comparison
def _rss_mb() -> float:
    """Resident memory of this process (MB), from /proc (NaN elsewhere)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def _median_total(runs: list[dict[str, float]]) -> dict[str, float]:
    out = {s: statistics.median(r[s] for r in runs) for s in STAGES}
    out["total"] = statistics.median(sum(r.values()) for r in runs)
    return out


def compare(
    grid: OccupancyMap,
    n_particles: int = 4000,
    n_beams: int = 100,
    updates: int = 20,
    warmup: int = 3,
    seed: int = 0,
    threads: tuple[int, ...] = (1, 2),
    accuracy_poses: int = 1500,
    default_filter: bool = False,
    out=print,
) -> dict[str, float]:
    """Our full MCL update against the kctess5-style GLT update, interleaved in one run.

    Prints (through ``out``) the workload, build time and memory of both tables, the p99 error of
    both casters against our exact caster, and the median ms per stage with the ratios; returns the
    headline numbers. Ours: [`mcl.ParticleFilter`][mcl.ParticleFilter] with the ``lut`` caster (cast and score in
    one pass), resampling every update (the lab's policy, like the peer), on ``threads`` numba
    threads; the peer on its one thread. ``default_filter`` also times, last in each round on one
    thread, the wrapper's per-scan work with the default settings
    ([`DefaultUpdate`][mcl.bench.default_update.DefaultUpdate]) on scans along the odometry's path.
    """
    import numba

    from mcl.bench.mcl import DT, TWIST, mcl_update
    from mcl.filter.motion_model import twist_to_odometry
    from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
    from mcl.filter.sensor_model import SensorModel
    from racecar_sim.raycast import RayCaster, clear_cache
    from racecar_sim.sensors.lidar import Lidar

    rng = np.random.default_rng(seed)
    truth = grid.sample_free_poses(rng, 1, clearance=1.0)[0]
    scan = Lidar(grid).measure(truth, rng).astype(np.float64)
    results: dict[str, float] = {}

    clear_cache()
    rss = _rss_mb()
    start = time.perf_counter()
    ours = SensorModel(grid, SensorModelParams(num_beams_per_particle=n_beams, parallel=False))
    results["ours_build_s"] = time.perf_counter() - start
    assert ours.caster is not None and ours.caster.table is not None
    results["ours_table_mb"] = ours.caster.table.nbytes / 1e6
    rss_ours = _rss_mb()
    peer = GltUpdate(grid, ours.params, np.random.default_rng(seed + 1))
    results["glt_build_s"] = peer.build_seconds
    results["glt_rss_mb"] = _rss_mb() - rss_ours
    out(
        f"workload: {n_particles} particles x {n_beams} beams (of a {scan.size}-beam scan), "
        f"max range {ours.max_range:.2f} m, map {grid.name} {grid.width}x{grid.height} cells at "
        f"{grid.resolution} m, every update resamples"
    )
    out(
        f"tables: ours (lut) {results['ours_build_s']:.2f} s, {results['ours_table_mb']:.0f} MB "
        f"(process grew {rss_ours - rss:.0f} MB); range_libc GLT (theta_disc {THETA_DISC}) "
        f"{results['glt_build_s']:.2f} s, process grew {results['glt_rss_mb']:.0f} MB"
    )

    # Accuracy against the exact caster: the project's standard check (poses uniform over free
    # space, beams over the full turn) and the workload's own cloud and beams.
    exact = RayCaster(grid, ours.max_range, method="exact")
    uniform = grid.sample_free_poses(rng, accuracy_poses, clearance=0.0)
    full_turn = np.linspace(-math.pi, math.pi, 100, endpoint=False)
    angles, _ = ours.observe(scan)
    cloud = truth + rng.normal(0.0, [0.3, 0.3, 0.1], size=(accuracy_poses, 3))
    cloud = cloud[grid.is_free(cloud[:, :2])]
    for label, poses, beams in (("uniform", uniform, full_turn), ("cloud", cloud, angles)):
        ex = exact.cast(poses, beams)
        ours_err = np.abs(ours.caster.cast(poses, beams) - ex)
        glt_err = accuracy(grid, peer.caster, exact, poses, beams)
        results[f"ours_p99_{label}"] = float(np.quantile(ours_err, 0.99))
        results[f"glt_p99_{label}"] = float(np.quantile(glt_err, 0.99))
        out(
            f"error vs exact ({label} poses): ours mean {ours_err.mean():.3f} m p99 "
            f"{results[f'ours_p99_{label}']:.3f} m; GLT mean {glt_err.mean():.3f} m p99 "
            f"{results[f'glt_p99_{label}']:.3f} m"
        )

    # Timing, interleaved: one update of each in turn, medians over `updates`.
    idx, _ = ours.beams_used(scan.size)
    odometry = twist_to_odometry(TWIST, DT)
    filters = {}
    for t in threads:
        sm = SensorModel(grid, SensorModelParams(num_beams_per_particle=n_beams, parallel=t > 1))
        pf = ParticleFilter(
            grid,
            n_particles,
            sensor_model=sm,
            params=ParticleFilterParams(resample_threshold="always"),
            rng=seed,
        )
        pf.initialize(truth, spread=(0.5, 0.5, 0.2))
        filters[t] = pf
    default = None
    if default_filter:
        from mcl.bench.default_update import DefaultUpdate

        try:
            default = DefaultUpdate(grid, filters[min(threads)].sensor_model, n_particles, truth,
                                    TWIST, DT, warmup + updates, (0.5, 0.5, 0.2), seed)  # fmt: skip
        except ValueError as exc:  # the car would drive into a wall before the last scan
            out(f"default filter: skipped ({exc})")
    state = {"p": truth + rng.normal(0.0, [0.5, 0.5, 0.2], size=(n_particles, 3))}
    runs: dict[str, list[dict[str, float]]] = {"glt": [], **{f"ours/{t}": [] for t in threads}}
    cpu: dict[str, list[float]] = {name: [] for name in (*runs, "default")}
    default_runs: list[dict[str, float]] = []
    default_threads = numba.get_num_threads()
    try:
        for k in range(warmup + updates):
            # The peer first, on a quiet machine, and each round ends with a pause, as between
            # scans. (Added when our update used numba's OpenMP threads, which spin about 10 ms
            # after a parallel region and took the second core from the peer; the update now
            # shares work through racecar_sim.raycast.shared_work, whose threads block instead.)
            c = time.process_time()
            state["p"], r = peer.step(state["p"], odometry, scan[idx], angles)
            if k >= warmup:
                runs["glt"].append(r)
                cpu["glt"].append(time.process_time() - c)
            for t, pf in filters.items():
                numba.set_num_threads(min(t, numba.config.NUMBA_NUM_THREADS))
                c = time.process_time()
                r = mcl_update(pf, scan)
                if k >= warmup:
                    runs[f"ours/{t}"].append(r)
                    cpu[f"ours/{t}"].append(time.process_time() - c)
            if default is not None:
                numba.set_num_threads(1)
                c = time.process_time()
                r = default.step()
                if k >= warmup:
                    default_runs.append(r)
                    cpu["default"].append(time.process_time() - c)
            time.sleep(_ROUND_PAUSE_S)
    finally:
        numba.set_num_threads(default_threads)
    med = {name: _median_total(r) for name, r in runs.items()}
    glt_total = med["glt"]["total"]
    glt_cpu = statistics.median(cpu["glt"])
    out(
        "median ms per update (stages; 'cast' = cast + sensor model), ratio = GLT time / time; "
        "cpu = process CPU time (all threads), steadier than wall time on a busy machine"
    )
    out(
        f"{'impl':<12}"
        + "".join(f"{s:>10}" for s in (*STAGES, "total"))
        + f"{'x GLT':>8}{'cpu':>9}{'x GLT':>8}"
    )
    for name, m in med.items():
        label = "GLT (1 thr)" if name == "glt" else f"ours ({name.split('/')[-1]} thr)"
        out(
            f"{label:<12}"
            + "".join(f"{1e3 * m[s]:10.2f}" for s in (*STAGES, "total"))
            + f"{glt_total / m['total']:8.2f}"
            + f"{1e3 * statistics.median(cpu[name]):9.2f}"
            + f"{glt_cpu / statistics.median(cpu[name]):8.2f}"
        )
        results[f"{name}_ms"] = 1e3 * m["total"]
        results[f"{name}_ratio"] = glt_total / m["total"]
        results[f"{name}_cpu_ms"] = 1e3 * statistics.median(cpu[name])
    if default is not None:
        results.update(default.report(default_runs, cpu["default"], glt_total, glt_cpu, out))
    return results
