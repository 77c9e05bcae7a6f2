"""The track of a loop map as data: the bundled loop maps' centerlines (CSV files beside the maps,
written by ``racecar-sim make-maps``), and the centerline of any other loop map derived from its
free space.

The derivation needs no car. It is for maps whose free space runs round one island (the inner wall
block of a ring of corridors, as ``basement_loop``); on maps with rooms and doors off the loop
(``office``) the loop is not the free space's alone to say: their tracks are bundled CSVs, or the
user's. The free space the car can reach is one region around the island (the largest wall block
that does not touch the map's border). Every point of that region is nearer the island or nearer the
outer walls; the border between the two is the line midway between them, a closed curve round the
island. It is smoothed, centred between the walls along its normals and given its free widths by
`racecar_sim.world.track.centre_loop()`, and oriented counter-clockwise (the island
on the left) unless a start pose says otherwise. Frames: world (metres, radians).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import cv2
import numpy as np

from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.maps.bundled import maps_dir
from racecar_sim.world.track import LOOP_STARTS, Track, centre_loop, resample_polyline

__all__ = [
    "TRACK_KINDS",
    "bundled_track",
    "bundled_track_path",
    "centerline_for_map",
    "derive_centerline",
    "loop_centerline",
    "resolve_track",
]

TRACK_KINDS = ("centerline", "loop")
"""The bundled tracks of a loop map: ``centerline`` (centred between the walls, with widths: the
races' and ``track="auto"``'s) and ``loop`` (the wall follower's own path: the agents' and the
experiments' route)."""


def bundled_track_path(map_name: str, kind: str = "centerline") -> Path:
    """Where the bundled ``kind`` track of ``map_name`` lives: ``NAME_centerline.csv`` or
    ``NAME_loop.csv`` beside the map (`maps_dir()`); it may not exist."""
    if kind not in TRACK_KINDS:
        raise ValueError(f"kind must be one of {TRACK_KINDS}, got {kind!r}")
    return maps_dir() / f"{map_name}_{kind}.csv"


def bundled_track(map_name: str, kind: str = "centerline") -> Track | None:
    """The bundled ``kind`` track of a bundled map, or None when the map has none."""
    path = bundled_track_path(map_name, kind)
    return Track.from_csv(path) if path.is_file() else None


def centerline_for_map(map_name: str) -> Track:
    """The centerline of a bundled loop map (`loop_centerline()` of the map by name)."""
    return loop_centerline(resolve_map(map_name))


def loop_centerline(grid: OccupancyMap) -> Track:
    """The centerline of ``grid``: its bundled one when it is a bundled loop map (loaded from the
    bundled YAML), else
    `derive_centerline()` (the bundled map's start heading, `LOOP_STARTS`, when known).

    Raises:
        ValueError: the map's free space runs round no island (not a loop map).
    """
    if grid.path is not None and Path(grid.path).resolve() == (maps_dir() / f"{grid.name}.yaml").resolve():
        track = bundled_track(grid.name)
        if track is not None:
            return track
    return derive_centerline(grid, LOOP_STARTS.get(grid.name))


def derive_centerline(
    grid: OccupancyMap, start: tuple[float, float, float] | None = None, spacing: float = 0.25
) -> Track:
    """The line midway between a loop map's island and its outer walls (module docstring),
    centred and measured, every ``spacing`` metres.

    Args:
        grid: the map (world frame).
        start: a world pose [x, y, theta]: the track starts at its point nearest ``(x, y)`` and
            runs the way ``theta`` points there; None: counter-clockwise from the first point.
        spacing: metres between the track's points.

    Raises:
        ValueError: the map's free space runs round no island, or the midline leaves it.
    """
    walls = np.pad(grid.occupied, 1, constant_values=True)  # the border is a wall
    n, region = cv2.connectedComponents((~walls).astype(np.uint8), connectivity=4)
    if n < 2:
        raise ValueError(f"map {grid.name!r} has no free space")
    sizes = np.bincount(region.ravel())
    sizes[0] = 0  # label 0 is the walls
    reach = region == int(np.argmax(sizes))  # the largest free region: where the car drives
    m, blocks = cv2.connectedComponents((~reach).astype(np.uint8), connectivity=8)
    outer = int(blocks[0, 0])  # the padded border belongs to the outer walls
    counts = np.bincount(blocks.ravel(), minlength=m)
    counts[[0, outer]] = 0
    if m < 3 or counts.max() == 0:
        raise ValueError(
            f"map {grid.name!r} is not a loop map: its free space runs round no island; "
            "give a centerline CSV"
        )
    island = int(np.argmax(counts))
    # Smaller blocks (a box in a hallway) count as neither: the midline passes them, and
    # centre_loop() then moves it into the free space beside them.
    to_outer = cv2.distanceTransform((blocks != outer).astype(np.uint8), cv2.DIST_L2, 5)
    to_island = cv2.distanceTransform((blocks != island).astype(np.uint8), cv2.DIST_L2, 5)
    nearer_island = ((to_island < to_outer) | (blocks == island)).astype(np.uint8)
    contours, _ = cv2.findContours(nearer_island, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    ring = max(contours, key=cv2.contourArea)[:, 0, :]  # (K, 2) [col, row], padded
    xy = grid.grid_to_world(np.stack([ring[:, 1] - 1, ring[:, 0] - 1], axis=1))
    loop = resample_polyline(xy, spacing, loop=True)
    inside = grid.distance_at(loop) > 0
    if inside.mean() < 0.95:
        raise ValueError(
            f"map {grid.name!r}: the midline round the island runs through walls on "
            f"{100 * (1 - inside.mean()):.0f} % of its length; give a centerline CSV"
        )
    loop = _oriented(loop, start)
    return centre_loop(grid, loop, spacing)


def _oriented(loop: np.ndarray, start: tuple[float, float, float] | None) -> np.ndarray:
    """``loop`` (K, 2) counter-clockwise, or from ``start``'s nearest point in its heading."""
    area = 0.5 * float(np.sum(loop[:, 0] * np.roll(loop[:, 1], -1) - np.roll(loop[:, 0], -1) * loop[:, 1]))
    if area < 0:
        loop = loop[::-1]
    if start is None:
        return loop
    x, y, theta = start
    k = int(np.argmin(np.hypot(loop[:, 0] - x, loop[:, 1] - y)))
    loop = np.roll(loop, -k, axis=0)
    ahead = loop[1] - loop[0]
    if ahead[0] * math.cos(theta) + ahead[1] * math.sin(theta) < 0:
        loop = np.roll(loop[::-1], 1, axis=0)  # the same first point, the other way round
    return loop


def resolve_track(spec: object, grid: OccupancyMap) -> Track | None:
    """The track of the ``track`` setting: None (no track), a [`Track`][racecar_sim.world.track.Track],
    a CSV path (f1tenth's centerline format) or ``"auto"``: `loop_centerline()` of ``grid``
    (the bundled map's centerline, or the midline round the island of any other loop map).

    Raises:
        ValueError: a file that is not a track, or ``"auto"`` on a map that is not a loop map.
    """
    if spec is None or isinstance(spec, Track):
        return spec
    if isinstance(spec, str | os.PathLike):
        text = os.fspath(spec)
        if text == "auto":
            return loop_centerline(grid)
        return Track.from_csv(text)
    raise ValueError(f"track must be None, 'auto', a CSV path or a Track, got {spec!r}")
