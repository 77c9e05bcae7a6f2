"""A race: N cars on a map's track, each driven by one of the project's drivers at its own speed,
optionally each with its own particle filter, driving on its estimate.

Prints the results table and writes into ``--out``:

    results.csv   one row per car by finishing position: position, car, driver, speed, grid
                  slot, laps, best lap, lap times, distance, overtakes and times overtaken,
                  wall and car contacts, MCL error
    results.md    the same as a Markdown table
    race.mp4      the race at --video-fps: every car in its colour with its number, (localized)
                  its estimate and particles, and a panel with the race clock, the laps, the
                  standings and a legend (race_frames/*.png when OpenCV cannot write mp4)

With ``--live [HOST:]PORT`` the race streams to Foxglove as it runs (the map, every car's pose
and, localized, its estimate and particles; mcl.io.race_stream), paced at ``--live-speed``
times real time.

The default race is 4 cars on the default map (basement_loop) for 60 s, racing drivers at 2.0,
2.4, 2.8 and 3.2 m/s that know the other cars (they follow, pass where the track is wide enough
and give way), the slowest on pole: the faster cars come up behind the slower ones and pass them.
Drivers blind to the others (pursuit, wall, a policy) start from the fastest on pole instead,
unless --grid says otherwise: from behind, pure pursuit runs into the car ahead.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from mcl.cli.common import (
    ENV_HELP,
    MAP_HELP,
    Parser,
    check_env,
    check_map,
    check_out,
    non_negative_float,
    non_negative_int,
    number_list,
    output_folder,
    positive_float,
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
from mcl.experiments.race_drivers import DRIVER_NAMES, DriverError, DriverSpec, parse_drivers
from mcl.experiments.race_run import GRID_ORDERS, RaceSetup, RaceSpec
from racecar_sim.maps import DEFAULT_MAP

EXAMPLES = """\
examples:
  racecar-sim race --map basement_loop --out out/race      4 racing cars, 60 s, table, race.mp4
  racecar-sim race --map office --cars 6 --laps 3 --out out/office_race
  racecar-sim race --cars 3 --drivers wall,pursuit,pursuit --speeds 2.2,2.6,3.0 --laps 2
  racecar-sim race --localize --particles 500 --duration 30 --out out/race_mcl
  racecar-sim race --cars 2 --drivers pursuit,policy:runs/agent/truth/model.zip
  racecar-sim race --map my_map.yaml --track my_centerline.csv --video-fps 0
