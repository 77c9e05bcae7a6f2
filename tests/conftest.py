"""Shared fixtures: the real maps in ../shared/maps (skipped when absent) and the bundled maps."""

from __future__ import annotations

from pathlib import Path

import pytest

from racecar_sim.maps import OccupancyMap, bundled, load_map

REPO = Path(__file__).resolve().parent.parent
SHARED_MAPS = REPO.parent / "shared" / "maps"
STATA_YAML = SHARED_MAPS / "stata_basement.yaml"


def shared_map_path(name: str = "stata_basement.yaml") -> Path:
    """Path of a real map in ../shared/maps, or skip the test with the reason."""
    path = SHARED_MAPS / name
    if not path.is_file():
        pytest.skip(f"real map {path} not found: ../shared/maps is absent in this checkout")
    return path


@pytest.fixture(scope="session")
def stata_map() -> OccupancyMap:
    """The MIT Stata basement (0.0504 m/cell, origin yaw 3.14) from ../shared/maps."""
    return load_map(shared_map_path())


@pytest.fixture(scope="session")
def default_map() -> OccupancyMap:
    """The default bundled map (basement_loop)."""
    return load_map(bundled())
