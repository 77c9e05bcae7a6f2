"""Shared fixtures: the real maps in ../shared/maps (skipped when absent), the bundled maps, and a small
in-memory room map (no files, built in milliseconds) for the filter tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

from racecar_sim.maps import OccupancyMap, bundled, load_map
from tests.skips import shared_missing

# No test may depend on how long a first numba call takes: a kernel that compiles, or loads from the
# on-disk cache (about a third of a second on a fresh machine), is not a flaky failure. Every property
# test therefore runs without a deadline; tests/test_no_deadlines.py keeps any test from setting one.
settings.register_profile("no_deadline", deadline=None)
# `pytest --hypothesis-profile=stress` hunts for the edge cases CI would otherwise find one a run.
settings.register_profile("stress", deadline=None, max_examples=1000)
settings.load_profile("no_deadline")

LONGEST_FIRST = (
    "tests/calibration/test_real_bags.py",
    "tests/cli/test_wheel.py",
    "tests/fuzz/test_fuzz.py",
    "tests/io/test_replay.py",
    "tests/io/test_live_safety.py",
    "tests/experiments/test_changing_world.py",
    "tests/experiments/test_ray_executor.py",
    "tests/cli/test_editable.py",
    "tests/cli/test_bench_global.py",
    "tests/io/test_sensor_models_bench.py",
    "tests/experiments/test_recovery.py",
    "tests/io/test_live.py",
)
"""Test files of a minute or more (on the 2-core CI machine), run first: the workers of
``pytest -n 3 --dist loadfile`` take files in collection order, and a long file started last
would leave one worker idle at the end."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest files first (`LONGEST_FIRST`), the rest in their order."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))


REPO = Path(__file__).resolve().parent.parent
SHARED_MAPS = REPO.parent / "shared" / "maps"
STATA_YAML = SHARED_MAPS / "stata_basement.yaml"


def shared_map_path(name: str = "stata_basement.yaml") -> Path:
    """Path of a real map in ../shared/maps, or skip the test with the reason."""
    path = SHARED_MAPS / name
    if not path.is_file():
        pytest.skip(shared_missing(path))
    return path


@pytest.fixture(scope="session")
def stata_map() -> OccupancyMap:
    """The MIT Stata basement (0.0504 m/cell, origin yaw 3.14) from ../shared/maps."""
    return load_map(shared_map_path())


@pytest.fixture(scope="session")
def default_map() -> OccupancyMap:
    """The default bundled map (basement_loop)."""
    return load_map(bundled())


def room_map(resolution: float = 0.05) -> OccupancyMap:
    """An asymmetric 12 m x 8 m room (walls 2 cells thick) with three boxes, origin (1, -2, 0).

    Asymmetric so that a scan pins down the pose (no mirror or rotation ambiguity).
    """
    h, w = round(8.0 / resolution), round(12.0 / resolution)
    occ = np.zeros((h, w), dtype=bool)
    occ[:2, :] = occ[-2:, :] = True
    occ[:, :2] = occ[:, -2:] = True

    def box(x0: float, y0: float, x1: float, y1: float) -> None:
        # x along the columns, y up from the bottom row (metres in the map frame).
        r0, r1 = h - round(y1 / resolution), h - round(y0 / resolution)
        occ[r0:r1, round(x0 / resolution) : round(x1 / resolution)] = True

    box(2.0, 2.0, 3.0, 3.5)
    box(7.0, 5.0, 9.5, 5.6)
    box(9.0, 1.0, 9.4, 3.0)
    return OccupancyMap(occupied=occ, resolution=resolution, origin=(1.0, -2.0, 0.0), name="room")


def lidar_pose(pose: np.ndarray, mount_offset: float) -> np.ndarray:
    """World pose of a lidar mounted ``mount_offset`` metres ahead of a rear-axle ``pose`` (3,)."""
    x, y, th = pose
    return np.array([x + mount_offset * np.cos(th), y + mount_offset * np.sin(th), th])


@pytest.fixture(scope="session")
def room() -> OccupancyMap:
    """:func:`room_map` at 0.05 m per cell: a 12 m x 8 m asymmetric room with three boxes."""
    return room_map()


@pytest.fixture(scope="session")
def mount_pose():
    """:func:`lidar_pose`: the world pose of a lidar mounted ahead of a rear-axle pose."""
    return lidar_pose
