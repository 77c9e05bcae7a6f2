"""Tracks derived from the bundled loop maps by driving them: the wall follower's loop, centred.

These drive a :class:`~racecar_sim.env.RacecarEnv`, so they sit above the single env (which only
reads finished tracks, :mod:`racecar_sim.race.track`); the race envs pass
:func:`centerline_for_map` as the ``"auto"`` track.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from racecar_sim.drivers import WallFollower, waypoints_from_drive
from racecar_sim.env import RacecarEnv
from racecar_sim.maps import resolve_map
from racecar_sim.race.track import LOOP_STARTS, Track, centre_loop

__all__ = ["centerline_for_map", "track_for_map"]


@lru_cache(maxsize=4)
def track_for_map(map_name: str, start: tuple[float, float, float] | None = None) -> Track:
    """The loop the wall follower drives on ``map_name`` from ``start`` (default: the map's loop
    start, :data:`LOOP_STARTS`), 0.25 m between points, oriented along the start heading;
    computed once per process.

    Raises:
        ValueError: no start is known for the map and none is given, or the drive closes no loop.
    """
    if start is None:
        if map_name not in LOOP_STARTS:
            raise ValueError(
                f"no loop start known for map {map_name!r}; give start=(x, y, theta) "
                f"(known: {sorted(LOOP_STARTS)})"
            )
        start = LOOP_STARTS[map_name]
    env = RacecarEnv(map_name)
    try:
        points = waypoints_from_drive(env, WallFollower(), start_pose=np.array(start), seed=0)
    except RuntimeError as exc:
        raise ValueError(f"map {map_name!r}: the wall follower closes no loop: {exc}") from exc
    return Track(points)


@lru_cache(maxsize=4)
def centerline_for_map(map_name: str) -> Track:
    """The centerline of a bundled loop map (:data:`LOOP_STARTS`): the wall follower's loop
    (:func:`track_for_map`) centred between the walls, with widths; computed once per process."""
    return centre_loop(resolve_map(map_name), track_for_map(map_name).points)
