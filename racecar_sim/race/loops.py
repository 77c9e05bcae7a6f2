"""Tracks derived from the bundled loop maps by driving them: the wall follower's loop, centred.

These drive a [`RacecarEnv`][racecar_sim.env.RacecarEnv] ([`racecar_sim.race.loop_drive`][racecar_sim.race.loop_drive], given
the class); the race envs pass `centerline_for_map()` as the ``"auto"`` track, and the single
env does the same through [`loop_drive`][racecar_sim.race.loop_drive] with its own class (the same
cached result).
"""

from __future__ import annotations

from racecar_sim.env import RacecarEnv
from racecar_sim.race.loop_drive import drive_centerline, drive_loop
from racecar_sim.race.track import Track

__all__ = ["centerline_for_map", "track_for_map"]


def track_for_map(map_name: str, start: tuple[float, float, float] | None = None) -> Track:
    """The loop the wall follower drives on ``map_name`` from ``start`` (default: the map's loop
    start, `LOOP_STARTS`), 0.25 m between points, oriented along
    the start heading; computed once per process.

    Raises:
        ValueError: no start is known for the map and none is given, or the drive closes no loop.
    """
    return drive_loop(map_name, None if start is None else tuple(start), RacecarEnv)


def centerline_for_map(map_name: str) -> Track:
    """The centerline of a bundled loop map (`LOOP_STARTS`): the
    wall follower's loop (`track_for_map()`) centred between the walls, with widths; computed
    once per process."""
    return drive_centerline(map_name, RacecarEnv)
