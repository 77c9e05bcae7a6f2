"""Global localization against range_libc: the MCL update on a cloud spread over the whole floor.

``racecar-sim bench peers --only spread``. A particle filter searching for its pose weighs clouds of
5 000-20 000 particles uniform over the free space, where every particle reads the tables
somewhere else; the tracking workload ([`mcl.bench.peer_rangelibc.compare()`][mcl.bench.peer_rangelibc.compare]) has them within
half a metre of the car. Here, for each cloud (uniform over free space at each size, and a tracking
cloud N(truth, 0.5 m, 0.5 m, 0.2 rad) for the other regime in the same run), one round times in
turn: range_libc's GLT update ([`GltUpdate`][mcl.bench.peer_rangelibc.GltUpdate], one thread), ours on
each thread count, and ours with the Z-order sort of the cast turned off
(``SensorModelParams.lut_sort_extent = inf``, the caster before the sort). Every update starts from the same
cloud (a filter that resamples would otherwise collapse it after one scan); the sorted and
unsorted variants swap places every other round (the first after the GLT finds the cache swept); the scan is the
simulator's noisy lidar from a free pose. Printed: per variant the median time per update (wall, or CPU with ``clock="cpu"``)
and the range over the rounds, and the median (and range) of the per-round ratios.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time

import numpy as np

from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast.morton import spread_order

__all__ = ["CLOCKS", "SPREAD", "TRACKING", "clouds", "compare_spread", "glt_inputs"]

TRACKING = (0.5, 0.5, 0.2)
"""Standard deviations (metres, metres, radians) of the tracking cloud around the true pose."""

SPREAD = "spread"
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
"""What `compare_spread()` can time an update with."""
_PAUSE_S = 0.03  # after each round, as between a lidar's scans


def clouds(
    grid: OccupancyMap, sizes: tuple[int, ...], truth: np.ndarray, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """The workload's clouds (N, 3) world poses: ``spread N`` uniform over free space for each of
    ``sizes``, and ``tracking N`` (N = the first size) around ``truth`` (`TRACKING`)."""
    out = {f"{SPREAD} {n}": grid.sample_free_poses(rng, n, clearance=0.0) for n in sizes}
    out[f"tracking {sizes[0]}"] = truth + rng.normal(0.0, TRACKING, size=(sizes[0], 3))
    return out


def glt_inputs(grid: OccupancyMap, sm, scan: np.ndarray, seed: int):
    """``(peer, idx, angles, odometry)``: range_libc's GLT update for the beam model of ``sm``
    (a [`SensorModel`][mcl.filter.sensor_model.SensorModel]; None when range_libc is not installed), the
    indexes of the scan's beams it uses and their car-frame angles (radians), and the odometry of
    one update (car frame, metres, radians)."""
    from mcl.bench import peer_rangelibc
    from mcl.bench.mcl import DT, TWIST
    from mcl.filter.motion_model import twist_to_odometry

    peer = (
        peer_rangelibc.GltUpdate(grid, sm.params, np.random.default_rng(seed + 1))
        if peer_rangelibc.available()
        else None
    )
    idx, _ = sm.beams_used(scan.size)
    angles, _ = sm.observe(scan)
    return peer, idx, angles, twist_to_odometry(TWIST, DT)


def _row(label: str, times: list[float], base: list[float] | None) -> str:
    med = 1e3 * statistics.median(times)
    text = f"  {label:<22}{med:9.2f} ms  ({1e3 * min(times):.2f}-{1e3 * max(times):.2f})"
    if base is not None:
        r = [b / t for b, t in zip(base, times, strict=True)]
        text += f"  x GLT {statistics.median(r):5.2f} ({min(r):.2f}-{max(r):.2f})"
    return text


def compare_spread(
    grid: OccupancyMap,
    sizes: tuple[int, ...] = (4000, 10000),
    n_beams: int = 100,
    rounds: int = 8,
    warmup: int = 1,
    seed: int = 0,
    threads: tuple[int, ...] = (1, 2),
    out=print,
    clock: str = "wall",
) -> dict[str, dict[str, float]]:
    """Ours against the GLT update on spread and tracking clouds, interleaved round by round.

    ``clock``: ``"wall"`` (elapsed seconds) or ``"cpu"`` (the process's CPU seconds,
    [`time.process_time()`][time.process_time]: on a shared machine it leaves out the time spent waiting for a
    core; on two threads it is the sum of both threads' time, not the latency).

    Returns, per cloud name, per variant (``glt``, ``ours/T``, ``unsorted/T``): ``ms`` (median
    time per update on ``clock``) and, for ours, ``x_glt`` (median of the per-round GLT / ours
    ratios) and ``x_unsorted`` (median of the per-round unsorted / sorted ratios).
    """
    if clock not in CLOCKS:
        raise ValueError(f"clock must be one of {tuple(CLOCKS)}, got {clock!r}")
    timer = CLOCKS[clock]
    import numba

    from mcl.bench import peer_rangelibc
    from mcl.bench.mcl import mcl_update
    from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
    from mcl.filter.sensor_model import SensorModel, SensorModelParams
    from racecar_sim.sensors.lidar import Lidar

    rng = np.random.default_rng(seed)
    truth = grid.sample_free_poses(rng, 1, clearance=1.0)[0]
    scan = Lidar(grid).measure(truth, rng).astype(np.float64)
    work = clouds(grid, sizes, truth, rng)

    def model(t: int, sort: bool) -> SensorModel:
        params = SensorModelParams(num_beams_per_particle=n_beams, parallel=t > 1)
        if not sort:
            params = dataclasses.replace(params, lut_sort_extent=math.inf)
        return SensorModel(grid, params)

    variants = {f"{kind}/{t}": model(t, kind == "ours") for kind in ("ours", "unsorted")
                for t in threads}  # fmt: skip
    sm0 = variants[f"ours/{threads[0]}"]
    assert sm0.caster is not None
    peer, idx, angles, odometry = glt_inputs(grid, sm0, scan, seed)
    out(
        f"workload: clouds {', '.join(f'{k} particles' for k in work)} x {n_beams} beams, max "
        f"range {sm0.max_range:.2f} m, map {grid.name} {grid.width}x{grid.height} cells at "
        f"{grid.resolution} m; every update from the same cloud, resampling; {rounds} rounds "
        f"interleaved (GLT, then ours on {', '.join(map(str, threads))} threads, sorted and "
        f"unsorted swapping places each round), {clock} time; sort from a {sm0.caster.lut_params.sort_extent:g} m wide cloud"
    )
    if peer is None:
        out(f"range_libc not installed, ours only: {peer_rangelibc.INSTALL_HINT}")
    filters = {}
    for name, cloud in work.items():
        for v, sm in variants.items():
            pf = ParticleFilter(
                grid,
                cloud.shape[0],
                sensor_model=sm,
                params=ParticleFilterParams(resample_threshold="always"),
                rng=seed,
            )
            filters[name, v] = pf
    times: dict[tuple[str, str], list[float]] = {
        (name, v): [] for name in work for v in ("glt", *variants)
    }
    order = [f"{kind}/{t}" for t in threads for kind in ("ours", "unsorted")]
    default_threads = numba.get_num_threads()
    try:
        for k in range(warmup + rounds):
            for name, cloud in work.items():
                if peer is not None:
                    start = timer()
                    _, r = peer.step(cloud, odometry, scan[idx], angles)
                    spent = sum(r.values()) if clock == "wall" else timer() - start
                    if k >= warmup:
                        times[name, "glt"].append(spent)
                # sorted and unsorted swap places every other round: the first after the GLT
                # finds the cache swept by its table
                for v in order if k % 2 == 0 else order[::-1]:
                    numba.set_num_threads(min(int(v.split("/")[1]), numba.config.NUMBA_NUM_THREADS))
                    pf = filters[name, v]
                    pf.set_particles(cloud)
                    start = timer()
                    mcl_update(pf, scan)
                    if k >= warmup:
                        times[name, v].append(timer() - start)
            time.sleep(_PAUSE_S)
    finally:
        numba.set_num_threads(default_threads)
    results: dict[str, dict[str, float]] = {}
    out(f"median {clock} ms per update (range over rounds); x GLT: median (range) of per-round "
        "ratios")  # fmt: skip
    for name in work:
        gu, gv = sm0.caster.grid_cells(work[name])
        sorts = spread_order(gu, gv, sm0.caster.lut_params.sort_extent / grid.resolution)
        out(f"{name} particles ({'sorted' if sorts is not None else 'narrow: not sorted'}):")
        base = times[name, "glt"] if peer is not None else None
        res: dict[str, float] = {}
        if base is not None:
            out(_row("GLT (1 thr)", base, None))
            res["glt_ms"] = 1e3 * statistics.median(base)
        for v in variants:
            kind, t = v.split("/")
            out(
                _row(
                    f"{'ours' if kind == 'ours' else 'ours, no sort'} ({t} thr)",
                    times[name, v],
                    base,
                )
            )
            res[f"{v}_ms"] = 1e3 * statistics.median(times[name, v])
            if base is not None:
                res[f"{v}_x_glt"] = statistics.median(
                    b / t_ for b, t_ in zip(base, times[name, v], strict=True)
                )
        for t in threads:
            r = [
                u / s
                for u, s in zip(times[name, f"unsorted/{t}"], times[name, f"ours/{t}"], strict=True)
            ]
            res[f"ours/{t}_x_unsorted"] = statistics.median(r)
            out(
                f"  sorted vs unsorted ({t} thr): x {statistics.median(r):.2f} ({min(r):.2f}-{max(r):.2f})"
            )
        results[name] = res
    return results
