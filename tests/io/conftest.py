"""The synthetic recording shared by the bag tests (see :mod:`tests.io.bag_fixtures`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.io.bag_fixtures import record_drive


@pytest.fixture(scope="session")
def recorded(tmp_path_factory, room) -> tuple[Path, dict]:
    """(bag folder, truth) of a 3 s synthetic drive in the room."""
    path = tmp_path_factory.mktemp("bags") / "drive"
    return path, record_drive(path, room)
