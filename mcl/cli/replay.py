"""Replay a ROS bag (real lidar + odometry) through the particle filter on a map.

Reads ROS 1 .bag files and ROS 2 bags (sqlite3 or MCAP), runs the filter in recorded order from a
global start (or --init X,Y,THETA) and writes into --out:

    trajectory.csv  one row per scan: time,x,y,theta,n_particles,position_sd,heading_sd,ambiguous,
                    scan_fit (+ position_error,heading_error when the bag has /ground_truth)
    trajectory.png  the estimated path on the map with every k-th scan drawn from the estimate
    scan_fit.png    scan_fit (beams within 0.15 m of an exact cast from the estimate) and the
                    particle count against time
    replay.mp4      particles, scan and estimate at --video-fps frames per second of recording
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from mcl.cli.common import (
    Parser,
    check_map,
    check_out,
    non_negative_float,
    non_negative_int,
    output_folder,
    path_arg,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice, compile_report
from mcl.cli.live_options import (
    Pacer,
    add_live_arguments,
    check_live,
    start_live_view,
    stop_live_view,
)
from racecar_sim.file_guard import shown

EXAMPLES = """\
examples:
  racecar-sim replay ../shared/bags/localization_bag1_2022-03-29-19-23-29.bag \\
      --map ../shared/maps/stata_basement.yaml --out out/bag1
  racecar-sim replay out/drive_bag --map basement_loop --out out/roundtrip
  racecar-sim replay BAG --map MAP.yaml --init -20.9,-0.3,1.26 --seed 3 --out out/tracked
  racecar-sim replay BAG --map MAP.yaml --filter filter.kld.max_particles=3000 --out out/capped
"""


def build_parser() -> Parser:
    """The ``racecar-sim replay`` options."""
    parser = Parser("racecar-sim replay", __doc__, EXAMPLES)
    parser.add_argument(
        "bag", type=path_arg, nargs="?", help="a ROS 1 .bag, a ROS 2 bag folder, or its .mcap/.db3"
    )
    parser.add_argument(
        "--map",
        default=None,
        metavar="NAME|YAML",
        help="the map to localize on (required; a bundled name or a map_server YAML)",
    )
    parser.add_argument(
        "--out",
        type=path_arg,
        default=Path("out/replay"),
        metavar="DIR",
        help="output folder: a new or empty one, or one racecar-sim made",
    )
    parser.add_argument(
        "--init",
        default="global",
        metavar="global|X,Y,THETA",
        help="global start, or a base_link pose in the map frame (m, m, rad)",
    )
    parser.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="N", help="the filter's random seed"
    )
    parser.add_argument(
        "--filter", action="append", default=[], metavar="KEY=VALUE",
        help="a filter setting over the replay's own (LocalizationConfig, dotted, YAML values; "
        "repeatable; default: the adaptive filter of mcl.experiments.replay), e.g. "
        "filter.kld.max_particles=3000 or sensor.sigma_hit=2.0",
    )  # fmt: skip
    parser.add_argument("--scan-topic", default="/scan", metavar="T", help="LaserScan topic")
    parser.add_argument(
        "--odom-topic",
        default=None,
        metavar="T",
        help="Odometry topic (default: /vesc/odom, else /odom)",
    )
    parser.add_argument(
        "--mount-offset",
        type=float,
        default=None,
        metavar="M",
        help="metres from base_link to the lidar (default: from /tf_static, else 0.275)",
    )
    parser.add_argument(
        "--no-return",
        choices=("max", "drop"),
        default="max",
        help="weigh no-return beams as max-range readings, or drop them",
    )
    parser.add_argument(
        "--scan-every",
        type=positive_int,
        default=40,
        metavar="K",
        help="draw every K-th scan on trajectory.png",
    )
    parser.add_argument(
        "--video-fps",
        type=non_negative_float,
        default=10.0,
        metavar="FPS",
        help="video frames per second of recording (0: no video)",
    )
    add_live_arguments(parser, "replay")
    return parser


def _init(parser: Parser, text: str) -> str | tuple[float, float, float]:
    if text == "global":
        return "global"
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        parser.fail("--init", f"{text!r}: 'global' or three numbers X,Y,THETA")
    return values  # type: ignore[return-value]


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim replay``; returns the exit code (a user mistake exits with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from mcl.experiments.replay import ReplayConfig, replay, unknown_start_localization
    from mcl.experiments.replay_output import write_outputs
    from mcl.io import BagError, read_bag
    from mcl.wrappers.localization import dotted_settings
    from racecar_sim.maps import resolve_map
    from racecar_sim.settings.params import settings_over

    if args.bag is None:
        parser.fail("bag", "name the bag to replay (a ROS 1 .bag or a ROS 2 bag folder)")
    if args.map is None:
        parser.fail("--map", "required: the map the bag was recorded on")
    check_map(parser, args.map)
    init = _init(parser, args.init)
    try:
        settings = dotted_settings(args.filter)
        localization = settings_over(unknown_start_localization(), settings)
    except (TypeError, ValueError) as exc:
        parser.fail("--filter", str(exc))
    if "init" in settings:
        parser.fail("--filter", "init: give the start with --init")
    if args.mount_offset is not None and not (
        math.isfinite(args.mount_offset) and 0 <= args.mount_offset < 5
    ):
        parser.fail("--mount-offset", f"{args.mount_offset}: metres in [0, 5)")
    out: Path = check_out(parser, args.out)
    live = check_live(parser, args.live, args.live_speed)
    try:
        if not args.bag.exists():
            parser.fail("bag", f"{shown(args.bag)} does not exist")
        data = read_bag(args.bag, args.scan_topic, args.odom_topic, args.mount_offset)
    except BagError as exc:
        parser.fail("bag", str(exc))
    except OSError as exc:
        parser.fail("bag", f"{shown(args.bag)}: {exc.strerror or exc}")
    for w in data.warnings:
        print(f"warning: {w}", file=sys.stderr)
    print(data.summary())
    occupancy_map = resolve_map(args.map)
    config = ReplayConfig(
        init=init, seed=args.seed, no_return=args.no_return, localization=localization
    )
    compile_notice()
    server = start_live_view(parser, live)
    try:
        with output_folder(parser, out):
            on_scan = None
            if server is not None:
                from mcl.io.replay_stream import ReplayStream

                stream, pace = ReplayStream(data, occupancy_map, server), Pacer(args.live_speed)

                def on_scan(i: int, t: float, moved, pf) -> None:
                    stream(i, t, moved, pf)
                    pace(t)

            result = replay(data, occupancy_map, config, on_scan=on_scan)
            paths = write_outputs(result, occupancy_map, out, args.scan_every, args.video_fps)
            print(result.summary())
            print(f"wrote {', '.join(p.name for p in paths)}\noutput folder: {out.resolve()}")
            lost = result.not_found_warning()
            if lost is not None:
                print(f"warning: {lost}", file=sys.stderr)
    finally:
        stop_live_view(server)
    compile_report()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
