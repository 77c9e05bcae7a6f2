"""The start grid: cars staggered behind the start line of a track, none overlapping.

Car 0 (pole) stands with its front bumper ``gap`` metres behind the start line, the others follow
one car length plus ``gap`` apart along the centerline, alternately left and right of it by up to
``stagger`` metres (less where the track is narrower, none where the offset would put the car in
a wall). Each car faces along the track. Poses are rear-axle world poses [x, y, theta].
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from racecar_sim.settings.config import CarParams
from racecar_sim.world.track import Track

__all__ = ["start_grid"]


def start_grid(
    track: Track,
    n: int,
    car: CarParams,
    is_free: Callable[[np.ndarray], bool],
    gap: float = 0.3,
    stagger: float = 0.25,
    at: float = 0.0,
) -> np.ndarray:
    """(n, 3) rear-axle world poses of a staggered grid behind ``track``'s start line.

    Args:
        track: the track (its start line crosses its first point).
        n: number of cars.
        car: their geometry (length, width, rear overhang).
        is_free: whether a rear-axle pose (3,) keeps the car's box off the walls.
        gap: metres between a car's front and the next one's rear, and between pole and the line.
        stagger: the largest sideways offset from the centerline, metres.
        at: metres along the centerline of the line the grid stands behind (0: the start line;
            another value builds the same grid elsewhere on the track, e.g. a rolling start of
            training episodes).

    Raises:
        ValueError: more cars than fit once round the track (each takes its length plus ``gap``
            of centerline: the last would stand on the first), or a grid slot where the car fits
            neither staggered nor on the centerline.
    """
    pitch = car.length + gap  # metres of centerline each car takes
    most = int(track.length // pitch)
    if n > most:
        raise ValueError(
            f"start grid: {n} cars need {n * pitch:.1f} m of track (car length {car.length:g} m "
            f"+ gap {gap:g} m each), the track is {track.length:.1f} m long; at most {most} fit"
        )
    ahead = car.length - car.rear_overhang  # rear axle to the front bumper
    poses = np.zeros((n, 3))
    for i in range(n):
        s = at - (gap + ahead + i * (car.length + gap))
        point = track.point_at(s)
        theta = track.heading_at(s)
        right, left = track.width_at(s)
        side = 1.0 if i % 2 == 0 else -1.0  # pole on the left
        room = (left if side > 0 else right) - car.width / 2 - 0.1
        offsets = (side * max(0.0, min(stagger, room)), 0.0)
        normal = np.array([-math.sin(theta), math.cos(theta)])
        for off in offsets:
            xy = point + off * normal
            pose = np.array([xy[0], xy[1], theta])
            if is_free(pose):
                poses[i] = pose
                break
        else:
            raise ValueError(
                f"start grid: slot {i} ({at - s:.1f} m behind the line) has no room for the car"
            )
    return poses
