"""``racecar-sim update-map``: a map updated from simulated drives in the world as it is now.

Drives the world ``--map`` (the car's lidar and odometry, ``--noise-profile``, each ``--scene``,
seeds ``--seed`` .. ``--seed + --drives - 1``), localizes every drive on the out-of-date map
``--filter-map`` with the filter's defaults (or ``--filter``), counts what the scans saw through
that map's walls at the filter's own estimates, and opens the cells enough drives agree on
(``mcl.mapping.update_from_drives``; the rule's settings with ``--param``, fields of
``mcl.mapping.MapUpdateParams``). The updated map is written to ``--out`` as a map_server YAML
and PGM, new files only (``racecar_sim.maps.writer.save_map``); use it with ``racecar-sim drive
--filter-map``. No true pose is used: the world map only makes the simulated drives.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mcl.cli.common import (
    ENV_HELP,
    MAP_HELP,
    Parser,
    check_env,
    check_env_builds,
    check_map,
    duration_seconds,
    non_negative_int,
    path_arg,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice
from mcl.cli.filter_map_option import check_filter_map
from mcl.cli.out_paths import check_new_files
from mcl.experiments.recorded import RecordedDrive, record_drive
from mcl.experiments.runs import DRIVERS
from mcl.mapping import MapUpdateParams, update_from_drives
from mcl.wrappers.localization import as_localization_config, dotted_settings
from racecar_sim.file_guard import shown
from racecar_sim.maps import DEFAULT_MAP, resolve_map
from racecar_sim.maps.writer import save_map
from racecar_sim.settings.params import from_mapping
from racecar_sim.world.scenes import SCENES

EXAMPLES = """examples:
  racecar-sim update-map --map ../shared/maps/basement_fixed_aligned.yaml --filter-map ../shared/maps/stata_basement.yaml --noise-profile mit_racecar --out out/stata_updated.yaml
  racecar-sim update-map --map office --filter-map old_office.yaml --drives 8 --duration 30 --param drives_needed=3 --out out/office_updated.yaml
"""


def build_parser() -> Parser:
    """The ``racecar-sim update-map`` options."""
    parser = Parser("racecar-sim update-map", __doc__, EXAMPLES)
    add = parser.add_argument
    add("--map", default=DEFAULT_MAP, metavar="NAME|YAML",
        help=f"the world the drives are made in: {MAP_HELP}")  # fmt: skip
    add("--filter-map", default=None, metavar="NAME|YAML",
        help="the out-of-date map to update (same world frame as --map; required, no default)")  # fmt: skip
    add("--out", type=path_arg, default=None, metavar="FILE.yaml",
        help="the updated map: a new .yaml file (its .pgm is written beside it; neither may "
        "exist; required, no default)")  # fmt: skip
    add("--scene", action="append", choices=sorted(SCENES), default=None, metavar="SCENE",
        help=f"a scene of obstacles the drives are made in ({', '.join(sorted(SCENES))}; "
        "repeatable; default: cluttered and clean)")  # fmt: skip
    add("--drives", type=positive_int, default=20, metavar="N", help="drives per scene")
    add("--seed", type=non_negative_int, default=0, metavar="N", help="the first drive's seed")
    add("--duration", type=duration_seconds, default=60.0, metavar="S",
        help="simulated seconds per drive")  # fmt: skip
    add("--driver", choices=sorted(DRIVERS), default="wall", help="who steers the drives")
    add("--noise-profile", default=None, metavar="NAME",
        help="simulator noise profile, e.g. mit_racecar (default: the simulator's own settings)")  # fmt: skip
    add("--env", action="append", default=[], metavar="NAME=VALUE", help=ENV_HELP)
    add("--filter", action="append", default=[], metavar="KEY=VALUE",
        help="a filter setting other than the defaults, as in racecar-sim drive")  # fmt: skip
    add("--param", action="append", default=[], metavar="KEY=VALUE",
        help="a setting of the update rule (MapUpdateParams, YAML values; repeatable), "
        "e.g. drives_needed=3")  # fmt: skip
    add("--quiet", action="store_true", help="no progress bar")
    return parser


def _check_out(parser: Parser, out: Path) -> Path:
    """``--out`` is a new ``.yaml`` whose ``.pgm`` is new too, in a folder we may write into."""
    if out.suffix != ".yaml":
        parser.fail("--out", f"{shown(out)} must end in .yaml (the map's YAML; its .pgm goes beside it)")
    check_new_files(parser, (out, out.with_suffix(".pgm")), "--out")
    return out


def _params(parser: Parser, items: list[str]) -> MapUpdateParams:
    try:
        return from_mapping(MapUpdateParams, dotted_settings(items))
    except (TypeError, ValueError) as exc:
        parser.fail("--param", str(exc))


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim update-map``; returns the exit code (a user mistake exits with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    for flag, value in (("--filter-map", args.filter_map), ("--out", args.out)):
        if value is None:
            parser.fail(flag, "is required (racecar-sim update-map --help)")
    if args.noise_profile is not None:
        args.env.append(f"noise_profile={args.noise_profile}")
    env = check_env(parser, args.env)
    check_map(parser, args.map, env=env)
    check_map(parser, args.filter_map, "--filter-map", env=env)
    check_filter_map(parser, args.map, args.filter_map, env)
    out = _check_out(parser, args.out)
    params = _params(parser, args.param)
    try:
        config = as_localization_config(dotted_settings(args.filter))
    except (TypeError, ValueError) as exc:
        parser.fail("--filter", str(exc))
    settings: dict[str, Any] = dict(env)
    env_scene = settings.pop("scene", None)  # one scene given as --env scene=NAME
    scenes = args.scene or ([env_scene] if env_scene is not None else ["cluttered", "clean"])
    for scene in dict.fromkeys(scenes):  # each scene's obstacles find room on the world map
        check_env_builds(parser, args.map, (*settings.items(), ("scene", scene)), args.seed)
    jobs = [(scene, args.seed + i) for scene in scenes for i in range(args.drives)]

    def drives() -> Iterator[RecordedDrive]:
        for scene, seed in _bar(jobs, not args.quiet):
            yield record_drive(args.map, filter_map=args.filter_map, scene=scene,
                               driver=args.driver, seed=seed, duration=args.duration,
                               env=settings)  # fmt: skip

    compile_notice()
    old = resolve_map(args.filter_map, settings.get("max_map_cells"))
    update = update_from_drives(drives(), old, config, params)
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        written = save_map(update.map, out)
    except FileExistsError as exc:  # made by someone else while the drives ran
        parser.fail("--out", f"{exc}; nothing written")
    print(
        f"{int(update.opened.sum())} cells opened ({update.opened.sum() * old.resolution**2:.1f} m²) "
        f"from {update.scans} scans of {update.drives} drives; wrote {written} and "
        f"{written.with_suffix('.pgm').name}"
    )
    return 0


def _bar(jobs: list[tuple[str, int]], show: bool) -> Any:
    if not show:
        return jobs
    from tqdm import tqdm

    return tqdm(jobs, desc="drives (recorded, localized)", unit="drive")
