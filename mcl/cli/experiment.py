"""MCL experiments: the odometry-noise sweep (scenario ``tracking``, see mcl.experiments.noise_sweep), and
global localization / kidnapping (scenarios ``global`` and ``kidnap``, see mcl.experiments.recovery).

Every run writes its CSV error log as it goes into ``<out>/logs``; then ``<out>`` gets runs.csv,
summary.md and plots. The map, the env settings and every flag are checked before the first run.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from mcl.cli.common import (
    ENV_HELP,
    MAP_HELP,
    Parser,
    check_env,
    check_map,
    check_out,
    check_resume,
    duration_seconds,
    non_negative_float,
    number_list,
    output_folder,
    path_arg,
    positive_float,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice
from mcl.cli.filter_map_option import check_filter_map
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
from mcl.experiments.runner import EXECUTORS, make_executor
from mcl.experiments.runs import DRIVERS, RunResult
from mcl.experiments.scenarios import SCENARIOS
from mcl.filter.params import DEFAULT_PARTICLES
from racecar_sim.maps import DEFAULT_MAP

EXAMPLES = """\
examples (the README's runs):
  racecar-sim experiment --map ../shared/maps/stata_basement.yaml --seeds 3 --duration 60 \\
      --out runs/stata
  racecar-sim experiment --scenario global --map basement_loop --seeds 20 \\
      --out runs/global_basement_loop
  racecar-sim experiment --scenario kidnap --map basement_loop --seeds 20 \\
      --out runs/kidnap_basement_loop
a quick look (2 coefficients, 1 seed, 10 s, fewer beams):
  racecar-sim experiment --uniform 0.01,0.5 --gaussian 0.01,0.5 --no-matched --seeds 1 \\
      --duration 10 --env n_beams=181 --out runs/quick
"""

_FLAGS = {
    "n_particles": "--particles",
    "kidnap_time": "--kidnap-time",
    "time_limit": "--time-limit",
    "env": "--env",
}
"""Config field -> its flag, where the two are not spelled alike."""


def build_parser() -> Parser:
    """The ``racecar-sim experiment`` options."""
    parser = Parser("racecar-sim experiment", __doc__, EXAMPLES)
    add = parser.add_argument
    add("--map", default=DEFAULT_MAP, metavar="NAME|YAML", help=MAP_HELP)
    add(
        "--filter-map",
        default=None,
        metavar="NAME|YAML",
        help="the map the filter holds when the world (--map) differs from it (same world frame; "
        "tracking scenario; default: the --map itself)",
    )
    add(
        "--noise-profile",
        default=None,
        metavar="NAME",
        help="simulator noise profile for every run, e.g. mit_racecar (= --env noise_profile=NAME; "
        "default: none, the simulator's own settings)",
    )
    add("--driver", choices=sorted(DRIVERS), default="wall", help="who drives the car")
    add(
        "--scenario",
        choices=sorted(SCENARIOS),
        default="tracking",
        help="tracking: the noise sweep from a known start; global: start lost; kidnap: moved "
        "without telling the filter",
    )
    add("--seeds", type=positive_int, default=3, metavar="N", help="number of seeds (0, 1, ...)")
    add(
        "--duration",
        type=duration_seconds,
        default=None,
        metavar="S",
        help="simulated seconds per run (default: 60; global: 20; kidnap: kidnap time + 20)",
    )
    add(
        "--particles",
        type=positive_int,
        default=None,
        metavar="N",
        help=f"particles per run (default: {DEFAULT_PARTICLES}); global/kidnap: particles of the "
        "global start (default: 300 per m² of free floor)",
    )
    add(
        "--kidnap-time",
        type=non_negative_float,
        default=5.0,
        metavar="S",
        help="kidnap: seconds before the car is moved",
    )
    add(
        "--time-limit",
        type=positive_float,
        default=None,
        metavar="S",
        help="global/kidnap: seconds to converge for a success (default: 10 global, 15 kidnap)",
    )
    add(
        "--uniform",
        type=number_list,
        default=UNIFORM_COEFFICIENTS,
        metavar="C,C,...",
        help="tracking: uniform half-widths c, comma-separated ('' for none)",
    )
    add(
        "--gaussian",
        type=number_list,
        default=GAUSSIAN_SIGMAS,
        metavar="S,S,...",
        help="tracking: Gaussian sigmas, comma-separated ('' for none)",
    )
    add(
        "--no-matched",
        action="store_true",
        help="tracking: skip the Gaussian runs at sigma = c/sqrt(3) (variance of each uniform c)",
    )
    add("--env", action="append", default=[], metavar="NAME=VALUE", help=ENV_HELP)
    add(
        "--workers",
        type=positive_int,
        default=None,
        metavar="N",
        help="processes, or Ray runs in flight (default: the number of cores)",
    )
    add(
        "--executor",
        choices=EXECUTORS,
        default="pool",
        help="where the runs execute: a process pool on this machine, or Ray (extra [ray])",
    )
    add(
        "--ray-address",
        default=None,
        metavar="auto|HOST:PORT",
        help="join this Ray cluster (default with --executor ray: start Ray on this machine)",
    )
    add("--resume", action="store_true", help="skip runs whose log is complete")
    add("--no-plots", action="store_true", help="write no PNG plots")
    add("--out", type=path_arg, default=Path("runs/experiment"), metavar="DIR",
        help="output folder: a new or empty one, or one racecar-sim made")  # fmt: skip
    return parser


def _config_error(parser: Parser, exc: ValueError) -> None:
    """Stop with a config's ValueError, named by the flag of the field it names."""
    text = str(exc)
    match = re.search(r"\b(?:ExperimentConfig|RecoveryConfig|RunSpec)\.(\w+)", text)
    if match is None:
        parser.error(text)
    field = match.group(1)
    parser.fail(_FLAGS.get(field, "--" + field.replace("_", "-")), text)


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim experiment``; returns the exit code (1: a run failed; 2: a user mistake)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.ray_address is not None and args.executor != "ray":
        parser.fail("--ray-address", "needs --executor ray")
    try:
        executor = make_executor(args.executor, args.workers, args.ray_address)
    except ValueError as exc:
        parser.fail("--executor", str(exc))
    check_map(parser, args.map)
    if args.filter_map is not None:
        check_map(parser, args.filter_map, "--filter-map")
        if args.scenario in RECOVERY_SCENARIOS:
            parser.fail("--filter-map", "only with --scenario tracking")
    if args.noise_profile is not None:
        args.env.append(f"noise_profile={args.noise_profile}")
    env = check_env(parser, args.env)
    if args.filter_map is not None:
        check_filter_map(parser, args.map, args.filter_map, env)
    out: Path = check_out(parser, args.out)
    config: ExperimentConfig | RecoveryConfig
    try:
        if args.scenario in RECOVERY_SCENARIOS:
            config = RecoveryConfig(
                map=args.map,
                scenario=args.scenario,
                driver=args.driver,
                seeds=args.seeds,
                duration=args.duration,
                kidnap_time=args.kidnap_time,
                time_limit=args.time_limit,
                localization=recovery_localization(global_particles=args.particles),
                env=env,
            )
        else:
            if not args.uniform and not args.gaussian:
                parser.fail("--uniform/--gaussian", "both are empty: there is no run to make")
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
                env=env,
                filter_map=args.filter_map,
            )
        config.runs()  # every run's settings are valid
    except ValueError as exc:
        _config_error(parser, exc)
    check_resume(parser, config, out, args.resume)
    compile_notice()
    with output_folder(parser, out):
        options = {
            "workers": args.workers,
            "resume": args.resume,
            "plots": not args.no_plots,
            "executor": executor,
        }
        if isinstance(config, RecoveryConfig):
            report = run_recovery_experiment(config, out, **options)
            return _finish(out, [r.result.status for r in report.runs], report.failed)
        sweep = run_experiment(config, out, **options)
        return _finish(out, [r.status for r in sweep.results], sweep.failed)


def _finish(out: Path, statuses: list[str], failed: list[RunResult]) -> int:
    """Print the summary, the run counts and each failure; exit status 1 when a run failed."""
    print((out / "summary.md").read_text())
    ok, skipped = statuses.count("ok"), statuses.count("skipped")
    print(f"{ok} runs done, {skipped} skipped (complete logs), {len(failed)} failed")
    if failed:  # each failure was reported as it happened; name them once more, on one line
        ids = ", ".join(r.spec.run_id for r in failed)
        print(f"failed runs: {ids} (errors above and in summary.md)", file=sys.stderr)
    print(f"output folder: {out.resolve()}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
