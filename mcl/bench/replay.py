"""Benchmark the replay of real bags: is it faster than real time on one core?

For each bag (default: the two Stata basement recordings in ``../shared/bags``) and each seed, the
whole replay ([`mcl.experiments.replay.replay()`][mcl.experiments.replay.replay]: global start, the adaptive filter, the
uncertainty report and ``scan_fit`` after every scan) runs on one numba thread after a warm-up
replay (kernels compiled, lookup table built). Reported per bag, as medians over the seeds: wall
and CPU seconds, the real-time factor (seconds of recording per second of wall / CPU time; > 1 is
faster than real time), the mean ``scan_fit`` after the filter settled (position sd < 0.3 m held
to the end), the time it settled, and the same replay started from the settled pose of the first
seed (tracking only) as the baseline measured in the same run.

    .venv/bin/python scripts/bench_replay.py [--bag BAG ...] [--map YAML] [--seeds 3]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numba
import numpy as np

from mcl.bench import missing_map, shared_dir, stata_map
from mcl.experiments.replay import ReplayConfig, replay
from mcl.io import read_bag
from racecar_sim.maps import resolve_map


def settled_time(result) -> float:
    """Seconds from which the position sd stays below 0.3 m (inf if it never does)."""
    sd = result.column("position_sd")
    bad = np.nonzero(~(sd < 0.3))[0]
    if len(bad) == 0:
        return float(result.rows[0, 0])
    if bad[-1] == len(sd) - 1:
        return float("inf")
    return float(result.rows[bad[-1] + 1, 0])


def timed(data, grid, config):
    """(result, wall s, CPU s) of one replay."""
    w0, c0 = time.perf_counter(), time.process_time()
    result = replay(data, grid, config)
    return result, time.perf_counter() - w0, time.process_time() - c0


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--bag",
        action="append",
        type=Path,
        default=None,
        help="a bag (repeat for more; default: ../shared/bags/*.bag)",
    )
    parser.add_argument(
        "--map", default=str(stata_map()), help="map YAML or bundled name (default: ../shared's)"
    )
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args(argv)
    bags = args.bag or sorted((shared_dir() / "bags").glob("*.bag"))
    if not bags:
        parser.error(f"--bag: none given and no bag in {shared_dir() / 'bags'}; give --bag BAG")
    for bag in bags:
        if not bag.exists():
            parser.error(f"--bag: {bag} not found")
    spec = Path(args.map)
    if (spec.suffix in (".yaml", ".yml") or len(spec.parts) > 1) and not spec.is_file():
        parser.error(missing_map("--map", args.map))
    numba.set_num_threads(1)
    grid = resolve_map(args.map)
    print(
        "| bag | length | scans | start | wall (s) | CPU (s) | real-time factor (wall / CPU) "
        "| settled at | scan_fit after |"
    )
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|")
    for bag in bags:
        data = read_bag(bag)
        timed(data, grid, ReplayConfig(seed=99))  # warm-up: compile, table build
        runs = [timed(data, grid, ReplayConfig(seed=s)) for s in range(args.seeds)]
        first = runs[0][0]
        t_set = settled_time(first)
        i = int(np.searchsorted(first.column("time"), t_set)) if np.isfinite(t_set) else 0
        pose = tuple(first.rows[i, 1:4])
        # Tracking baseline: from the settled pose, the scans after it.
        n0 = i
        tail = type(data)(
            **{
                **data.__dict__,
                "scans": data.scans[n0:],
                "scan_times": data.scan_times[n0:],
                "duration": float(data.duration - data.scan_times[n0]),
            }
        )
        track = [timed(tail, grid, ReplayConfig(init=pose, seed=s)) for s in range(args.seeds)]
        for label, rs, d in (("global", runs, data), ("known pose", track, tail)):
            wall = statistics.median(r[1] for r in rs)
            cpu = statistics.median(r[2] for r in rs)
            settled = [settled_time(r[0]) for r in rs]
            fits = []
            for r, t in zip(rs, settled, strict=True):
                after = r[0].column("time") >= t
                fits.append(
                    float(np.nanmean(r[0].column("scan_fit")[after]))
                    if after.any()
                    else float("nan")
                )
            print(
                f"| {bag.name} | {d.duration:.1f} s | {d.n_scans} | {label} | {wall:.2f} | "
                f"{cpu:.2f} | {d.duration / wall:.2f} / {d.duration / cpu:.2f} | "
                f"{', '.join(f'{t:.2f}' for t in settled)} s | "
                f"{statistics.median(fits):.3f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
