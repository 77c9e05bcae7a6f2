"""Benchmark the ray casting methods: rays per second, error vs exact, table build time and memory.

Maps: the Stata basement (``../shared/maps/stata_basement.yaml`` from the repository root; skipped
with a message when absent) and the default bundled map (skipped when not generated yet).
Workloads, poses uniform in free space from a fixed seed:

* ``particles``: 4000 poses x 100 beams over the full turn, max range 10 m;
* ``lidar``: 1 pose x 1080 beams over 270 degrees, max range 30 m, cast for 2000 poses in a row.

Each method is timed as the median of 5 runs after a warm-up run. The baseline, measured in the same
run, is a plain numpy ray marcher (vectorised over rays, no numba): sphere tracing on the map's
distance field with steps of at least half a cell. Ratios are Mrays/s (wall clock) over the
baseline's. ``Mrays/CPU-s`` divides by this process's CPU time instead (summed over numba's
threads): steadier than wall clock when other programs share the cores. Errors are absolute, vs
``"exact"``, over every ray of the workload. The load average is printed before and after.

    .venv/bin/python scripts/bench_raycast.py [--quick] [--map YAML ...]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from mcl.bench import STATA
from racecar_sim.maps import MapError, OccupancyMap, bundled, load_map
from racecar_sim.raycast import METHODS, LutParams, RayCaster

BASELINE = "numpy-march"


# -------------------------------------------------------------------------- numpy baseline
class NumpyMarcher:
    """Plain numpy sphere tracing, vectorised over rays (the benchmark's baseline).

    Every active ray steps by ``max(d - sqrt(2), 0.5)`` cells, ``d`` the distance field (cell
    centre to nearest occupied centre) of the cell it is in, until it lands in an occupied cell or
    off the map; the range is that step's end (at most half a cell long).
    """

    def __init__(self, grid: OccupancyMap, max_range: float) -> None:
        self.grid = grid
        self.max_range = max_range
        res = grid.resolution
        self.step = np.maximum(grid.distance / res - math.sqrt(2.0), 0.5)[::-1].copy()
        self.occ = grid.occupied[::-1].copy()  # row 0 = bottom

    def cast(self, poses: np.ndarray, angles: np.ndarray) -> np.ndarray:
        poses = np.atleast_2d(poses)
        res = self.grid.resolution
        h, w = self.occ.shape
        uv = self.grid.world_to_map(poses[:, :2]) / res
        heading = poses[:, 2:3] - self.grid.yaw + angles[None, :]
        x0 = np.repeat(uv[:, 0], len(angles))
        y0 = np.repeat(uv[:, 1], len(angles))
        dx, dy = np.cos(heading).ravel(), np.sin(heading).ravel()
        max_t = self.max_range / res
        t = np.zeros(x0.shape)
        out = np.full(x0.shape, max_t)
        active = np.arange(x0.size)
        first = True
        while active.size:
            x = x0[active] + t[active] * dx[active]
            y = y0[active] + t[active] * dy[active]
            col = np.floor(x).astype(np.int64)
            row = np.floor(y).astype(np.int64)
            inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
            hit = ~inside
            hit[inside] = self.occ[row[inside], col[inside]]
            out[active[hit]] = 0.0 if first else t[active[hit]]
            first = False
            active, col, row = active[~hit], col[~hit], row[~hit]
            t[active] += self.step[row, col]
            over = t[active] >= max_t
            active = active[~over]
        return out.reshape(len(poses), len(angles)) * res


# -------------------------------------------------------------------------- workloads
@dataclass(frozen=True)
class Workload:
    """Rays cast ``scans`` times: each time ``poses_per_scan`` poses x ``angles``."""

    name: str
    poses: np.ndarray  # (scans * poses_per_scan, 3)
    poses_per_scan: int
    angles: np.ndarray
    max_range: float

    @property
    def rays(self) -> int:
        return len(self.poses) * len(self.angles)

    def run(self, cast: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
        """All ranges (n_poses, n_angles), cast in batches of ``poses_per_scan``."""
        k = self.poses_per_scan
        if k == len(self.poses):
            return cast(self.poses, self.angles)
        return np.concatenate(
            [cast(self.poses[i : i + k], self.angles) for i in range(0, len(self.poses), k)]
        )


def workloads(grid: OccupancyMap, quick: bool, seed: int) -> list[Workload]:
    rng = np.random.default_rng(seed)
    n_particles = 1000 if quick else 4000
    n_scans = 200 if quick else 2000
    return [
        Workload(
            f"{n_particles} poses x 100 beams @ 10 m",
            grid.sample_free_poses(rng, n_particles),
            n_particles,
            np.linspace(-math.pi, math.pi, 100, endpoint=False),
            10.0,
        ),
        Workload(
            f"1 pose x 1080 beams @ 30 m, {n_scans} scans",
            grid.sample_free_poses(rng, n_scans),
            1,
            np.linspace(-2.35619449, 2.35619449, 1080),
            30.0,
        ),
    ]


def median_seconds(fn: Callable[[], object], runs: int) -> tuple[float, float]:
    """Median wall-clock and median process-CPU seconds of ``runs`` calls after a warm-up."""
    fn()  # warm-up (and numba compilation on a first use)
    wall, cpu = [], []
    for _ in range(runs):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


# -------------------------------------------------------------------------- one map
def bench_map(grid: OccupancyMap, args: argparse.Namespace) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = []
    runs = 3 if args.quick else 5
    lut_params = LutParams(n_angles=args.lut_angles, tolerance=args.lut_tolerance)
    for wl in workloads(grid, args.quick, args.seed):
        casters: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
            BASELINE: NumpyMarcher(grid, wl.max_range).cast
        }
        builds: dict[str, tuple[float, int]] = {}
        for method in METHODS:
            start = time.perf_counter()
            caster = RayCaster(grid, wl.max_range, method, lut=lut_params, cache=False)
            if caster.table is not None:
                builds[method] = (time.perf_counter() - start, caster.table.nbytes)
            casters[method] = caster.cast
        exact = wl.run(casters["exact"])
        seconds = {
            name: median_seconds(lambda c=c, w=wl: w.run(c), runs) for name, c in casters.items()
        }
        base = wl.rays / seconds[BASELINE][0]
        for name, cast in casters.items():
            err = np.abs(wl.run(cast) - exact)
            build_s, nbytes = builds.get(name, (None, None))
            rows.append(
                {
                    "map": grid.name,
                    "workload": wl.name,
                    "method": name,
                    "mrays": wl.rays / seconds[name][0] / 1e6,
                    "cpu_mrays": wl.rays / seconds[name][1] / 1e6,
                    "ratio": wl.rays / seconds[name][0] / base,
                    "err": None if name == "exact" else err,
                    "build_s": build_s,
                    "mbytes": None if nbytes is None else nbytes / 1e6,
                }
            )
        del casters
    return rows


def format_table(rows: list[dict[str, object]]) -> str:
    head = (
        "| map | workload | method | Mrays/s | x baseline | Mrays/CPU-s | mean err (m) "
        "| p99 err (m) | max err (m) | build (s) | table (MB) |"
    )
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        err = r["err"]
        if isinstance(err, np.ndarray):
            e = f"{err.mean():.4f} | {np.percentile(err, 99):.4f} | {err.max():.3f}"
        else:
            e = "exact | exact | exact"
        build = "" if r["build_s"] is None else f"{r['build_s']:.2f}"
        mb = "" if r["mbytes"] is None else f"{r['mbytes']:.0f}"
        lines.append(
            f"| {r['map']} | {r['workload']} | {r['method']} | {r['mrays']:.2f} "
            f"| {r['ratio']:.1f} | {r['cpu_mrays']:.2f} | {e} | {build} | {mb} |"
        )
    return "\n".join(lines)


def load_maps(paths: list[str] | None) -> list[OccupancyMap]:
    if paths:
        return [load_map(p) for p in paths]
    grids = []
    if STATA.is_file():
        grids.append(load_map(STATA))
    else:
        print(f"skipping the Stata basement: {STATA} not found (../shared/maps is absent)")
    try:
        grids.append(load_map(bundled()))
    except MapError as exc:
        print(f"skipping the default bundled map: {exc}")
    return grids


def main(argv: list[str] | None = None) -> str:
    """Run the benchmark and print (and return) the markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller workloads, 3 runs")
    parser.add_argument("--map", nargs="*", help="map YAMLs instead of Stata + the default map")
    parser.add_argument("--seed", type=int, default=0, help="seed of the poses")
    parser.add_argument("--lut-angles", type=int, default=LutParams.n_angles)
    parser.add_argument("--lut-tolerance", type=float, default=LutParams.tolerance)
    args = parser.parse_args(argv)

    print(
        f"cores: {os.cpu_count()}, numba threads: {numba.get_num_threads()}, "
        f"load average at start: {os.getloadavg()[0]:.1f}"
    )
    rows: list[dict[str, object]] = []
    for grid in load_maps(args.map):
        print(f"benchmarking {grid.name} ({grid.width} x {grid.height} cells)...", flush=True)
        rows.extend(bench_map(grid, args))
    table = format_table(rows)
    print(table)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")
    return table


if __name__ == "__main__":
    main()
