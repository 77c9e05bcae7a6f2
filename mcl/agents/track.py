"""The loop an agent drives: [`racecar_sim.world.track.Track`][racecar_sim.world.track.Track] (the race's track class).

Progress along the loop (the agent's reward and its lap times) is the arc length ``s`` of the
point of the loop nearest the car, in metres from the loop's first point, increasing in the
driving direction. A bundled loop map's loop is the wall follower's path round it, bundled as
``NAME_loop.csv`` beside the map ([`racecar_sim.world.centerline`][racecar_sim.world.centerline]);
`drive_loop()` drives it anew (``racecar-sim make-maps`` writes the bundled files with it), from
any start on any map.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from racecar_sim.drivers import WallFollower, waypoints_from_drive
from racecar_sim.env import RacecarEnv
from racecar_sim.maps import resolve_map
from racecar_sim.world.centerline import bundled_track
from racecar_sim.world.track import LOOP_STARTS, Track, centre_loop

__all__ = ["LOOP_STARTS", "Track", "drive_centerline", "drive_loop", "loop_maps", "track_for_map"]


def loop_maps() -> list[str]:
    """The bundled maps whose loop start is known (`track_for_map()` needs no ``start``)."""
    return sorted(LOOP_STARTS)


def track_for_map(map_name: str, start: tuple[float, float, float] | None = None) -> Track:
    """The loop the wall follower drives on ``map_name``: the bundled ``NAME_loop.csv`` when
    ``start`` is None and the map has one, else `drive_loop()` from ``start``.

    Raises:
        ValueError: no start is known for the map and none is given, or the drive closes no loop.
    """
    if start is None:
        track = bundled_track(map_name, "loop")
        if track is not None:
            return track
    return drive_loop(map_name, None if start is None else tuple(start))


@lru_cache(maxsize=8)
def drive_loop(map_name: str, start: tuple[float, float, float] | None = None) -> Track:
    """The loop the wall follower drives on ``map_name`` from ``start`` (None: the map's loop
    start, `LOOP_STARTS`; world x m, y m, theta rad), 0.25 m between points, oriented along the
    start heading; computed once per process.

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


def drive_centerline(map_name: str) -> Track:
    """`drive_loop()` from the map's loop start, centred between the walls, with widths: the
    bundled ``NAME_centerline.csv``."""
    return centre_loop(resolve_map(map_name), drive_loop(map_name).points)
