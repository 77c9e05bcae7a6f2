"""Which parts of the global-localization filter matter? The recovery experiment with one part off.

Runs [`mcl.experiments.recovery.run_recovery_experiment()`][mcl.experiments.recovery.run_recovery_experiment] on one map for each variant below (``--variants``
to choose), each into ``<out>/<variant>``, and prints one summary line per variant:

* ``full``: [`mcl.experiments.recovery.recovery_localization()`][mcl.experiments.recovery.recovery_localization] as is;
* ``lab``: the plain filter of the tracking experiments (beam model squash 1/2.2, every scan,
  global start at the default 20 particles/m², fixed count, no augmented MCL);
* ``sparse``: a global start at 20 particles/m² instead of 300;
* ``sharp``: the lab's squash 1/2.2 instead of 0.1;
* ``every_scan``: every scan used (40 Hz) instead of one every 0.1 m / 0.2 rad;
* ``no_recovery``: augmented MCL off (both alphas 0).

Each variant's runs, logs and summary go to ``<out>/<variant>``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from mcl.cli.common import (
    MAP_HELP,
    Parser,
    check_map,
    check_out,
    check_resume,
    output_folder,
    path_arg,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice
from mcl.experiments.recovery import RecoveryConfig, recovery_localization, run_recovery_experiment
from mcl.filter.sensor_model import SensorModelParams
from mcl.wrappers.localization import LocalizationConfig
from racecar_sim.maps import DEFAULT_MAP

EXAMPLES = """\
examples:
  racecar-sim ablation --scenario global --map basement_loop --seeds 20 --out runs/ablation_global
  racecar-sim ablation --variants full no_recovery --seeds 5 --out runs/ablation_quick
"""

VARIANTS = {
    "full": lambda: recovery_localization(),
    "lab": lambda: LocalizationConfig(sensor=SensorModelParams(parallel=False)),
    "sparse": lambda: recovery_localization(global_density=20.0),
    "sharp": lambda: recovery_localization(squash_exponent=1.0 / 2.2),
    "every_scan": lambda: recovery_localization(update_min_distance=0.0, update_min_angle=0.0),
    "no_recovery": lambda: recovery_localization(alpha_slow=0.0, alpha_fast=0.0),
}


def build_parser() -> Parser:
    """The ``racecar-sim ablation`` options."""
    parser = Parser("racecar-sim ablation", __doc__, EXAMPLES)
    add = parser.add_argument
    add("--map", default=DEFAULT_MAP, metavar="NAME|YAML", help=MAP_HELP)
    add("--scenario", choices=["global", "kidnap"], default="global", help="how the car is lost")
    add("--seeds", type=positive_int, default=20, metavar="N", help="number of seeds (0, 1, ...)")
    add(
        "--variants",
        nargs="+",
        choices=list(VARIANTS),
        default=list(VARIANTS),
        metavar="NAME",
        help=f"variants to run, from: {', '.join(VARIANTS)}",
    )
    add(
        "--workers",
        type=positive_int,
        default=None,
        metavar="N",
        help="processes (default: the number of cores)",
    )
    add("--resume", action="store_true", help="skip runs whose log is complete")
    add("--out", type=path_arg, default=Path("runs/ablation"), metavar="DIR",
        help="output folder: a new or empty one, or one racecar-sim made")  # fmt: skip
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim ablation``; returns the exit code (1: a run failed; 2: a user mistake)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    check_map(parser, args.map)
    out: Path = check_out(parser, args.out)
    base = RecoveryConfig(map=args.map, scenario=args.scenario, seeds=args.seeds)
    configs = {name: replace(base, localization=VARIANTS[name]()) for name in args.variants}
    for name, config in configs.items():
        check_resume(parser, config, out / name, args.resume)
    compile_notice()
    with output_folder(parser, out):
        return _run(args, base, configs, out)


def _run(
    args: argparse.Namespace, base: RecoveryConfig, configs: dict[str, RecoveryConfig], out: Path
) -> int:
    """Every variant in turn, one table row each."""
    print(f"{args.scenario} on {Path(args.map).stem}, {args.seeds} seeds, limit {base.limit:g} s")
    print("| variant | success | median s | never | confidently wrong | wall s per run |")
    print("|---|---|---|---|---|---|")
    failed = 0
    for name, config in configs.items():
        report = run_recovery_experiment(
            config, out / name, workers=args.workers, resume=args.resume, progress=False
        )
        failed += len(report.failed)
        stats = [r.stats for r in report.runs if r.stats is not None]
        times = sorted(s.convergence_s for s in stats if s.convergence_s == s.convergence_s)
        median = f"{times[len(times) // 2]:.2f}" if times else "–"
        wrong = sum(s.wrong_fraction for s in stats) / max(len(stats), 1)
        walls = [r.result.wall_s for r in report.runs if r.result.status == "ok"]
        wall = f"{sum(walls) / len(walls):.1f}" if walls else "–"
        print(
            f"| {name} | {sum(s.success for s in stats)}/{len(stats)} | {median} | "
            f"{len(stats) - len(times)} | {100 * wrong:.0f} % | {wall} |",
            flush=True,
        )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
