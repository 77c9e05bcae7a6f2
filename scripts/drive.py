"""Main job (for now): cast a 1080-beam scan on the default bundled map and draw it to a PNG."""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from racecar_sim.maps import DEFAULT_MAP, resolve_map
from racecar_sim.params import LidarParams
from racecar_sim.raycast import RayCaster


def main(argv: list[str] | None = None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--map", default=DEFAULT_MAP, help="bundled map name or YAML path")
    parser.add_argument("--out", type=Path, default=Path("out/drive"), help="output folder")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    grid = resolve_map(args.map)
    lidar = LidarParams()
    rng = np.random.default_rng(args.seed)
    pose = grid.sample_free_poses(rng, 1, clearance=0.5)[0]
    ranges = RayCaster(grid, lidar.max_range).cast(pose, lidar.angles)[0]

    img = cv2.cvtColor(np.where(grid.occupied, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)
    ends = pose[:2] + ranges[:, None] * np.column_stack(
        [np.cos(pose[2] + lidar.angles), np.sin(pose[2] + lidar.angles)]
    )
    start_rc = grid.world_to_grid(pose[:2])
    end_rc = grid.world_to_grid(ends)
    for r, c in end_rc:
        cv2.line(img, (int(start_rc[1]), int(start_rc[0])), (int(c), int(r)), (255, 200, 120), 1)
    for r, c in end_rc:
        cv2.circle(img, (int(c), int(r)), 1, (0, 0, 255), -1)
    cv2.circle(img, (int(start_rc[1]), int(start_rc[0])), 4, (0, 160, 0), -1)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "scan.png"
    cv2.imwrite(str(path), img)
    print(f"map {grid.name}: {len(ranges)} beams from pose {np.round(pose, 3).tolist()}")
    print(
        f"ranges: min {ranges.min():.2f} m, median {np.median(ranges):.2f} m, max {ranges.max():.2f} m"
    )
    print(f"wrote {path}")
    return path


if __name__ == "__main__":
    main()
