"""``racecar-sim fast-laps``: localization on fast laps, the lab's motion noise against the alpha
model ([`mcl.experiments.fast_laps`][mcl.experiments.fast_laps]; results in docs/odometry.md)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from mcl.cli.common import (
    ENV_HELP,
    Parser,
    check_env,
    check_map,
    check_out,
    duration_seconds,
    output_folder,
    path_arg,
    positive_float,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice

EXAMPLE = """examples:
  racecar-sim fast-laps --env car_model=single_track --seeds 5 --duration 60 --out runs/fast_laps
"""


DESCRIPTION = (
    "Localization on fast laps: pure pursuit round the map's loop at --speed, the lab's motion "
    "noise against the alpha model (results: docs/odometry.md)."
)


def build_parser() -> Parser:
    """The command line of ``racecar-sim fast-laps``."""
    parser = Parser("racecar-sim fast-laps", DESCRIPTION, EXAMPLE)
    add = parser.add_argument
    add("--out", type=path_arg, default=Path("runs/fast_laps"),
        help="output folder (config.json, logs/, summary.md): a new or empty one, or one "
        "racecar-sim made")  # fmt: skip
    add("--map", default="basement_loop", help="bundled map with a known loop")
    add("--speed", type=positive_float, default=6.0, help="m/s the car holds, corners included")
    add(
        "--seeds",
        type=positive_int,
        default=5,
        help="runs per motion model (starts round the loop)",
    )
    add("--duration", type=duration_seconds, default=60.0, help="simulated seconds per run")
    add("--particles", type=positive_int, default=1500, help="particles per filter")
    add("--workers", type=positive_int, default=None, help="processes (default: the CPU count)")
    add("--env", action="append", default=[], metavar="NAME=VALUE", help=ENV_HELP)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the fast-lap experiment; prints its table and writes OUT/summary.md."""
    parser = build_parser()
    args = parser.parse_args(argv)
    grid = check_map(parser, args.map)
    env = check_env(parser, args.env)
    out = check_out(parser, args.out)
    from mcl.agents.track import loop_maps
    from mcl.experiments.fast_laps import FastLapConfig, markdown_table, run_fast_laps

    if grid not in loop_maps():
        parser.fail("--map", f"no loop known for {grid!r}; maps with a loop: {loop_maps()}")
    cfg = FastLapConfig(
        map=grid, speed=args.speed, seeds=args.seeds, duration=args.duration,
        n_particles=args.particles, env=dict(env),
    )  # fmt: skip
    compile_notice()
    with output_folder(parser, out):
        rows, _ = run_fast_laps(cfg, out, workers=args.workers, progress=True)
    print(markdown_table(rows, cfg.diverged_m))
    print(f"wrote {out / 'summary.md'}")
    return 0
