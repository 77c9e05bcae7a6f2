"""Several cars in one world: `RaceEnv` (PettingZoo, extra ``race``), tracks, laps, grid.

``RaceEnv`` is imported on first use, so the tracks and the single-agent race env work without
pettingzoo installed.
"""

from __future__ import annotations

from typing import Any

from racecar_sim.world.centerline import resolve_track
from racecar_sim.world.track import Track

__all__ = ["RaceEnv", "Track", "resolve_track"]


def __getattr__(name: str) -> Any:
    if name == "RaceEnv":
        from racecar_sim.race.env import RaceEnv

        return RaceEnv
    raise AttributeError(f"module 'racecar_sim.race' has no attribute {name!r}")