"""

DEFAULT_CARS = 4


def default_speeds(n_cars: int) -> tuple[float, ...]:
    """2.0, 2.4, 2.8, ... m/s (each car its own speed), at most 4.4 m/s."""
    return tuple(round(min(2.0 + 0.4 * k, 4.4), 2) for k in range(n_cars))


def build_parser() -> Parser:
    """The ``racecar-sim race`` options."""
    parser = Parser("racecar-sim race", __doc__, EXAMPLES)
    add = parser.add_argument
    add("--map", default=DEFAULT_MAP, metavar="NAME|YAML", help=MAP_HELP)
    add(
        "--track",
        default=None,
        metavar="CSV",
        help="the track's centerline, f1tenth's CSV (x_m, y_m, w_tr_right_m, w_tr_left_m; "
        "default: the map's own on basement_loop and office)",
    )
    add("--out", type=Path, default=Path("out/race"), metavar="DIR", help="output folder")
    add("--cars", type=positive_int, default=DEFAULT_CARS, metavar="N", help="cars in the race")
    add(
        "--drivers",
        default="racing",
        metavar="LIST",
        help="one driver, or one per car, comma-separated: "
        + "; ".join(f"{k}: {v}" for k, v in DRIVER_NAMES.items()),
    )
    add(
        "--speeds",
        type=number_list,
        default=None,
        metavar="LIST",
        help="m/s, one for every car or one per car (the racing driver's top speed, the wall "
        "follower's on a straight, pure pursuit's, the most a policy gets; default: 2.0, 2.4, "
        "2.8, ... per car)",
    )
    add(
        "--grid",
        choices=GRID_ORDERS,
        default=None,
        help="the start grid's order: the slowest car on pole, the fastest, or car 0 first "
        "(default: slowest-first with racing drivers, fastest-first when a car's driver is "
        "blind to the others)",
    )
    add(
        "--duration",
        type=positive_float,
        default=60.0,
        metavar="S",
        help="simulated seconds at most",
    )
    add(
        "--laps",
        type=positive_int,
        default=None,
        metavar="N",
        help="end when the first car completes N laps (default: race --duration seconds)",
    )
    add(
        "--localize",
        action="store_true",
        help="a particle filter per car (beam skipping on); the cars steer on their estimates "
        "(racing drivers still see every car where it is, as an opponent does)",
    )
    add(
        "--particles",
        type=positive_int,
        default=1000,
        metavar="N",
        help="particles per car's filter, with --localize",
    )
    add(
        "--seed",
        type=non_negative_int,
        default=0,
        metavar="N",
        help="the race's seed (car i: seed + i)",
    )
    add("--env", action="append", default=[], metavar="NAME=VALUE", help=ENV_HELP)
    add(
        "--video-fps",
        type=non_negative_float,
        default=10.0,
        metavar="FPS",
        help="video frames per simulated second (0: no video)",
    )
    add_live_arguments(parser, "race")
    add("--quiet", action="store_true", help="no progress bar")
    return parser


def _drivers(parser: Parser, text: str, n_cars: int) -> tuple[DriverSpec, ...]:
    try:
        specs = parse_drivers(text, n_cars)
    except ValueError as exc:
        parser.fail("--drivers", str(exc))
    for spec in specs:
        if spec.path is not None and not spec.path.is_file():
            parser.fail("--drivers", f"policy file {spec.path} does not exist")
    return specs


def default_grid(drivers: tuple[DriverSpec, ...]) -> str:
    """``slowest-first`` when every car has the racing driver (the faster cars pass), else
    ``fastest-first`` (a driver blind to the others would run into a slower car ahead)."""
    return "slowest-first" if all(d.kind == "racing" for d in drivers) else "fastest-first"


def _speeds(parser: Parser, given: tuple[float, ...] | None, n_cars: int) -> tuple[float, ...]:
    if given is None:
        return default_speeds(n_cars)
    if len(given) == 1:
        return given * n_cars
    if len(given) != n_cars:
        parser.fail("--speeds", f"{len(given)} speeds for {n_cars} cars: give one, or one per car")
    return given


def _setup(parser: Parser, spec: RaceSpec, render: bool) -> RaceSetup:
    """Build the race and its drivers, and check the grid, or stop naming the flag at fault."""
    from mcl.experiments.race_run import setup_race, start_poses
    from racecar_sim.maps import MapError
    from racecar_sim.race.env import MAX_CARS

    if spec.n_cars > MAX_CARS:
        parser.fail("--cars", f"{spec.n_cars} cars: at most {MAX_CARS} race together")
    try:
        setup = setup_race(spec, render)
    except DriverError as exc:
        parser.fail("--drivers", str(exc))
    except MapError as exc:
        parser.fail("--map", str(exc))
    except ValueError as exc:
        parser.fail("--track" if spec.track is not None else "--map", str(exc))
    top = setup.race.car_params.max_speed
    if max(spec.speeds) > top:
        parser.fail(
            "--speeds", f"{max(spec.speeds):g} m/s is faster than the car's top speed, {top:g} m/s"
        )
    try:
        start_poses(setup.race, spec)
    except ValueError as exc:
        parser.fail("--cars", f"{exc} (--cars {spec.n_cars})")
    return setup


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim race``; returns the exit code (a user mistake exits with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    env = check_env(parser, args.env)
    for name, flag in (("track", "--track"), ("terminate_on_collision", None)):
        if name in dict(env):
            parser.fail(
                f"--env {name}",
                f"set the track with {flag}"
                if flag
                else "a race keeps every car racing after a contact and counts the contacts",
            )
    check_map(parser, args.map, env=env)
    if args.track is not None and not Path(args.track).is_file():
        parser.fail("--track", f"{args.track} does not exist")
    out: Path = check_out(parser, args.out)
    n = args.cars
    drivers = _drivers(parser, args.drivers, n)
    spec = RaceSpec(
        map=str(args.map),
        drivers=drivers,
        speeds=_speeds(parser, args.speeds, n),
        duration=args.duration,
        laps=args.laps,
        track=args.track,
        grid=args.grid or default_grid(drivers),
        localize=args.localize,
        particles=args.particles,
        seed=args.seed,
        env=env,
    )
    live = check_live(parser, args.live, args.live_speed)
    compile_notice()
    setup = _setup(parser, spec, render=args.video_fps > 0)
    from mcl.io.race_stream import RaceStream, start_race_live

    server = start_live_view(parser, live, start_race_live)
    on_step = None
    if server is not None:
        stream, pace = RaceStream(setup.race, server), Pacer(args.live_speed)

        def on_step(env: Any, obs: dict, infos: dict) -> None:
            stream(env, obs, infos)
            pace(float(next(iter(infos.values()))["time"]))

    try:
        with output_folder(parser, out):
            return _race(spec, setup, out, args.video_fps, not args.quiet, on_step)
    finally:
        stop_live_view(server)


def _race(
    spec: RaceSpec,
    setup: RaceSetup,
    out: Path,
    video_fps: float,
    progress: bool,
    on_step: Any = None,
) -> int:
    """The race into the existing folder ``out``, then the table."""
    from mcl.experiments.race_frames import RaceFrames
    from mcl.experiments.race_run import run_race
    from mcl.experiments.race_table import markdown_table, write_results
    from mcl.experiments.video import FrameWriter

    dt = setup.race.dt
    video, on_frame, frame_every = None, None, 1
    if video_fps > 0:
        frame_every = max(1, round(1.0 / (video_fps * dt)))
        video = FrameWriter(out / "race.mp4", fps=1.0 / (frame_every * dt))
        frames = RaceFrames(setup.race.map, spec)

        def on_frame(frame: Any, state: Any) -> None:
            video.write(frames(frame, state))

    try:
        result = run_race(
            spec,
            setup,
            on_frame=on_frame,
            frame_every=frame_every,
            on_step=on_step,
            progress=progress,
        )
    finally:
        if video is not None:
            video.close()
    paths = write_results(result, out)
    print(markdown_table(result))
    wall = f"{result.wall_time:.1f} s of wall time ({result.steps} steps)"
    print(f"\n{result.seconds:.1f} s raced in {wall}")
    names = [p.name for p in paths]
    if video is not None and video.n_frames:
        kind = "mp4" if video.kind == "mp4" else "PNG frames"
        names.append(f"{video.path.name} ({video.n_frames} frames, {kind})")
    print(f"wrote {', '.join(names)}\noutput folder: {out.resolve()}")
    compile_report()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
