"""Fit the simulator's noise profile from real recordings (README, "Honest noise").

Reads ROS bags (``/scan`` LaserScan and ``/vesc/odom`` Odometry), finds the lidar pose of every
scan on the map (a global search for one scan, then scan-to-map tracking with the odometry),
fits the beam model by expectation-maximisation (Probabilistic Robotics table 6.2), measures what
it misses (failure runs, drop-outs by range, long returns, mixed pixels) and the odometry's bias
and noise, and writes the profile YAML (``racecar_sim/sensors/noise_profiles/data/mit_racecar.yaml`` is
this command's output on the two shared bags):

    racecar-sim calibrate-noise ../shared/bags/*.bag --map ../shared/maps/stata_basement.yaml \\
        --out racecar_sim/sensors/noise_profiles/data/mit_racecar.yaml
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from mcl.cli.common import Parser, check_file_out, path_arg

EXAMPLES = """\
examples:
  racecar-sim calibrate-noise ../shared/bags/*.bag --map ../shared/maps/stata_basement.yaml \\
      --out racecar_sim/sensors/noise_profiles/data/mit_racecar.yaml
  racecar-sim calibrate-noise BAG1 BAG2 --map MAP.yaml --out my_car.yaml \\
      --start=-19.34,5.74,1.136 --start=-20.49,-0.70,1.763     (skip the global searches)
"""


def _pose(text: str) -> np.ndarray:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected X,Y,THETA (lidar pose), got {text!r}")
    return np.asarray(values)


def main(argv: list[str] | None = None) -> int:
    parser = Parser("racecar-sim calibrate-noise", __doc__, EXAMPLES)
    parser.add_argument("bags", nargs="*", type=Path, help="ROS 1 .bag files or ROS 2 bag folders")
    parser.add_argument("--map", type=Path, help="map YAML the car drove on (required)")
    parser.add_argument(
        "--out", type=path_arg, help="profile YAML to write: a new file or one it wrote (required)"
    )
    parser.add_argument(
        "--mount-offset", type=float, default=0.275, help="lidar ahead of base_link, m"
    )
    parser.add_argument(
        "--start",
        type=_pose,
        action="append",
        default=None,
        metavar="X,Y,THETA",
        help="per bag, the lidar pose of its scan at a third of the recording instead of the "
        "global search (repeat once per bag, in order)",
    )
    parser.add_argument(
        "--poses",
        type=Path,
        action="append",
        default=None,
        metavar="CSV",
        help="per bag, a replay's trajectory.csv (racecar-sim replay) whose poses are used instead "
        "of scan matching (repeat once per bag, in order; default: scan matching)",
    )
    parser.add_argument(
        "--sim-dt", type=float, default=0.025, help="env step the odometry noise is for"
    )
    args = parser.parse_args(argv)
    if not args.bags:
        parser.fail("BAG", "give at least one bag")
    if args.map is None or args.out is None:
        parser.fail("--map" if args.map is None else "--out", "is required")
    for bag in args.bags:
        if not bag.exists():
            parser.fail("BAG", f"{bag} not found")
    if not args.map.is_file():
        parser.fail("--map", f"{args.map}: file not found")
    from mcl.calibration.pipeline import is_written_profile

    check_file_out(parser, args.out, "--out", is_written_profile)
    if args.start is not None and len(args.start) != len(args.bags):
        parser.fail("--start", f"given {len(args.start)} times for {len(args.bags)} bags")
    if args.poses is not None:
        if len(args.poses) != len(args.bags):
            parser.fail("--poses", f"given {len(args.poses)} times for {len(args.bags)} bags")
        for f in args.poses:
            if not f.is_file():
                parser.fail("--poses", f"{f} not found")
    try:
        import rosbags  # noqa: F401
    except ImportError:
        parser.error("reading bags needs the 'rosbags' package (pip install rosbags)")
    from mcl.calibration.pipeline import calibrate, profile_document, write_profile

    t0 = time.perf_counter()
    try:
        cal = calibrate(
            args.bags, args.map, args.mount_offset, args.start, progress=True, pose_files=args.poses
        )
    except ValueError as exc:
        parser.error(str(exc).splitlines()[0])
    doc = profile_document(cal, sim_dt=args.sim_dt)
    path = write_profile(doc, args.out)
    fit = doc["fit"]
    b = fit["beam_model_em"]
    print(
        f"beam model (EM, {b['n_beams']} beams): z_hit {b['z_hit']:.3f} z_short {b['z_short']:.3f} "
        f"z_max {b['z_max']:.3f} z_rand {b['z_rand']:.3f} sigma_hit {b['sigma_hit']:.3f} m "
        f"bias {b['bias']:+.3f} m lambda_short {b['lambda_short']:.3f} /m"
    )
    print("residuals:", ", ".join(f"{k} {v:.3f}" for k, v in fit["residuals"].items()))
    o = fit["odometry"]
    print(
        f"odometry: lag {o['lag_s']:.2f} s, scale bias {o['scale_bias']}, offset {o['offset']}, "
        f"window rmse {o['window_rmse']} ({o['windows']} windows of {o['window_s']} s)"
    )
    print(f"wrote {path} in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
