"""A global start's own figures: its first update, and whole replays of the shared bags from one.

``racecar-sim bench peers --only spread`` (after the spread clouds; ``--global-rounds 0`` skips
it). A filter that starts without a pose spreads the replay's global start over the free floor
([`mcl.experiments.replay.unknown_start_localization()`][mcl.experiments.replay.unknown_start_localization]: 300 particles per m², at most 300 000;
236 447 on the Stata basement) and weighs them all at the first scan; then the search keeps 5 000 to
20 000 while it converges. Two figures, each on one numba thread, ours with the Z-order sort of the
``lut`` cast (``SensorModelParams.lut_sort_extent``, 10 m) and without it (``inf``), the two
swapping places every round:

* `first_update()`: the MCL update (predict, cast and score, weigh, resample, estimate) of the
  global cloud, interleaved round by round with range_libc's GLT update of the same cloud when
  range_libc is installed;
* `bag_replays()`: the wall time of a whole global-start replay of each bag
  ([`mcl.experiments.replay.replay()`][mcl.experiments.replay.replay], the command ``racecar-sim replay``), after a warm-up
  replay; the sorted and unsorted replays must give the same trajectory (checked, printed).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from pathlib import Path

import numpy as np

from racecar_sim.maps import OccupancyMap

__all__ = ["bag_replays", "first_update", "global_cloud"]

_VARIANTS = {"sorted": 10.0, "unsorted": math.inf}
"""Variant -> SensorModelParams.lut_sort_extent (metres)."""


def _spread(times: list[float]) -> str:
    return f"{statistics.median(times):.3f} s ({min(times):.3f}-{max(times):.3f})"


def _ratio(num: list[float], den: list[float]) -> str:
    r = [a / b for a, b in zip(num, den, strict=True)]
    return f"x {statistics.median(r):.2f} ({min(r):.2f}-{max(r):.2f})"


def global_cloud(grid: OccupancyMap, seed: int) -> np.ndarray:
    """(N, 3) world poses: the replay filter's global start on ``grid``
    ([`initialize_global()`][mcl.filter.particle_filter.ParticleFilter.initialize_global] at its density and cap)."""
    from mcl.experiments.replay import unknown_start_localization
    from mcl.filter.particle_filter import ParticleFilter

    loc = unknown_start_localization()
    pf = ParticleFilter(grid, loc.filter.n_particles, params=loc.filter, rng=seed)
    pf.initialize_global()
    return pf.particles.copy()


def first_update(
    grid: OccupancyMap, n_beams: int = 100, rounds: int = 3, seed: int = 0, out=print
) -> dict[str, float]:
    """Wall seconds of the first update of a global start (`global_cloud()`), ours sorted and
    unsorted on one thread and the GLT update, interleaved; medians (``sorted``, ``unsorted``,
    ``glt``) and the particle count ``n``."""
    import numba

    from mcl.bench.mcl import mcl_update
    from mcl.bench.peer_spread import glt_inputs
    from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
    from mcl.filter.sensor_model import SensorModel, SensorModelParams
    from racecar_sim.sensors.lidar import Lidar

    rng = np.random.default_rng(seed)
    truth = grid.sample_free_poses(rng, 1, clearance=1.0)[0]
    scan = Lidar(grid).measure(truth, rng).astype(np.float64)
    cloud = global_cloud(grid, seed)
    filters = {}
    for name, extent in _VARIANTS.items():
        params = SensorModelParams(
            num_beams_per_particle=n_beams, parallel=False, lut_sort_extent=extent
        )
        filters[name] = ParticleFilter(
            grid,
            cloud.shape[0],
            sensor_model=SensorModel(grid, params),
            params=ParticleFilterParams(resample_threshold="always"),
            rng=seed,
        )
    peer, idx, angles, odometry = glt_inputs(grid, filters["sorted"].sensor_model, scan, seed)
    out(
        f"first update of a global start: {cloud.shape[0]} particles (the replay's 300 per m^2 "
        f"of free floor) x {n_beams} beams, one thread, {rounds} rounds after a warm-up"
        + ("" if peer is not None else "; range_libc not installed, ours only")
    )
    times: dict[str, list[float]] = {name: [] for name in (*_VARIANTS, "glt")}
    default_threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        for k in range(rounds + 1):
            if peer is not None:
                _, r = peer.step(cloud, odometry, scan[idx], angles)
                if k:
                    times["glt"].append(sum(r.values()))
            for name in _VARIANTS if k % 2 == 0 else list(_VARIANTS)[::-1]:
                pf = filters[name]
                pf.set_particles(cloud)
                start = time.perf_counter()
                mcl_update(pf, scan)
                if k:
                    times[name].append(time.perf_counter() - start)
    finally:
        numba.set_num_threads(default_threads)
    same = np.array_equal(filters["sorted"].particles, filters["unsorted"].particles)
    out(f"  ours, sorted        {_spread(times['sorted'])}")
    out(f"  ours, not sorted    {_spread(times['unsorted'])}  "
        f"sorted {_ratio(times['unsorted'], times['sorted'])}; same particles: {same}")  # fmt: skip
    res = {"n": float(cloud.shape[0])}
    res.update({name: statistics.median(t) for name, t in times.items() if t})
    if peer is not None:
        out(f"  GLT (1 thr)         {_spread(times['glt'])}  "
            f"ours sorted {_ratio(times['glt'], times['sorted'])} the GLT")  # fmt: skip
    return res


def bag_replays(
    grid: OccupancyMap, bags: list[Path], rounds: int = 3, out=print
) -> dict[str, dict[str, float]]:
    """Wall seconds of whole global-start replays of each bag, sorted and unsorted interleaved on
    one thread after a warm-up replay; per bag name the medians and ``same`` (1.0 when the two
    trajectories are equal)."""
    import numba

    from mcl.experiments.replay import ReplayConfig, replay, unknown_start_localization
    from mcl.io import read_bag

    loc = unknown_start_localization()
    configs = {
        name: ReplayConfig(
            seed=0,
            localization=dataclasses.replace(
                loc, sensor=dataclasses.replace(loc.sensor, lut_sort_extent=extent)
            ),
        )
        for name, extent in _VARIANTS.items()
    }
    out(f"whole replays from a global start (racecar-sim replay, seed 0), one thread, {rounds} "
        "rounds after a warm-up")  # fmt: skip
    results: dict[str, dict[str, float]] = {}
    default_threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        for bag in bags:
            data = read_bag(bag)
            replay(data, grid, configs["sorted"])  # warm-up: kernels, tables
            times: dict[str, list[float]] = {name: [] for name in _VARIANTS}
            rows = {}
            for k in range(rounds):
                for name in _VARIANTS if k % 2 == 0 else list(_VARIANTS)[::-1]:
                    start = time.perf_counter()
                    rows[name] = replay(data, grid, configs[name]).rows
                    times[name].append(time.perf_counter() - start)
            same = np.array_equal(rows["sorted"], rows["unsorted"], equal_nan=True)
            out(f"  {bag.name} ({data.duration:.1f} s, {data.n_scans} scans): sorted "
                f"{_spread(times['sorted'])}, not sorted {_spread(times['unsorted'])}, sorted "
                f"{_ratio(times['unsorted'], times['sorted'])}; real-time factor "
                f"{data.duration / statistics.median(times['sorted']):.1f}; same trajectory: "
                f"{same}")  # fmt: skip
            results[bag.name] = {name: statistics.median(t) for name, t in times.items()}
            results[bag.name]["same"] = float(same)
    finally:
        numba.set_num_threads(default_threads)
    return results
