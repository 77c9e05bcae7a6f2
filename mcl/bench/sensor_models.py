"""Accuracy of the two sensor models in simulation: the beam model (lut, 100 beams) against the
likelihood field (every beam), same drives, same seeds: ``racecar-sim``-style drives with MCL in
the loop (:func:`mcl.experiments.runs.run_one`), position and heading error per run.

    .venv/bin/python scripts/bench_sensor_models.py [--map YAML|NAME] [--seeds 3] [--duration 30]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

from mcl.bench import STATA
from mcl.experiments.runs import RunSpec, run_one
from mcl.sensor_model import SensorModelParams
from mcl.wrapper import LocalizationConfig
from racecar_sim.config import LidarParams

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
    return 0


if __name__ == "__main__":
    sys.exit(main())
