"""Every car's lidar in one numba call: the walls, the other cars' boxes, then the beam noise.

A race scan is the single env's scan (:mod:`racecar_sim.raycast.scan`: the mount pose, the exact
cast on the grid, the four-part beam noise) with one stage between the cast and the noise: each
other car's footprint (its ``length x width`` box at its pose at scan time, world frame) cuts the
beams that hit it first, exactly (:func:`racecar_sim.obstacles.ray_segment` on the box's four
edges). The noise then treats a car like a wall.

Culling keeps the cost linear in the beams a car actually covers, not cars x beams: a car whose
bounding circle lies beyond ``max_range`` is skipped, and of the others only the beams inside the
angle their bounding circle subtends are tested (beams are evenly spaced, so that is an index
range). A car directly behind another covers ~1/10 of a 270 degree scan at 2 m.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.obstacles import ray_segment
from racecar_sim.raycast.scan import add_beam_noise, exact_one
from racecar_sim.raycast.shared_work import fetch_add

__all__ = ["car_boxes", "race_scans_serial", "race_scans_shared"]

_TWO_PI = 2.0 * math.pi


def car_boxes(poses: np.ndarray, local_corners: np.ndarray) -> np.ndarray:
    """(N, 4, 2) world corners of the cars' boxes at rear-axle world ``poses`` (N, 3).

    ``local_corners`` (4, 2): the box in the car frame (x forward, y left, origin at the rear
    axle), as :attr:`RacecarPhysics._local_corners`.
    """
    c = np.cos(poses[:, 2])[:, None]
    s = np.sin(poses[:, 2])[:, None]
    lx, ly = local_corners[None, :, 0], local_corners[None, :, 1]
    out = np.empty((len(poses), 4, 2))
    out[:, :, 0] = poses[:, 0:1] + c * lx - s * ly
    out[:, :, 1] = poses[:, 1:2] + s * lx + c * ly
    return out


@nb.njit(cache=True, inline="always")
def _cut_by_cars(k, mx, my, th, boxes, radius, cos_a, sin_a, angle0, step, max_range, ranges):
    """Shorten ``ranges`` of the lidar at world (mx, my, th) of car ``k`` where a beam hits
    another car's box (``boxes`` (N, 4, 2) world corners; ``radius`` their bounding circle's
    radius about the box centre, metres)."""
    n = cos_a.shape[0]
    ct = math.cos(th)
    st = math.sin(th)
    for c in range(boxes.shape[0]):
        if c == k:
            continue
        cx = 0.25 * (boxes[c, 0, 0] + boxes[c, 1, 0] + boxes[c, 2, 0] + boxes[c, 3, 0])
        cy = 0.25 * (boxes[c, 0, 1] + boxes[c, 1, 1] + boxes[c, 2, 1] + boxes[c, 3, 1])
        ddx = cx - mx
        ddy = cy - my
        d = math.sqrt(ddx * ddx + ddy * ddy)
        if d - radius >= max_range:
            continue
        for shift in range(-1, 2):
            if d <= radius or step == 0.0:  # the lidar inside the circle: every beam
                if shift != 0:
                    continue
                i0 = 0
                i1 = n - 1
            else:
                phi = math.atan2(ddy, ddx) - th
                phi = (phi + math.pi) % _TWO_PI - math.pi + shift * _TWO_PI
                half = math.asin(radius / d)
                i0 = max(0, int(math.ceil((phi - half - angle0) / step)))
                i1 = min(n - 1, int(math.floor((phi + half - angle0) / step)))
            for i in range(i0, i1 + 1):
                bx = ct * cos_a[i] - st * sin_a[i]
                by = st * cos_a[i] + ct * sin_a[i]
                best = ranges[i]
                for e in range(4):
                    f = (e + 1) % 4
                    best = ray_segment(
                        mx, my, bx, by, boxes[c, e, 0], boxes[c, e, 1], boxes[c, f, 0],
                        boxes[c, f, 1], best,
                    )  # fmt: skip
                ranges[i] = best


@nb.njit(cache=True, inline="always")
def _race_one(field, poses, k, geometry, cos_a, sin_a, angle0, step, boxes, radius, seed, noise,
              ranges, out):  # fmt: skip
    x, y, th = poses[k, 0], poses[k, 1], poses[k, 2]
    if exact_one(field, x, y, th, geometry, cos_a, sin_a, ranges):
        return 1
    mount = geometry[6]
    mx = x + mount * math.cos(th)
    my = y + mount * math.sin(th)
    _cut_by_cars(k, mx, my, th, boxes, radius, cos_a, sin_a, angle0, step, geometry[8], ranges)
    return add_beam_noise(ranges, seed, noise, out)


@nb.njit(cache=True, nogil=True)
def race_scans_serial(field, poses, cars, geometry, cos_a, sin_a, angle0, step, boxes, radius,
                      seeds, noise, ranges, out, status):  # fmt: skip
    """The scans of cars ``cars`` (K,) into rows of ``ranges`` (exact, float64 metres), ``out``
    (noisy, float32 metres) and ``status`` (0 ok, 1 pose not finite, 2 range out of bounds).

    Args:
        field, geometry, cos_a, sin_a, noise: as :func:`racecar_sim.raycast.scan.scan_with_noise`.
        poses: (N, 3) rear-axle world poses of every car.
        angle0, step: the first beam's angle and the spacing (car frame, radians).
        boxes: (N, 4, 2) every car's world corners (:func:`car_boxes`); a car's own is skipped.
        radius: metres from a box's centre to its corners.
        seeds: (K,) int64 seeds of the scans' noise streams.
    """
    for j in range(cars.shape[0]):
        status[j] = _race_one(
            field, poses, cars[j], geometry, cos_a, sin_a, angle0, step, boxes, radius, seeds[j],
            noise, ranges[j], out[j],
        )  # fmt: skip


@nb.njit(cache=True, nogil=True)
def race_scans_shared(field, poses, cars, geometry, cos_a, sin_a, angle0, step, boxes, radius,
                      seeds, noise, ranges, out, status, chunk, counter):  # fmt: skip
    """:func:`race_scans_serial` in chunks of ``chunk`` cars taken from ``counter``: one thread of
    :func:`racecar_sim.raycast.shared_work.run_shared`."""
    n = cars.shape[0]
    while True:
        j0 = fetch_add(counter, 1) * chunk
        if j0 >= n:
            break
        for j in range(j0, min(n, j0 + chunk)):
            status[j] = _race_one(
                field, poses, cars[j], geometry, cos_a, sin_a, angle0, step, boxes, radius,
                seeds[j], noise, ranges[j], out[j],
            )  # fmt: skip
