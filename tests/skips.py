"""One wording for the suite's skips, so that a skipped run reads the same everywhere: real data
beside the checkout (``../shared``, named by its resolved path) and the ``[rl]`` extra."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared"
"""``../shared`` beside the checkout: the real maps and bags (README, Real data beside the checkout)."""

NO_SB3 = importlib.util.find_spec("stable_baselines3") is None
RL_MISSING = "stable-baselines3 is not installed: pip install torch==2.13.0 -e '.[rl]'"
"""The skip reason of every test that needs the ``[rl]`` extra."""


def shared_missing(path: Path) -> str:
    """The skip reason for a file of ``../shared`` that is not there."""
    return f"{path.resolve()} not found: ../shared (the real maps and bags) is absent beside this checkout"


def need_shared(*relative: str) -> list[Path]:
    """The files ``relative`` to ``../shared`` (e.g. ``"maps/stata_basement.yaml"``), or skip the
    test naming the first one missing."""
    paths = [SHARED / r for r in relative]
    for path in paths:
        if not path.is_file():
            pytest.skip(shared_missing(path))
    return paths
