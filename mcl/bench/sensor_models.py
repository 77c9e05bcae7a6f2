"""Accuracy of the two sensor models: the beam model (lut, 100 beams) against the likelihood field
(every beam).

* In simulation: same drives, same seeds ([`mcl.experiments.runs.run_one()`][mcl.experiments.runs.run_one], MCL in the loop),
  position and heading error per run.
* On the real bags in ``../shared/bags`` (when present, ``--no-bags`` to skip): the replay's global
  filter finds the start; both models then track from its pose one second after it first fits the
  map, and the likelihood field also tries the global start itself. There is no ground truth, so
  the measure is ``scan_fit`` (beams within 0.15 m of an exact cast from the estimate).

    .venv/bin/python scripts/bench_sensor_models.py [--map YAML|NAME] [--seeds 3] [--duration 30]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

from mcl.bench import SHARED, STATA
from mcl.experiments.runs import RunSpec, run_one
from mcl.filter.sensor_model import SensorModelParams
from mcl.wrappers.localization import LocalizationConfig
from racecar_sim.settings.config import LidarParams

MODELS = {
    "beam (lut, 100 beams)": SensorModelParams(parallel=False),
    "likelihood field (all beams)": SensorModelParams(
        model="likelihood_field", num_beams_per_particle=LidarParams().n_beams, parallel=False
    ),
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    default_map = str(STATA) if STATA.is_file() else "basement_loop"
    parser.add_argument("--map", default=default_map, help="bundled name or map YAML")
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0 .. N-1")
    parser.add_argument("--duration", type=float, default=30.0, help="simulated seconds per run")
    parser.add_argument("--particles", type=int, default=1500)
    parser.add_argument("--no-bags", action="store_true", help="skip the real bags")
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.duration <= 0 or args.particles < 1:
        parser.error("--seeds, --duration and --particles must be positive")
    print(
        f"map {args.map}, {args.seeds} seeds x {args.duration:g} s, {args.particles} particles, "
        "wall follower, tracking from a 0.25 m / 0.1 rad spread"
    )
    header = "model                          mean (m)  p95 (m)  max (m)  heading (deg)  update (ms)"
    print(header)
    with tempfile.TemporaryDirectory() as tmp:
        for label, sensor in MODELS.items():
            stats = []
            for seed in range(args.seeds):
                spec = RunSpec(
                    map=args.map, seed=seed, duration=args.duration, n_particles=args.particles
                )
                result = run_one(
                    spec, Path(tmp) / f"{seed}.csv", config=LocalizationConfig(sensor=sensor)
                )
                if result.stats is None:
                    print(f"{label}: seed {seed} failed: {result.error}")
                    return 1
                stats.append(result.stats)

            def med(name: str, stats=stats) -> float:
                return statistics.median(getattr(s, name) for s in stats)

            print(
                f"{label:<30} {med('mean_error'):8.3f} {med('p95_error'):8.3f} "
                f"{med('max_error'):8.3f} {57.29578 * med('mean_heading_error'):14.2f} "
                f"{1e3 * med('mean_update_s'):12.1f}"
            )
    print("(medians over seeds of each run's statistic)")
    bags = sorted((SHARED / "bags").glob("*.bag"))
    if args.no_bags or not bags or not STATA.is_file():
        print("real bags: skipped" + ("" if args.no_bags else " (../shared/bags not found)"))
        return 0
    for bag in bags:
        bag_comparison(bag)
    return 0


def bag_comparison(bag: Path) -> None:
    """Print both models' scan_fit on one real bag (see the module docstring)."""
    import dataclasses

    import numpy as np

    from mcl.experiments.replay import ReplayConfig, replay, unknown_start_localization
    from mcl.io import read_bag
    from racecar_sim.maps import load_map

    grid = load_map(STATA)
    data = read_bag(bag, "/scan", None, None)
    found = replay(data, grid, ReplayConfig(seed=0))
    fit = found.column("scan_fit")
    if not (fit > 0.8).any():
        print(f"{bag.name}: the global beam filter never fitted the map (max {fit.max():.2f})")
        return
    j = min(int(np.argmax(fit > 0.8)) + 40, fit.size - 1)  # a second after it first fits
    start = tuple(float(found.column(c)[j]) for c in ("x", "y", "theta"))
    k = int(np.searchsorted(data.odom_times, data.scan_times[j]))
    tail = dataclasses.replace(
        data,
        scan_times=data.scan_times[j:],
        scans=data.scans[j:],
        odom_times=data.odom_times[k:],
        odom_twist=data.odom_twist[k:],
        odom_pose=data.odom_pose[k:],
        scan_stamps=data.scan_stamps[j:],
        odom_stamps=data.odom_stamps[k:],
    )
    for label, sensor in MODELS.items():
        if sensor.model == "likelihood_field":  # every beam of the real scan (1081)
            sensor = dataclasses.replace(sensor, num_beams_per_particle=data.scans.shape[1])
        tracked = replay(
            tail,
            grid,
            ReplayConfig(init=start, seed=0, localization=LocalizationConfig(sensor=sensor)),
        )
        f = tracked.column("scan_fit")
        print(
            f"{bag.name}: {label}, tracking from scan {j} of {fit.size}: scan_fit median "
            f"{np.median(f):.3f}, min {f.min():.3f}"
        )
    field = dataclasses.replace(unknown_start_localization(), sensor=dataclasses.replace(
        MODELS["likelihood field (all beams)"], num_beams_per_particle=data.scans.shape[1]
    ))  # fmt: skip
    lost = replay(data, grid, ReplayConfig(seed=0, localization=field))
    print(
        f"{bag.name}: global start, beam model scan_fit median {np.median(fit):.3f}; "
        f"likelihood field {np.median(lost.column('scan_fit')):.3f}"
    )


if __name__ == "__main__":
    sys.exit(main())
