"""A race drawn: the map, the track's centerline, every car's last scan hits (lighter) and its box,
each car in its own colour. Images are RGB ``uint8`` (H, W, 3) from a
[`MapRenderer`][racecar_sim.render.MapRenderer]; poses are world frame (metres, radians)."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from racecar_sim.render import MapRenderer
from racecar_sim.world.track import Track

__all__ = ["CAR_COLOURS", "draw_race"]

CAR_COLOURS: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180), (214, 39, 40), (44, 160, 44), (255, 127, 14), (148, 103, 189),
    (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
)  # fmt: skip
"""RGB colour of car ``i`` is ``CAR_COLOURS[i % 10]`` (matplotlib's tab10)."""


def draw_race(renderer: MapRenderer, world: Any, track: Track | None, max_range: float) -> np.ndarray:
    """A new frame of the race ``world`` (a [`RaceWorld`][racecar_sim.race.world.RaceWorld]):
    the centerline of ``track`` (when given), then each car's scan hits (beams at ``max_range``
    metres drawn as no hit) and its box, in `CAR_COLOURS`."""
    img = renderer.base()
    if track is not None:
        line = renderer.world_to_pixel(track.points)
        cv2.polylines(img, [line], True, (200, 200, 200), 1)
    lidar = world.cars[0].lidar
    for i in range(world.n_cars):
        colour = CAR_COLOURS[i % len(CAR_COLOURS)]
        light = tuple(int(c + (255 - c) * 0.5) for c in colour)
        renderer.draw_scan(img, lidar.mount_pose(world.scan_poses[i]), world.scans[i], lidar.angles,
                           colour=light, max_range=max_range)  # fmt: skip
    for i, box in enumerate(world.boxes()):
        renderer.draw_car(img, box, CAR_COLOURS[i % len(CAR_COLOURS)])
    return img
