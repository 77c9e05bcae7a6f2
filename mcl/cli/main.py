"""``racecar-sim``: the console command, dispatching to one subcommand module each.

Subcommands: ``drive`` (a headless localized drive), ``experiment`` (noise sweep, global
localization, kidnapping), ``ablation`` (the recovery ablation), ``opponents`` (MCL among opponents), ``lost-flag`` (the lost flag judged against the truth), ``bench`` (benchmarks),
``race`` (N cars on a track, each with its driver), ``replay`` (a ROS bag through the filter), ``make-maps`` (draw the bundled maps), ``train-agent`` (PPO on the localized pose),
``calibrate-noise`` (a noise profile from real bags), ``update-map`` (a map updated from drives).
"""

from __future__ import annotations

import difflib
import importlib
import sys
from collections.abc import Sequence

SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "drive": (
        "mcl.cli.drive",
        "a headless localized drive on a map, with error log, plot and video",
    ),
    "experiment": ("mcl.cli.experiment", "the noise sweep, or global localization / kidnapping"),
    "ablation": ("mcl.cli.recovery_ablation", "the recovery experiment with one part switched off"),
    "race": ("mcl.cli.race", "N cars race on a track: drivers, speeds, laps, optional MCL per car"),
    "opponents": (
        "mcl.cli.opponents",
        "MCL error alone and among opponents, plain and beam skipping",
    ),
    "lost-flag": (
        "mcl.cli.lost_flag",
        "how right the lost flag is; recovery after kidnaps (table)",
    ),
    "replay": ("mcl.cli.replay", "replay a ROS 1 / ROS 2 bag through the filter on a map"),
    "bench": ("mcl.cli.bench", "benchmarks (racecar-sim bench lists them)"),
    "make-maps": ("mcl.cli.make_maps", "draw the bundled maps"),
    "train-agent": ("mcl.cli.train_agent", "PPO laps on the scan and a pose (extra [rl])"),
    "fast-laps": (
        "mcl.cli.fast_laps",
        "localization on fast laps: lab motion noise vs the alpha model",
    ),
    "update-map": (
        "mcl.cli.update_map",
        "an out-of-date map updated from simulated drives in the world as it is (map YAML)",
    ),
    "calibrate-noise": (
        "mcl.cli.calibrate_noise",
        "fit a simulator noise profile from real ROS bags (lidar and odometry)",
    ),
}
"""Subcommand name -> (module with ``main(argv)``, one-line description)."""


def _usage() -> str:
    width = max(len(n) for n in SUBCOMMANDS)
    rows = "\n".join(f"  {n:<{width}}  {d}" for n, (_, d) in SUBCOMMANDS.items())
    return (
        "usage: racecar-sim SUBCOMMAND [options]   (racecar-sim SUBCOMMAND --help for its options)\n\n"
        f"subcommands:\n{rows}\n\n"
        "examples:\n"
        "  racecar-sim drive --map office --duration 30 --out out/office\n"
        "  racecar-sim race --map basement_loop --out out/race\n"
        "  racecar-sim experiment --scenario global --seeds 20 --out runs/global\n"
        "  racecar-sim bench sim --quick\n"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``racecar-sim SUBCOMMAND ...``; returns the exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        print(_usage(), end="")
        return 0
    if args[0] == "--version":
        from racecar_sim import __version__

        print(f"racecar-sim {__version__}")
        return 0
    name, rest = args[0], args[1:]
    if name not in SUBCOMMANDS:
        close = difflib.get_close_matches(name, list(SUBCOMMANDS), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        print(
            f"racecar-sim: error: unknown subcommand {name!r}{hint}; choose from "
            f"{', '.join(SUBCOMMANDS)} (racecar-sim --help)",
            file=sys.stderr,
        )
        return 2
    module = importlib.import_module(SUBCOMMANDS[name][0])
    try:
        result = module.main(rest)
    except KeyboardInterrupt:
        print(f"racecar-sim {name}: interrupted", file=sys.stderr)
        return 130
    return result if isinstance(result, int) else 0


if __name__ == "__main__":
    sys.exit(main())
