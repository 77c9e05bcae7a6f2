"""Fixtures and helpers for bag tests: a synthetic recording (a car driving an arc through the test
room, written with BagRecorder) and the real bags in ../shared/bags."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mcl.io import BagRecorder
from mcl.motion_model import compose, twist_to_odometry
from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import RayCaster

REPO = Path(__file__).resolve().parents[2]
SHARED_BAGS = REPO.parent / "shared" / "bags"
BAG1 = SHARED_BAGS / "localization_bag1_2022-03-29-19-23-29.bag"
BAG2 = SHARED_BAGS / "localization_bag2_2022-03-29-19-24-34.bag"
ANGLES = np.linspace(-3 * math.pi / 4, 3 * math.pi / 4, 1081)
MOUNT = 0.3
START = np.array([5.0, 2.0, 0.0])
TWIST = np.array([1.0, 0.0, 0.15])


def shared_bag(path: Path) -> Path:
    """A bag in ../shared/bags, or skip with the reason."""
    if not path.exists():
        pytest.skip(f"real bag {path} not found: ../shared/bags is absent in this checkout")
    return path


def record_drive(
    path: Path,
    occupancy_map: OccupancyMap,
    duration: float = 3.0,
    beams: list[int] | None = None,
    seed: int = 0,
) -> dict:
    """Drive START with TWIST for ``duration`` s: odometry at 50 Hz, scans at 40 Hz (exact cast
    + 1 cm noise, every 97th beam a no-return), truth and a fake estimate; returns the truth.

    ``beams``: per-scan beam counts to write instead of 1081 (for the beam-count error)."""
    rng = np.random.default_rng(seed)
    caster = RayCaster(occupancy_map, 30.0, method="exact")
    truth_t, truth = [], []
    with BagRecorder(path, occupancy_map, ANGLES, 30.0, MOUNT) as rec:
        rec.write_static(0.0)
        events = sorted(
            [(k * 0.02, "odom") for k in range(int(duration / 0.02) + 1)]
            + [(0.005 + k * 0.025, "scan") for k in range(int(duration / 0.025))]
        )
        for i, (t, kind) in enumerate(events):
            pose = compose(START[None], twist_to_odometry(TWIST, t))[0]
            if kind == "odom":
                rec.write_odom(t, pose - START, TWIST)  # odometry frame = start pose frame
                rec.write_truth(t, pose)
                truth_t.append(t)
                truth.append(pose)
            else:
                lidar = pose + np.array([MOUNT * math.cos(pose[2]), MOUNT * math.sin(pose[2]), 0.0])
                ranges = caster.cast(lidar, ANGLES)[0] + rng.normal(0, 0.01, ANGLES.size)
                ranges[::97] = np.nan
                if beams is not None:
                    ranges = ranges[: beams[i % len(beams)]]
                rec.write_scan(t, ranges)
                rec.write_estimate(t, pose, np.eye(3) * 1e-4, pose + rng.normal(0, 0.05, (50, 3)))
    return {"times": np.array(truth_t), "poses": np.array(truth)}


def recorded_fixture():
    """A session fixture ``recorded``: (bag folder, truth) of a 3 s synthetic drive in the room
    (each test module assigns it: ``recorded = recorded_fixture()``)."""

    @pytest.fixture(scope="session")
    def recorded(tmp_path_factory, room) -> tuple[Path, dict]:
        path = tmp_path_factory.mktemp("bags") / "drive"
        return path, record_drive(path, room)

    return recorded
