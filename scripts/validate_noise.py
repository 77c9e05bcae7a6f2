"""The simulated lidar against the real one (docs: Honest noise): leave-one-bag-out and the
clean corridor, by one judge.

    python scripts/validate_noise.py --bags ../shared/bags --map ../shared/maps/stata_basement.yaml \\
        --fit1 fit_bag1.yaml --fit2 fit_bag2.yaml --profile mit_racecar

``--fit1`` / ``--fit2``: profiles fitted on bag 1 / bag 2 alone (``racecar-sim calibrate-noise
BAG --out ...``). Prints Markdown tables: each bag's five fractions, the other bag's fit
predicting it (bag 1 with the clean scene, bag 2 with the cluttered one), and the profile in the
clean scene against the clean stretches of both bags.
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
"""First scan of each bag's clean stretch: bag 1 after its first 2.1 s (something unmapped
beside the start), bag 2's last third (after the people by the car have gone)."""
KEYS = ("within5", "within15", "short", "long", "noreturn")


def _row(name: str, f: dict[str, float]) -> str:
    return f"| {name} | " + " | ".join(f"{f[k]:.3f}" for k in KEYS) + " |"


def main(argv: list[str] | None = None) -> int:
    from mcl.calibration.scan_stats import residual_fractions
    from mcl.calibration.validation import MAX_RANGE, judge_bag, simulated_fractions
    from racecar_sim.maps import load_map

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--bags", type=Path, required=True, help="folder of the two shared bags")
    p.add_argument("--map", type=Path, required=True, help="stata_basement.yaml")
    p.add_argument("--fit1", required=True, help="profile fitted on bag 1 alone")
    p.add_argument("--fit2", required=True, help="profile fitted on bag 2 alone")
    p.add_argument("--profile", default="mit_racecar", help="the shipped profile (both bags)")
    p.add_argument("--every", type=int, default=3, help="simulate from every N-th reference pose")
    args = p.parse_args(argv)
    grid = load_map(args.map)
    bags = [judge_bag(args.bags / n, grid, np.array(s)) for n, s in zip(NAMES, STARTS, strict=True)]
    head = "| | " + " | ".join(KEYS) + " |\n|---|" + "---:|" * len(KEYS)
    print(head)
    for i, b in enumerate(bags):
        print(_row(f"bag {i + 1}, real", b.fractions.as_dict()))
    for i, (fit, scene) in enumerate(((args.fit2, "clean"), (args.fit1, "cluttered"))):
        sim = simulated_fractions(grid, bags[i].poses.base, args.every, noise_profile=fit, scene=scene)
        print(_row(f"bag {i + 1}, predicted from bag {2 - i}'s fit, scene {scene}", sim.as_dict()))
    z = np.vstack([b.z[k:] for b, k in zip(bags, CLEAN_FROM, strict=True)])
    zs = np.vstack([b.z_star[k:] for b, k in zip(bags, CLEAN_FROM, strict=True)])
    poses = np.vstack([b.poses.base[k:] for b, k in zip(bags, CLEAN_FROM, strict=True)])
    print(_row("clean stretches, real", residual_fractions(z, zs, MAX_RANGE).as_dict()))
    for scene in ("clean", "cluttered"):
        sim = simulated_fractions(grid, poses, args.every, noise_profile=args.profile, scene=scene)
        print(_row(f"clean stretches, {args.profile}, scene {scene}", sim.as_dict()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
