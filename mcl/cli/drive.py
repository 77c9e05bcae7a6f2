"""Main job: a headless localized drive, wall following with MCL in the loop.

Drives ~60 s of simulated time on the default bundled map (or ``--map``), with a particle filter
(mcl.LocalizationWrapper) tracking the car from its odometry and lidar. Prints the error summary
and writes into ``--out``:

    error_log.csv   one row per step: true pose, estimate, position / heading error, n_eff, time
    error.png       position and heading error against time
    drive.mp4       render() frames (map, scan, car, particles, estimate, with a legend) at --video-fps
                    (drive_frames/*.png instead when OpenCV cannot write mp4)

With ``--bag DIR`` the drive is also recorded as a ROS 2 bag with MCAP storage (scans, odometry,
tf, ground truth, the filter's pose and particles, the map; [`mcl.io.DriveRecorder`][mcl.io.DriveRecorder],
attached to the drive's wrapper as a step hook), which ``racecar-sim replay DIR --map MAP`` reads
back and scores against the ground truth.

With ``--live [HOST:]PORT`` the same messages stream to Foxglove as the drive runs (a WebSocket
server on 127.0.0.1 unless a host is given; [`mcl.io.live`][mcl.io.live]), paced at ``--live-speed`` times
real time (0: as fast as it runs).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from mcl.cli.common import (
    ENV_HELP,
    MAP_HELP,
    Parser,
    check_bag,
    check_env,
    check_env_builds,
    check_map,
    check_out,
    duration_seconds,
    non_negative_float,
    non_negative_int,
    output_folder,
    path_arg,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice, compile_report
from mcl.cli.filter_map_option import check_filter_map
from mcl.cli.live_options import (
    Pacer,
    add_live_arguments,
    check_live,
    start_live_view,
    stop_live_view,
)
from mcl.experiments.frame_text import draw_legend
from mcl.experiments.metrics import DIVERGED_M
from mcl.experiments.plots import plot_error_vs_time
from mcl.experiments.runs import DRIVERS, RunSpec, run_one
from mcl.experiments.video import FrameWriter
from mcl.filter.params import DEFAULT_PARTICLES
from mcl.io import DriveRecorder
from mcl.io.bag_writer import LIVE_RATE, UNPACED_LIVE_RATE
from mcl.io.live import LiveServer
from mcl.wrappers.error_log import read_error_log
from mcl.wrappers.hooks import StepHook, StepRecord
from mcl.wrappers.localization import as_localization_config, dotted_settings
from mcl.wrappers.single import LocalizationWrapper
from racecar_sim.maps import DEFAULT_MAP
from racecar_sim.render import CAR_COLOUR, ESTIMATE_COLOUR, PARTICLE_COLOUR, SCAN_COLOUR

DRIVE_LEGEND = (
    ("car (true pose)", CAR_COLOUR, "box"),
    ("lidar hits", SCAN_COLOUR, "dots"),
    ("particles", PARTICLE_COLOUR, "dots"),
    ("MCL estimate", ESTIMATE_COLOUR, "arrow"),
)
"""What a drive's frame draws (LocalizationWrapper.render), in its colours."""


