"""The bundled loop maps' tracks, derived by driving them in an env class the caller gives.

The derivation drives a car with the wall follower ([`waypoints_from_drive()`][racecar_sim.drivers.waypoints_from_drive])
round the loop and centres that path between the walls ([`centre_loop()`][racecar_sim.race.track.centre_loop]).
It needs an env to drive but does not import one: the single env passes its own class, so that
``RacecarSim-v0`` takes ``track="auto"`` as the race envs do, with no import loop between the env
and this module ([`racecar_sim.race.loops`][racecar_sim.race.loops] is the same with [`RacecarEnv`][racecar_sim.env.RacecarEnv]
filled in). Each result is computed once per process and env class.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from racecar_sim.drivers import WallFollower, waypoints_from_drive
from racecar_sim.maps import resolve_map
from racecar_sim.race.track import LOOP_STARTS, Track, centre_loop

__all__ = ["drive_centerline", "drive_loop"]


@lru_cache(maxsize=8)
def drive_loop(map_name: str, start: tuple[float, float, float] | None, env_class: type) -> Track:
    """The loop the wall follower drives on ``map_name`` from ``start`` (None: the map's loop
    start, `LOOP_STARTS`) in an ``env_class(map_name)`` env, 0.25 m between points,
    oriented along the start heading.

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
    env = env_class(map_name)
    try:
        points = waypoints_from_drive(env, WallFollower(), start_pose=np.array(start), seed=0)
    except RuntimeError as exc:
        raise ValueError(f"map {map_name!r}: the wall follower closes no loop: {exc}") from exc
    return Track(points)


@lru_cache(maxsize=8)
def drive_centerline(map_name: str, env_class: type) -> Track:
    """The centerline of a bundled loop map: `drive_loop()` from its loop start, centred
    between the walls, with widths."""
    return centre_loop(resolve_map(map_name), drive_loop(map_name, None, env_class).points)
