"""Benchmark the uncertainty report (covariance + clusters + ambiguity flag) and KLD-sampling's count.

For 1 000, 10 000 and 100 000 particles in two shapes of cloud, a *converged* one (Gaussian, 0.1 m /
0.05 rad) and a *global* one (uniform over the free space of the map), the median wall time over
``--repeats`` calls of

* ``uncertainty``: ``ParticleFilter.uncertainty()`` (covariance, clustering, flag);
* ``kld``: ``ParticleFilter.kld_count()`` (Fox's rule on draws of the weighted particles);

against two baselines measured in the same run: ``covariance`` (``ParticleFilter.covariance()``, the
report the filter already had) and ``update``, one full correction (cast 100 beams per particle with
the ``lut`` caster, weigh, resample) at the same particle count. The ratios say what the report
adds to each step.

    .venv/bin/python scripts/bench_uncertainty.py [--map NAME_OR_YAML] [--repeats 20]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import numpy as np

from mcl.filter.kld import KLDParams
from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.maps import DEFAULT_MAP, resolve_map
from racecar_sim.sensors.lidar import Lidar

COUNTS = (1_000, 10_000, 100_000)


def _median_s(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm-up (numba compile / caches)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--map", default=DEFAULT_MAP, help="bundled map name or map YAML path")
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--update-repeats", type=int, default=5)
    args = parser.parse_args(argv)

    grid = resolve_map(args.map)
    rng = np.random.default_rng(0)
    sensor = SensorModel(grid, SensorModelParams(parallel=False))
    lidar = Lidar(grid)
    truth = grid.sample_free_poses(rng, 1, clearance=0.5)[0]
    scan = lidar.measure(truth, rng)
    load = os.getloadavg()[0]
    print(f"map {grid.name}: {grid.free_area:.0f} m² free; load average {load:.1f}")
    print(
        "| particles | cloud | uncertainty ms | kld ms | covariance ms | update ms "
        "| uncertainty / covariance | uncertainty / update |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|")
    params = ParticleFilterParams(kld=KLDParams(enabled=True, max_particles=max(COUNTS)))
    for n in COUNTS:
        for cloud in ("converged", "global"):
            pf = ParticleFilter(grid, n, sensor_model=sensor, params=params, rng=1)
            if cloud == "converged":
                pf.initialize(truth, (0.1, 0.1, 0.05))
            else:
                pf.initialize_global(n)
            w = rng.random(n)
            pf.set_particles(pf.particles, w / w.sum())
            unc = _median_s(pf.uncertainty, args.repeats)
            kld = _median_s(pf.kld_count, args.repeats)
            cov = _median_s(pf.covariance, args.repeats)
            particles, weights = pf.particles.copy(), pf.weights.copy()

            def update(pf=pf, particles=particles, weights=weights, n=n) -> None:
                pf.set_particles(particles, weights)
                pf.update_weights(sensor.log_evaluate(pf.particles, scan))
                pf.resample(n)

            upd = _median_s(update, args.update_repeats)
            print(
                f"| {n:,} | {cloud} | {1e3 * unc:.2f} | {1e3 * kld:.2f} | {1e3 * cov:.2f} | "
                f"{1e3 * upd:.1f} | {unc / cov:.1f}x | {unc / upd:.3f}x |"
            )


if __name__ == "__main__":
    main()
