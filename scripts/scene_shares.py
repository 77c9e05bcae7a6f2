"""What the scenes add, as shares of beams, on two routes (docs: Honest noise, "What the room
adds"): the two bags' reference poses on ``stata_basement.yaml`` and the wall follower's drive in
``basement_fixed_aligned.yaml`` (the noise experiment's route), against the bags' own shares.

    python scripts/scene_shares.py --bags ../shared/bags --maps ../shared/maps

Prints a Markdown table: per scene and route, the shares of mapped beams (off the car's body) in
wide runs of long returns (openings) and of short returns (furniture, people), and the openings'
mean excess beyond 0.15 m, by the judge of [`mcl.calibration.judge`][mcl.calibration.judge].
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

NAMES = ("localization_bag1_2022-03-29-19-23-29.bag", "localization_bag2_2022-03-29-19-24-34.bag")
STARTS = ((-19.737, 4.391, 1.644), (-20.464, -0.832, 1.775))
"""Lidar poses of the scan a third into each bag (what the global search finds)."""
CLEAN_FROM = (84, 232)
"""First scan of each bag's clean stretch (as in scripts/validate_noise.py)."""


def main(argv: list[str] | None = None) -> int:
    from mcl.calibration.validation import MAX_RANGE, judge_bag, simulated_room, wall_follower_route
    from racecar_sim.maps import load_map
    from racecar_sim.sensors.noise_profiles import profile_document

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--bags", type=Path, required=True, help="folder of the two shared bags")
    p.add_argument("--maps", type=Path, required=True, help="folder of stata_basement.yaml and basement_fixed_aligned.yaml")
    p.add_argument("--scenes", default="none,clean,cluttered", help="comma-separated scenes")
    p.add_argument("--every", type=int, default=3, help="simulate from every N-th bag pose")
    p.add_argument("--seeds", type=int, default=3, help="wall-follower drives (seeds 0..N-1)")
    args = p.parse_args(argv)
    from mcl.calibration.room_split import room_stats

    stata = load_map(args.maps / "stata_basement.yaml")
    world = str(args.maps / "basement_fixed_aligned.yaml")
    body = float(profile_document("mit_racecar")["settings"]["scan_effects"]["body_last"])
    bags = [judge_bag(args.bags / n, stata, np.array(s)) for n, s in zip(NAMES, STARTS, strict=True)]
    print("| route | scene | openings | their excess (m) | short, wide runs |\n|---|---|---:|---:|---:|")
    for i, b in enumerate(bags):
        zs = b.z_star.copy()
        zs[:, : round(body * zs.shape[1])] = np.inf
        spacing = float(np.median(np.diff(b.rec.angles)))
        k = CLEAN_FROM[i]
        for name, r in ((f"bag {i + 1}", room_stats(b.z, zs, spacing, MAX_RANGE)),
                        (f"bag {i + 1}, clean stretch", room_stats(b.z[k:], zs[k:], spacing, MAX_RANGE))):  # fmt: skip
            print(f"| {name} | real | {r.openings:.3f} | {r.opening_excess:.2f} | {r.clutter:.3f} |")
    bag_poses = np.vstack([b.poses.base for b in bags])
    route = wall_follower_route(world, tuple(range(args.seeds)))
    for scene in args.scenes.split(","):
        kw = {"noise_profile": "mit_racecar", "scene": scene, "body": body}
        for name, grid, poses, every in (("bags' poses, stata_basement", stata, bag_poses, args.every),
                                         ("wall follower, basement_fixed_aligned", world, route, 1)):  # fmt: skip
            r = simulated_room(grid, poses, every, **kw)
            print(f"| {name} | {scene} | {r.openings:.3f} | {r.opening_excess:.2f} | {r.clutter:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
