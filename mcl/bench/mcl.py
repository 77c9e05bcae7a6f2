"""Benchmark one full MCL update (predict + correct + resample + estimate) by stage.

On the Stata basement map (``../shared/maps/stata_basement.yaml`` by default) for 1 000, 4 000 and
10 000 particles x 100 beams: the median over ``--updates`` updates after ``--warmup`` updates, split
by stage, for

* ``mcl``: the library (``mcl.ParticleFilter``; particles cast with ``--method``, default ``lut``);
* ``mcl/exact``: the same with the exact caster, to show what the approximate caster buys;
* ``numpy``: a straightforward numpy update measured in the same run: ray marching on the distance
  field, ``table[z, d]`` fancy indexing with a product over beams, ``Generator.choice`` resampling.

The scan comes from the simulator's exact, noisy lidar (``racecar_sim.sensors.lidar.Lidar``), so the model
and the world never share a caster's errors. Every update resamples (the MIT lab's policy, the
worst case). Ratios are against the numpy baseline of the same run.

    .venv/bin/python scripts/bench_mcl.py [--map YAML] [--particles 1000 4000 10000] [--beams 100]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mcl.bench import missing_map, stata_map
from mcl.filter.motion_model import MotionModel, twist_to_odometry
from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
from mcl.filter.sensor_model import SensorModel, SensorModelParams, beam_table
from racecar_sim.maps import OccupancyMap, load_map
from racecar_sim.sensors.lidar import Lidar
from racecar_sim.settings.config import LidarParams

STAGES = ("predict", "cast", "weigh", "resample", "estimate")
TWIST = np.array([2.0, 0.0, 0.5])  # m/s, m/s, rad/s
DT = 0.025  # seconds (40 Hz)


# -------------------------------------------------------------------------- the library
def mcl_update(pf: ParticleFilter, scan: np.ndarray) -> dict[str, float]:
    """One update with the library, stage by stage; seconds per stage.

    ``cast`` is the sensor model's whole scan evaluation (the ``lut`` caster casts and scores in
    one pass), ``weigh`` the Bayes update of the weights (normalisation, effective sample size).
    """
    sm = pf.sensor_model
    t0 = time.perf_counter()
    pf.predict(TWIST, DT)
    t1 = time.perf_counter()
    log_likelihood = sm.log_evaluate(pf.particles, scan)  # the lut casts and scores in one pass
    t2 = time.perf_counter()
    pf.update_weights(log_likelihood)
    t3 = time.perf_counter()
    if pf.needs_resampling():
        pf.resample()
    t4 = time.perf_counter()
    pf.estimate()
    pf.covariance()
    t5 = time.perf_counter()
    return dict(zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True))


# -------------------------------------------------------------------------- numpy baseline
class NumpyBaseline:
    """A plain numpy MCL update: the obvious implementation, for the ratio.

    Casting marches every ray through the distance field (sphere tracing, f1tenth style) until the
    step falls under half a cell; the weight is ``prod(table[z, d]) ** squash`` by fancy indexing;
    resampling is ``rng.choice`` (the MIT lab's multinomial).
    """

    def __init__(self, grid: OccupancyMap, params: SensorModelParams, rng: np.random.Generator):
        self.grid = grid
        self.params = params
        self.rng = rng
        self.table = beam_table(params)
        self.motion = MotionModel()
        self.m_per_px = grid.resolution * params.lidar_scale_to_map_scale
        self.max_range = params.z_max * self.m_per_px
        self.dist = grid.distance

    def cast(self, poses: np.ndarray, angles: np.ndarray) -> np.ndarray:
        g = self.grid
        res, h, w = g.resolution, g.height, g.width
        uv = g.world_to_map(poses[:, :2])
        heading = (poses[:, 2] - g.yaw)[:, None] + angles[None, :]
        du, dv = np.cos(heading).ravel(), np.sin(heading).ravel()
        u0 = np.repeat(uv[:, 0], len(angles))
        v0 = np.repeat(uv[:, 1], len(angles))
        t = np.zeros_like(du)
        active = np.arange(du.size)
        for _ in range(400):
            if active.size == 0:
                break
            col = np.floor((u0[active] + t[active] * du[active]) / res).astype(np.int64)
            row = h - 1 - np.floor((v0[active] + t[active] * dv[active]) / res).astype(np.int64)
            inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
            d = np.zeros(active.size)
            d[inside] = self.dist[row[inside], col[inside]]
            go = (d > 0.5 * res) & (t[active] < self.max_range)
            t[active[go]] += d[go]
            active = active[go]
        return np.minimum(t, self.max_range).reshape(len(poses), len(angles))

    def update(self, particles: np.ndarray, scan: np.ndarray) -> tuple[np.ndarray, dict]:
        p = self.params
        t0 = time.perf_counter()
        odo = twist_to_odometry(TWIST, DT)
        particles = self.motion.evaluate(particles, odo, self.rng)
        t1 = time.perf_counter()
        idx = np.linspace(0, len(scan) - 1, p.num_beams_per_particle).round().astype(int)
        angles = LidarParams().angles[idx]
        off = p.mount_offset
        lidar = particles + off * np.column_stack(
            [np.cos(particles[:, 2]), np.sin(particles[:, 2]), np.zeros(len(particles))]
        )
        expected = self.cast(lidar, angles)
        t2 = time.perf_counter()
        z = np.clip(scan[idx] / self.m_per_px, 0, p.z_max).round().astype(int)
        d = np.clip(expected / self.m_per_px, 0, p.z_max).round().astype(int)
        weights = np.prod(self.table[z[None, :], d], axis=1) ** p.squash_exponent
        weights /= weights.sum()
        t3 = time.perf_counter()
        particles = particles[self.rng.choice(len(particles), len(particles), p=weights)]
        t4 = time.perf_counter()
        np.average(particles[:, :2], axis=0)
        math.atan2(np.sin(particles[:, 2]).mean(), np.cos(particles[:, 2]).mean())
        np.cov(particles.T)
        t5 = time.perf_counter()
        return particles, dict(
            zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True)
        )


# -------------------------------------------------------------------------- driver
def median_stages(
    step: Callable[[], dict[str, float]], updates: int, warmup: int
) -> dict[str, float]:
    """Median seconds per stage and of the total over ``updates`` calls after ``warmup`` calls."""
    for _ in range(warmup):
        step()
    runs = [step() for _ in range(updates)]
    out = {s: statistics.median(r[s] for r in runs) for s in STAGES}
    out["total"] = statistics.median(sum(r.values()) for r in runs)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument(
        "--map", type=Path, default=stata_map(), help="map YAML (default: ../shared's Stata map)"
    )
    parser.add_argument("--particles", type=int, nargs="+", default=[1000, 4000, 10000])
    parser.add_argument("--beams", type=int, default=100, help="beams per particle")
    parser.add_argument("--updates", type=int, default=20, help="timed updates (median)")
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--baseline-updates", type=int, default=5, help="timed numpy updates")
    parser.add_argument("--method", default="lut", help="ray casting method for the particles")
    parser.add_argument(
        "--threads",
        choices=("auto", "one", "all"),
        default="auto",
        help="numba threads for the library's casting and scoring (SensorModelParams.parallel)",
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if not args.map.is_file():
        parser.error(missing_map("--map", args.map))

    grid = load_map(args.map)
    rng = np.random.default_rng(args.seed)
    truth = grid.sample_free_poses(rng, 1, clearance=1.0)[0]
    scan = Lidar(grid).measure(truth, rng).astype(np.float64)
    parallel = {"auto": None, "one": False, "all": True}[args.threads]
    params = SensorModelParams(
        raycast_method=args.method, num_beams_per_particle=args.beams, parallel=parallel
    )

    t = time.perf_counter()
    fast = SensorModel(grid, params)  # builds (or takes from the cache) the caster's table
    build = time.perf_counter() - t
    exact = SensorModel(
        grid,
        SensorModelParams(
            raycast_method="exact", num_beams_per_particle=args.beams, parallel=parallel
        ),
    )
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    print(
        f"{os.cpu_count()} CPUs, load average {load:.1f} before the run (other processes slow it)"
    )
    print(
        f"map {grid.name}: {grid.width}x{grid.height} cells at {grid.resolution} m; "
        f"{args.beams} beams per particle; caster {fast.caster.method!r} built in {build:.2f} s; "
        f"threads {args.threads}; "
        f"median of {args.updates} updates ({args.baseline_updates} for numpy) after {args.warmup}"
    )

    header = (
        f"{'N':>6} {'impl':<10} "
        + " ".join(f"{s:>9}" for s in (*STAGES, "total"))
        + (f" {'Hz':>7} {'ns/(N*M)':>9} {'Mrays/s':>8} {'x numpy':>8}")
    )
    print("times in ms\n" + header)
    for n in args.particles:
        rows = {}
        for name, sm in (("mcl", fast), ("mcl/exact", exact)):
            pf = ParticleFilter(
                grid,
                n,
                sensor_model=sm,
                params=ParticleFilterParams(resample_threshold="always"),
                rng=args.seed,
            )
            pf.initialize(truth, spread=(0.5, 0.5, 0.2))
            rows[name] = median_stages(
                lambda pf=pf: mcl_update(pf, scan), args.updates, args.warmup
            )
        base = NumpyBaseline(grid, params, np.random.default_rng(args.seed))
        state = {"p": truth + rng.normal(0, [0.5, 0.5, 0.2], size=(n, 3))}

        def base_step(base=base, state=state) -> dict[str, float]:
            state["p"], stages = base.update(state["p"], scan)
            return stages

        rows["numpy"] = median_stages(base_step, args.baseline_updates, 1)
        for name, r in rows.items():
            print(
                f"{n:>6} {name:<10} "
                + " ".join(f"{1e3 * r[s]:9.2f}" for s in (*STAGES, "total"))
                + f" {1 / r['total']:7.1f} {1e9 * r['total'] / (n * args.beams):9.1f}"
                + f" {n * args.beams / r['cast'] / 1e6:8.1f}"
                + f" {rows['numpy']['total'] / r['total'] if 'numpy' in rows else math.nan:8.1f}"
            )
    likelihood_field_timing(grid, scan, truth, rng, args.updates, parallel)
    return 0


def likelihood_field_timing(
    grid: OccupancyMap,
    scan: np.ndarray,
    truth: np.ndarray,
    rng: np.random.Generator,
    updates: int,
    parallel: bool | None,
    n: int = 10_000,
) -> float:
    """Scan evaluation: the likelihood field on every beam against the beam model on 100, for
    ``n`` particles around ``truth``, interleaved; prints medians and returns their ratio."""
    beam = SensorModel(grid, SensorModelParams(num_beams_per_particle=100, parallel=parallel))
    field = SensorModel(
        grid,
        SensorModelParams(
            model="likelihood_field", num_beams_per_particle=scan.size, parallel=parallel
        ),
    )
    particles = truth + rng.normal(0.0, [0.3, 0.3, 0.1], size=(n, 3))
    times: dict[str, list[float]] = {"beam": [], "field": []}
    for k in range(updates + 2):
        for name, sm in (("beam", beam), ("field", field)):
            t = time.perf_counter()
            sm.log_evaluate(particles, scan)
            if k >= 2:
                times[name].append(time.perf_counter() - t)
    b, f = (statistics.median(times[k]) for k in ("beam", "field"))
    print(
        f"scan evaluation, {n} particles: likelihood field on all {scan.size} beams "
        f"{1e3 * f:.2f} ms, beam model (lut) on 100 beams {1e3 * b:.2f} ms: field/beam = {f / b:.2f}"
    )
    return f / b


if __name__ == "__main__":
    sys.exit(main())
