"""The same noise sweep on the process pool and on a local Ray, timed in one run.

Each repeat runs the sweep once per executor (alternating, in fresh temporary folders), timing the
whole call: pool start-up or ``ray.init``, every run, summaries (no plots). It prints the median
wall time of each executor, their ratio, the start-up of Ray alone, and checks that both wrote the
same logs (the ``update_s`` timing column aside).

    .venv/bin/racecar-sim bench executors --seeds 2 --duration 20 --repeats 3
"""

from __future__ import annotations

import argparse
import csv
import io
import os
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from mcl.experiments.noise_sweep import ExperimentConfig, run_experiment
from mcl.experiments.runner import make_executor


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return [{k: v for k, v in r.items() if k != "update_s"} for r in csv.DictReader(f)]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", default="basement_loop")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--duration", type=float, default=20.0, help="simulated s per run")
    parser.add_argument("--particles", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    try:
        import ray
    except ImportError:
        parser.error("needs Ray: pip install -e '.[ray]'")
    config = ExperimentConfig(
        map=args.map,
        seeds=args.seeds,
        duration=args.duration,
        n_particles=args.particles,
        uniform=(0.1, 0.5),
        gaussian=(0.1, 0.5),
        matched=False,
    )
    n_runs = len(config.runs())
    times: dict[str, list[float]] = {"pool": [], "ray": []}
    ray_start: list[float] = []
    identical = True
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.repeats):
            outs = {}
            for name in ("pool", "ray"):
                out = Path(tmp) / f"{name}{k}"
                t0 = time.perf_counter()
                if name == "ray":
                    ray.init(num_cpus=args.workers, include_dashboard=False, log_to_driver=False)
                    ray_start.append(time.perf_counter() - t0)
                executor = make_executor(name, args.workers)
                run_experiment(
                    config,
                    out,
                    progress=False,
                    plots=False,
                    stream=io.StringIO(),
                    executor=executor,
                )
                if name == "ray":
                    ray.shutdown()
                times[name].append(time.perf_counter() - t0)
                outs[name] = out
            for log in sorted((outs["pool"] / "logs").glob("*.csv")):
                identical &= _rows(log) == _rows(outs["ray"] / "logs" / log.name)
            print(
                f"repeat {k + 1}: pool {times['pool'][-1]:.1f} s, ray {times['ray'][-1]:.1f} s "
                f"(ray.init {ray_start[-1]:.1f} s)",
                flush=True,
            )
    pool, on_ray = statistics.median(times["pool"]), statistics.median(times["ray"])
    load = os.getloadavg()[0]
    print(
        f"\n{n_runs} runs of {args.duration:g} s on {args.map}, {args.particles} particles, "
        f"{args.workers} workers, median of {args.repeats} (load average {load:.1f}):\n"
        f"| executor | wall time | per run | vs pool |\n|---|---:|---:|---:|\n"
        f"| process pool | {pool:.1f} s | {pool / n_runs:.2f} s | 1.00 |\n"
        f"| local Ray | {on_ray:.1f} s | {on_ray / n_runs:.2f} s | {on_ray / pool:.2f} |\n"
        f"Ray start-up alone: {statistics.median(ray_start):.1f} s; logs identical apart from "
        f"update_s: {'yes' if identical else 'NO'}"
    )
    return 0 if identical else 1


if __name__ == "__main__":
    raise SystemExit(main())
