"""MCL experiments: the odometry-noise sweep (scenario ``tracking``, see mcl.experiments.noise_sweep), and
global localization / kidnapping (scenarios ``global`` and ``kidnap``, see mcl.experiments.recovery).

Examples (the full runs of the README):

    .venv/bin/python scripts/experiment.py --map ../shared/maps/stata_basement.yaml \
        --seeds 3 --duration 60 --out runs/stata
    .venv/bin/python scripts/experiment.py --scenario global --map basement_loop \
        --seeds 20 --out runs/global_basement_loop
    .venv/bin/python scripts/experiment.py --scenario kidnap --map basement_loop \
        --seeds 20 --out runs/kidnap_basement_loop
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from mcl.experiments.noise_sweep import (
    GAUSSIAN_SIGMAS,
    UNIFORM_COEFFICIENTS,
    ExperimentConfig,
    run_experiment,
)
from mcl.experiments.recovery import (
    RECOVERY_SCENARIOS,
    RecoveryConfig,
    recovery_localization,
    run_recovery_experiment,
)
from mcl.experiments.runs import DRIVERS, RunResult
from mcl.experiments.scenarios import SCENARIOS
from mcl.filter_params import DEFAULT_PARTICLES
from racecar_sim.maps import DEFAULT_MAP


def _floats(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}"
        ) from None


def _setting(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` (VALUE read as YAML: numbers, booleans, lists) for an env setting."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), yaml.safe_load(value)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--map", default=DEFAULT_MAP, help="bundled map name or map YAML path")
    parser.add_argument("--driver", choices=sorted(DRIVERS), default="wall")
    parser.add_argument("--scenario", choices=sorted(SCENARIOS), default="tracking")
    parser.add_argument("--seeds", type=int, default=3, help="number of seeds (0, 1, ...)")
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        help="simulated seconds per run (default: 60; global: 20; kidnap: kidnap time + 20)",
    )
    parser.add_argument(
        "--particles",
        type=int,
        default=None,
        help=f"particles per run (default {DEFAULT_PARTICLES}); global/kidnap: particles of the "
        "global start (default: 300 per m² of free floor)",
    )
    parser.add_argument(
        "--kidnap-time", type=float, default=5.0, help="kidnap: seconds before the car is moved"
    )
    parser.add_argument(
        "--time-limit",
        type=float,
        default=None,
        help="global/kidnap: seconds to converge for a success (default: 10 global, 15 kidnap)",
    )
    parser.add_argument(
        "--uniform",
        type=_floats,
        default=UNIFORM_COEFFICIENTS,
        help="uniform half-widths c, comma-separated (empty: none)",
    )
    parser.add_argument(
        "--gaussian",
        type=_floats,
        default=GAUSSIAN_SIGMAS,
        help="Gaussian sigmas, comma-separated (empty: none)",
    )
    parser.add_argument(
        "--no-matched",
        action="store_true",
        help="skip the Gaussian runs at sigma = c/sqrt(3) (variance of each uniform c)",
    )
    parser.add_argument(
        "--env",
        type=_setting,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a RacecarEnv setting for every run, e.g. --env lidar_rate=20 (repeatable)",
    )
    parser.add_argument("--workers", type=int, default=None, help="processes (default: cores)")
    parser.add_argument("--resume", action="store_true", help="skip runs whose log is complete")
    parser.add_argument("--no-plots", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("runs/experiment"), help="output folder")
    args = parser.parse_args(argv)
    if args.scenario in RECOVERY_SCENARIOS:
        return _recovery(parser, args)

    try:
        config = ExperimentConfig(
            map=args.map,
            driver=args.driver,
            scenario=args.scenario,
            seeds=args.seeds,
            duration=args.duration if args.duration is not None else 60.0,
            n_particles=args.particles if args.particles is not None else DEFAULT_PARTICLES,
            uniform=args.uniform,
            gaussian=args.gaussian,
            matched=not args.no_matched,
            env=tuple(args.env),
        )
    except ValueError as exc:
        parser.error(str(exc))
    report = run_experiment(
        config, args.out, workers=args.workers, resume=args.resume, plots=not args.no_plots
    )
    return _finish(args.out, [r.status for r in report.results], report.failed)


def _recovery(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """The global-localization / kidnapping experiment (mcl.experiments.recovery)."""
    try:
        config = RecoveryConfig(
            map=args.map,
            scenario=args.scenario,
            driver=args.driver,
            seeds=args.seeds,
            duration=args.duration,
            kidnap_time=args.kidnap_time,
            time_limit=args.time_limit,
            localization=recovery_localization(global_particles=args.particles),
            env=tuple(args.env),
        )
    except ValueError as exc:
        parser.error(str(exc))
    report = run_recovery_experiment(
        config, args.out, workers=args.workers, resume=args.resume, plots=not args.no_plots
    )
    return _finish(args.out, [r.result.status for r in report.runs], report.failed)


def _finish(out: Path, statuses: list[str], failed: list[RunResult]) -> int:
    """Print the summary, the run counts and each failure; exit status 1 when a run failed."""
    print((out / "summary.md").read_text())
    ok, skipped = statuses.count("ok"), statuses.count("skipped")
    print(f"{ok} runs done, {skipped} skipped (complete logs), {len(failed)} failed")
    for r in failed:
        print(f"FAILED {r.spec.run_id}: {r.error}", file=sys.stderr)
    print(f"output folder: {out.resolve()}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