def _caption(frame: np.ndarray, info: dict[str, Any]) -> np.ndarray:
    """Write the time and the current errors in the frame's top-left corner and the legend in its
    top-right corner (in place)."""
    loc = info["localization"]
    text = (
        f"t {info['time']:5.1f} s   error {loc['position_error']:.3f} m  "
        f"{math.degrees(loc['heading_error']):+.1f} deg   n_eff {loc['n_eff']:.0f}"
    )
    cv2.putText(frame, text, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    draw_legend(frame, DRIVE_LEGEND, "top-right")
    return frame


EXAMPLES = """\
examples:
  racecar-sim drive                                   60 s on basement_loop into out/drive
  racecar-sim drive --map office --duration 30 --out out/office
  racecar-sim drive --map ../shared/maps/stata_basement.yaml --driver pursuit
  racecar-sim drive --env lidar_rate=20 --env range_sigma=0.05 --video-fps 0 --quiet
"""


def build_parser() -> Parser:
    """The ``racecar-sim drive`` options."""
    parser = Parser("racecar-sim drive", __doc__, EXAMPLES)
    parser.add_argument("--map", default=DEFAULT_MAP, metavar="NAME|YAML", help=MAP_HELP)
    parser.add_argument(
        "--out",
        type=path_arg,
        default=Path("out/drive"),
        metavar="DIR",
        help="output folder: a new or empty one, or one racecar-sim made",
    )
    parser.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="N", help="start pose and noise seed"
    )
    parser.add_argument(
        "--duration",
        type=duration_seconds,
        default=60.0,
        metavar="S",
        help="simulated seconds (at most a day)",
    )
    parser.add_argument(
        "--particles",
        type=positive_int,
        default=DEFAULT_PARTICLES,
        metavar="N",
        help="particles of the filter",
    )
    parser.add_argument(
        "--driver",
        choices=sorted(DRIVERS),
        default="wall",
        help="wall: follow the right wall; pursuit: pure pursuit around the loop the wall "
        "follower records first",
    )
    parser.add_argument("--env", action="append", default=[], metavar="NAME=VALUE", help=ENV_HELP)
    parser.add_argument(
        "--filter", action="append", default=[], metavar="KEY=VALUE",
        help="a filter setting other than the defaults (LocalizationConfig, dotted, YAML values; "
        "repeatable), e.g. filter.odometry_scale.learn=false; the motion noise as motion.*",
    )  # fmt: skip
    parser.add_argument(
        "--filter-map",
        default=None,
        metavar="NAME|YAML",
        help="the map the filter holds when the world (--map) differs from it (same world frame; "
        "default: the --map itself)",
    )
    parser.add_argument(
        "--noise-profile",
        default=None,
        metavar="NAME",
        help="simulator noise profile, e.g. mit_racecar (= --env noise_profile=NAME; default: none, "
        "the simulator's own settings)",
    )
    parser.add_argument(
        "--video-fps",
        type=non_negative_float,
        default=10.0,
        metavar="FPS",
        help="video frames per simulated second (0: no video)",
    )
    parser.add_argument(
        "--bag",
        type=path_arg,
        default=None,
        metavar="BAGDIR",
        help="also record the drive as a ROS 2 / MCAP bag in this new folder, outside --out (an "
        "existing folder is replaced only when it holds exactly an earlier recording; default: "
        "no bag)",
    )
    add_live_arguments(parser, "drive")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim drive``; returns the exit code (a user mistake exits with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.noise_profile is not None:
        args.env.append(f"noise_profile={args.noise_profile}")
    env = check_env(parser, args.env)
    check_map(parser, args.map, env=env)
    if args.filter_map is not None:
        check_map(parser, args.filter_map, "--filter-map", env=env)
        check_filter_map(parser, args.map, args.filter_map, env)
    out: Path = check_out(parser, args.out)
    if args.bag is not None:
        check_bag(parser, args.bag, out)
    live = check_live(parser, args.live, args.live_speed)
    try:
        settings = dotted_settings(args.filter)
        config = as_localization_config(settings)
    except (TypeError, ValueError) as exc:
        parser.fail("--filter", str(exc))
    if "n_particles" in settings.get("filter", {}):  # --particles sets the count
        parser.fail("--filter", "filter.n_particles: give the count with --particles")
    try:
        spec = RunSpec(
            map=str(args.map),
            driver=args.driver,
            motion=config.motion,
            seed=args.seed,
            duration=args.duration,
            n_particles=args.particles,
            series="drive",
            env=env,
            filter_map=args.filter_map,
            config=config,
        )
    except ValueError as exc:
        if "particles" in str(exc):
            parser.fail("--particles", str(exc))
        parser.error(str(exc))
    check_env_builds(parser, args.map, env, args.seed)
    compile_notice()
    server = start_live_view(parser, live)
    try:
        with output_folder(parser, out):
            return _drive(
                spec, out, args.video_fps, not args.quiet, args.bag, server, args.live_speed
            )
    finally:
        stop_live_view(server)


def _drive(
    spec: RunSpec,
    out: Path,
    video_fps: float,
    progress: bool,
    bag: Path | None = None,
    live: LiveServer | None = None,
    live_speed: float = 0.0,
) -> int:
    """The drive into the existing folder ``out``, then the summary."""
    log_path = out / "error_log.csv"
    video = None
    on_frame = None
    frame_every = 1
    if video_fps > 0:
        frame_every = max(1, round(1.0 / (video_fps * spec.dt)))
        video = FrameWriter(out / "drive.mp4", fps=1.0 / (frame_every * spec.dt))

        def on_frame(frame: np.ndarray, info: dict[str, Any]) -> None:
            video.write(_caption(frame, info))

    recorder: list[DriveRecorder] = []
    pace = Pacer(live_speed if live is not None else 0.0)

    def step_hooks(wrapped: LocalizationWrapper) -> list[StepHook]:
        """The wrapper's one step hook: the bag and / or the live view, then the pace."""

        def record(step: StepRecord) -> None:
            if not recorder:  # made at the reset's record, so a drive that fails first leaves no bag
                # the live view: 20 frames a second of simulated time and of wall time (a drive
                # faster than real time streams a screen's worth, not every frame); 10 unpaced
                wall = LIVE_RATE if live_speed > 0 else UNPACED_LIVE_RATE
                recorder.append(DriveRecorder(bag, wrapped, live=live, live_wall_rate=wall))
            recorder[0](step)
            pace(step.time)

        return [record]

    t0 = time.perf_counter()
    try:
        result = run_one(
            spec,
            log_path,
            on_frame=on_frame,
            frame_every=frame_every,
            progress=progress,
            step_hooks=step_hooks if bag is not None or live is not None else None,
        )
    finally:
        if video is not None:
            video.close()
        for r in recorder:
            r.close()
    wall = time.perf_counter() - t0
    plot_path = plot_error_vs_time(
        read_error_log(log_path),
        out / "error.png",
        f"MCL on {Path(spec.map).stem}: {spec.driver} driver, {spec.n_particles} particles, "
        f"seed {spec.seed}",
        DIVERGED_M,
    )
    s = result.stats
    assert s is not None
    print(
        f"Localized drive on {Path(spec.map).stem}: {s.duration:.1f} s simulated in {wall:.2f} s "
        f"of wall time ({s.n_steps} steps, {spec.n_particles} particles, "
        f"{result.n_collisions} steps touching a wall)"
    )
    print(
        f"position error: mean {s.mean_error:.3f} m, median {s.median_error:.3f} m, "
        f"p95 {s.p95_error:.3f} m, max {s.max_error:.3f} m"
    )
    print(
        f"heading error: mean |error| {math.degrees(s.mean_heading_error):.2f} deg; "
        f"diverged (> {DIVERGED_M:g} m) {100 * s.diverged_fraction:.1f}% of the time; "
        f"filter update {1e3 * s.mean_update_s:.1f} ms"
    )
    print(f"wrote {log_path.name}, {plot_path.name}", end="")
    if video is not None:
        kind = "mp4" if video.kind == "mp4" else "PNG frames"
        print(f", {video.path.name} ({video.n_frames} frames, {kind})", end="")
    if bag is not None:
        print(f"\nrecorded the drive as a ROS 2 / MCAP bag: {bag.resolve()}", end="")
    print(f"\noutput folder: {out.resolve()}")
    compile_report()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
