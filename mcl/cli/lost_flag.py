"""racecar-sim lost-flag: how right the filter's ``lost`` flag is, and how fast a kidnapped filter
finds the car again ([`mcl.experiments.lost_flag`][mcl.experiments.lost_flag]).

Per world, tracking drives (the honest world: Stata with the ``mit_racecar`` noise, the cluttered
and the clean scene, the filter holding the old map) and kidnap drives (the same worlds and the
bundled basement_loop). The flag is judged against the truth (position error > 1 m): precision,
recall, false alarms on the steps under 0.3 m; after a kidnap, the time to flag and to recover
(error under 0.5 m for 2 s). The markdown table goes to --out/results.md and to stdout.

The filter of the honest world holds another map with --filter-map YAML (e.g. one that
``racecar-sim update-map`` brought up to date, in the same world frame).

Filter settings other than the defaults: --filter KEY=VALUE (repeatable, YAML values), e.g.
--filter sensor.sigma_hit=2.0 --filter lost.raise_below=0.35.

Each drive's filter draws its motion noise and resampling from a generator seeded by the drive's
seed; --filter-seed-offset N seeds it by the seed + N instead, so the same drives (the same
kidnaps) are localized with another draw, to tell a change from the luck of one draw.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from mcl.cli.common import (
    Parser,
    check_map,
    check_out,
    check_resume,
    duration_seconds,
    non_negative_int,
    output_folder,
    path_arg,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice
from mcl.cli.filter_map_option import check_filter_map
from mcl.experiments.lost_flag import LostFlagConfig, default_worlds, run_lost_flag
from mcl.wrappers.localization import as_localization_config, dotted_settings

EXAMPLES = """\
examples:
  racecar-sim lost-flag --out runs/lost_flag
  racecar-sim lost-flag --seeds 3 --kidnap-seeds 3 --worlds basement_loop --out runs/lost_quick
  racecar-sim lost-flag --filter sensor.sigma_hit=2.0 --out runs/lost_flag_sigma2
  racecar-sim lost-flag --filter-map out/stata_updated.yaml --worlds cluttered clean --out runs/lost_updated
  racecar-sim lost-flag --seeds 0 --kidnap-seeds 20 --worlds cluttered clean --filter-seed-offset 1000 --out runs/kidnaps_draw2
"""


def build_parser() -> Parser:
    """The ``racecar-sim lost-flag`` options."""
    parser = Parser("racecar-sim lost-flag", __doc__, EXAMPLES)
    add = parser.add_argument
    add("--shared", type=path_arg, default=Path("../shared"), metavar="DIR",
        help="the real-data folder holding maps/basement_fixed_aligned.yaml and stata_basement.yaml")  # fmt: skip
    add("--filter-map", type=path_arg, default=None, metavar="YAML",
        help="the map the honest world's filter holds (default: stata_basement.yaml in --shared)")  # fmt: skip
    add("--worlds", nargs="+", default=None, metavar="NAME",
        help="worlds to run (default: cluttered clean basement_loop)")  # fmt: skip
    add("--seeds", type=non_negative_int, default=10, metavar="N", help="tracking drives per world")
    add("--kidnap-seeds", type=non_negative_int, default=5, metavar="N",
        help="kidnap drives per world")  # fmt: skip
    add("--duration", type=duration_seconds, default=60.0, metavar="S",
        help="seconds of a tracking drive")  # fmt: skip
    add("--kidnap-time", type=duration_seconds, default=10.0, metavar="S",
        help="seconds after reset at which the car is kidnapped")  # fmt: skip
    add("--after-kidnap", type=duration_seconds, default=20.0, metavar="S",
        help="seconds driven after the kidnap")  # fmt: skip
    add("--filter-seed-offset", type=non_negative_int, default=0, metavar="N",
        help="seed each drive's filter by its seed + N: the same drives, another draw of the "
             "filter's random numbers (default: 0, the drive's seed)")  # fmt: skip
    add("--filter", action="append", default=[], metavar="KEY=VALUE",
        help="a filter setting (LocalizationConfig, dotted: sensor.sigma_hit=2.0, lost.window_s=1)")  # fmt: skip
    add("--workers", type=positive_int, default=None, metavar="N",
        help="processes (default: the number of cores)")  # fmt: skip
    add("--resume", action="store_true", help="skip runs whose log is complete")
    add("--out", type=path_arg, default=Path("runs/lost_flag"), metavar="DIR",
        help="output folder: a new or empty one, or one racecar-sim made")  # fmt: skip
    return parser


def filter_settings(parser: Parser, items: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` items as a nested mapping of [`LocalizationConfig`][mcl.wrappers.localization.LocalizationConfig]
    fields ([dotted_settings][mcl.wrappers.localization.dotted_settings]); a malformed item fails
    naming ``--filter``."""
    try:
        return dotted_settings(items)
    except ValueError as exc:
        parser.fail("--filter", str(exc))


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim lost-flag``; returns the exit code (1: a run failed; 2: a user mistake)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    filter_map = None if args.filter_map is None else str(args.filter_map)
    worlds = default_worlds(args.shared, filter_map)
    names = [w.name for w in worlds]
    chosen = args.worlds if args.worlds is not None else names
    unknown = [n for n in chosen if n not in names]
    if unknown:
        parser.fail("--worlds", f"unknown world(s) {unknown}; choose from {names}")
    worlds = tuple(w for w in worlds if w.name in chosen)
    for w in worlds:
        if Path(w.map).suffix == ".yaml" and not Path(w.map).is_file():
            parser.fail("--shared", f"{w.map} not found (the real-data folder, README)")
        if w.filter_map is not None and filter_map is None and not Path(w.filter_map).is_file():
            parser.fail("--shared", f"{w.filter_map} not found (the real-data folder, README)")
    if filter_map is not None:
        honest = [w for w in worlds if w.filter_map is not None]
        if not honest:
            parser.fail("--filter-map", "only the honest worlds (cluttered, clean) hold a filter map")
        check_map(parser, filter_map, "--filter-map")
        check_filter_map(parser, honest[0].map, filter_map)
    try:
        localization = as_localization_config(filter_settings(parser, args.filter))
    except (TypeError, ValueError) as exc:
        parser.fail("--filter", str(exc))
    config = LostFlagConfig(
        worlds=worlds, seeds=args.seeds, kidnap_seeds=args.kidnap_seeds, duration=args.duration,
        kidnap_time=args.kidnap_time, after_kidnap=args.after_kidnap, localization=localization,
        filter_seed_offset=args.filter_seed_offset,
    )  # fmt: skip
    if not config.runs():
        parser.fail("--seeds", "no drives to run (--seeds and --kidnap-seeds are both 0)")
    out: Path = check_out(parser, args.out)
    check_resume(parser, config, out, args.resume)
    compile_notice()
    with output_folder(parser, out):
        table = run_lost_flag(config, out, workers=args.workers, resume=args.resume, progress=False)
    print(table, end="")
    return 1 if "failed)" in table else 0


if __name__ == "__main__":
    sys.exit(main())
