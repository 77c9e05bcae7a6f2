"""Every car's lidar in one numba call: the walls, the other cars' boxes, then the beam noise.

A race scan is the single env's scan ([`racecar_sim.raycast.scan`][racecar_sim.raycast.scan]: the mount pose, the exact
cast on the grid, the four-part beam noise) with one stage between the cast and the noise: each
other car's footprint (its ``length x width`` box at its pose at scan time, world frame) cuts the
beams that hit it first, exactly ([`racecar_sim.world.obstacles.ray_segment()`][racecar_sim.world.obstacles.ray_segment] on the box's four
edges). The noise then treats a car like a wall.

Culling keeps the cost linear in the beams a car actually covers, not cars x beams: a car whose
bounding circle lies beyond ``max_range`` is skipped, and of the others only the beams inside the
angle their bounding circle subtends are tested (beams are evenly spaced, so that is an index
range), nearest car first, and a beam that already ends nearer than a car's bounding circle skips
it (a car hidden behind the one ahead costs a comparison per beam). The cars are cut before the
walls are cast: a beam that hit a car is cast on the grid only to just behind the car (the wall
cast's per-beam limits, [`racecar_sim.raycast.scan.exact_one()`][racecar_sim.raycast.scan.exact_one]), so the long beams down a
straight that the car ahead blocks cost a few cells. The result is, bit for bit, the full wall
cast cut by every other car's box (tested against that brute force).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.raycast.scan import add_beam_noise, exact_one
from racecar_sim.raycast.shared_work import fetch_add
from racecar_sim.world.obstacles import ray_segment

__all__ = ["car_boxes", "race_scans_serial", "race_scans_shared"]

_TWO_PI = 2.0 * math.pi
_SLACK = 1e-9  # metres: a bound on rounding, so that the skip below never drops a hit


def car_boxes(poses: np.ndarray, local_corners: np.ndarray) -> np.ndarray:
    """(N, 4, 2) world corners of the cars' boxes at rear-axle world ``poses`` (N, 3).

    ``local_corners`` (4, 2): the box in the car frame (x forward, y left, origin at the rear
    axle), as [`RacecarPhysics.local_corners`][racecar_sim.car.physics.RacecarPhysics.local_corners].
    """
    c = np.cos(poses[:, 2])[:, None]
    s = np.sin(poses[:, 2])[:, None]
    lx, ly = local_corners[None, :, 0], local_corners[None, :, 1]
    out = np.empty((len(poses), 4, 2))
    out[:, :, 0] = poses[:, 0:1] + c * lx - s * ly
    out[:, :, 1] = poses[:, 1:2] + s * lx + c * ly
    return out


@nb.njit(cache=True, inline="always")
def _cut_by_cars(k, mx, my, th, boxes, radius, cos_a, sin_a, angle0, step, max_range, order, dist,
                 ranges):  # fmt: skip
    """Shorten ``ranges`` of the lidar at world (mx, my, th) of car ``k`` where a beam hits
    another car's box nearer (``boxes`` (N, 4, 2) world corners; ``radius`` their bounding
    circle's radius about the box centre, metres; ``order``, ``dist``: (N,) scratch).

    The cars in range go nearest first, and a beam that already ends nearer than a car's bounding
    circle skips that car: a car hidden behind a nearer one costs a comparison per beam. Each hit
    is the nearest of `ray_segment()` on the box's four edges, so ``ranges`` ends as the
    minimum of what it held and every hit, whatever the order. Returns the number of cars in
    range.
    """
    n = cos_a.shape[0]
    ct = math.cos(th)
    st = math.sin(th)
    m = 0
    for c in range(boxes.shape[0]):  # the cars within range, sorted by distance (insertion)
        if c == k:
            continue
        cx = 0.25 * (boxes[c, 0, 0] + boxes[c, 1, 0] + boxes[c, 2, 0] + boxes[c, 3, 0])
        cy = 0.25 * (boxes[c, 0, 1] + boxes[c, 1, 1] + boxes[c, 2, 1] + boxes[c, 3, 1])
        ddx = cx - mx
        ddy = cy - my
        d = math.sqrt(ddx * ddx + ddy * ddy)
        if d - radius >= max_range:
            continue
        j = m
        while j > 0 and dist[j - 1] > d:
            dist[j] = dist[j - 1]
            order[j] = order[j - 1]
            j -= 1
        dist[j] = d
        order[j] = c
        m += 1
    for q in range(m):
        c = order[q]
        d = dist[q]
        near = d - radius - _SLACK  # no point of the box is nearer the lidar
        whole = d <= radius or step == 0.0  # the lidar inside the circle: every beam
        phi = 0.0
        half = 0.0
        if not whole:
            cx = 0.25 * (boxes[c, 0, 0] + boxes[c, 1, 0] + boxes[c, 2, 0] + boxes[c, 3, 0])
            cy = 0.25 * (boxes[c, 0, 1] + boxes[c, 1, 1] + boxes[c, 2, 1] + boxes[c, 3, 1])
            phi = math.atan2(cy - my, cx - mx) - th
            phi = (phi + math.pi) % _TWO_PI - math.pi
            half = math.asin(radius / d)
        for shift in range(-1, 2):
            if whole:
                if shift != 0:
                    continue
                i0 = 0
                i1 = n - 1
            else:
                centre = phi + shift * _TWO_PI
                i0 = max(0, int(math.ceil((centre - half - angle0) / step)))
                i1 = min(n - 1, int(math.floor((centre + half - angle0) / step)))
            for i in range(i0, i1 + 1):
                best = ranges[i]
                if best <= near:
                    continue
                bx = ct * cos_a[i] - st * sin_a[i]
                by = st * cos_a[i] + ct * sin_a[i]
                for e in range(4):
                    f = (e + 1) % 4
                    best = ray_segment(
                        mx, my, bx, by, boxes[c, e, 0], boxes[c, e, 1], boxes[c, f, 0],
                        boxes[c, f, 1], best,
                    )  # fmt: skip
                ranges[i] = best
    return m


@nb.njit(cache=True, inline="always")
def _race_one(field, poses, k, geometry, cos_a, sin_a, angle0, step, boxes, radius, seed, noise,
              work, where, order, dist, ranges, out):  # fmt: skip
    """One car's scan: the other cars' boxes first, then the walls, a beam that hit a car cast
    only to just behind it, then the noise; a status (as `race_scans_serial()`).

    Scratch: ``work`` (5, M) float64, ``where`` (M,) int64, ``order``, ``dist`` (N,).
    """
    x, y, th = poses[k, 0], poses[k, 1], poses[k, 2]
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(th)):
        return 1
    mount = geometry[6]
    mx = x + mount * math.cos(th)
    my = y + mount * math.sin(th)
    res = geometry[4]
    max_t = geometry[7]
    max_out = geometry[8]
    n = ranges.shape[0]
    for i in range(n):
        ranges[i] = max_out
    if not _cut_by_cars(k, mx, my, th, boxes, radius, cos_a, sin_a, angle0, step, max_out, order,
                        dist, ranges):  # fmt: skip
        exact_one(field, x, y, th, geometry, cos_a, sin_a, None, ranges)  # no car in range
        return add_beam_noise(ranges, seed, noise, out)
    # The beams no car stops are cast as usual (the kernel without limits, the fastest); those a
    # car stops only to a limit whose range lies beyond the car's hit (limit * res > hit), so
    # that a beam reaching its limit keeps the car's range below. Each beam's cast is its own
    # (the same doubles in any batch), so the result is the nearer of the full wall cast and the
    # car, as if every beam were cast to max_range.
    cos_w, sin_w, cut, walls, limits = work[0], work[1], work[2], work[3], work[4]
    n_open = 0
    for i in range(n):
        if ranges[i] >= max_out:
            where[n_open] = i
            cos_w[n_open] = cos_a[i]
            sin_w[n_open] = sin_a[i]
            n_open += 1
    n_cut = 0
    for i in range(n):
        r = ranges[i]
        if r < max_out:
            j = n_open + n_cut
            where[j] = i
            cos_w[j] = cos_a[i]
            sin_w[j] = sin_a[i]
            cut[n_cut] = r
            limits[n_cut] = min(max_t, r / res * (1.0 + 1e-9) + 1e-9)
            n_cut += 1
    exact_one(field, x, y, th, geometry, cos_w[:n_open], sin_w[:n_open], None, walls[:n_open])
    for j in range(n_open):
        ranges[where[j]] = walls[j]
    exact_one(field, x, y, th, geometry, cos_w[n_open:n], sin_w[n_open:n], limits[:n_cut],
              walls[n_open:n])  # fmt: skip
    for j in range(n_cut):  # the nearer of wall and car
        w = walls[n_open + j]
        ranges[where[n_open + j]] = w if w <= cut[j] else cut[j]
    return add_beam_noise(ranges, seed, noise, out)


@nb.njit(cache=True, nogil=True)
def race_scans_serial(field, poses, cars, geometry, cos_a, sin_a, angle0, step, boxes, radius,
                      seeds, noise, ranges, out, status):  # fmt: skip
    """The scans of cars ``cars`` (K,) into rows of ``ranges`` (exact, float64 metres), ``out``
    (noisy, float32 metres) and ``status`` (0 ok, 1 pose not finite, 2 range out of bounds).

    Args:
        field, geometry, cos_a, sin_a, noise: as [`racecar_sim.raycast.scan.scan_with_noise()`][racecar_sim.raycast.scan.scan_with_noise].
        poses: (N, 3) rear-axle world poses of every car.
        angle0, step: the first beam's angle and the spacing (car frame, radians).
        boxes: (N, 4, 2) every car's world corners (`car_boxes()`); a car's own is skipped.
        radius: metres from a box's centre to its corners.
        seeds: (K,) int64 seeds of the scans' noise streams.
    """
    m = cos_a.shape[0]
    work, where = np.empty((5, m)), np.empty(m, dtype=np.int64)
    order, dist = np.empty(poses.shape[0], dtype=np.int64), np.empty(poses.shape[0])
    for j in range(cars.shape[0]):
        status[j] = _race_one(
            field, poses, cars[j], geometry, cos_a, sin_a, angle0, step, boxes, radius, seeds[j],
            noise, work, where, order, dist, ranges[j], out[j],
        )  # fmt: skip


@nb.njit(cache=True, nogil=True)
def race_scans_shared(field, poses, cars, geometry, cos_a, sin_a, angle0, step, boxes, radius,
                      seeds, noise, ranges, out, status, chunk, counter):  # fmt: skip
    """`race_scans_serial()` in chunks of ``chunk`` cars taken from ``counter``: one thread of
    [`racecar_sim.raycast.shared_work.run_shared()`][racecar_sim.raycast.shared_work.run_shared]."""
    n = cars.shape[0]
    m = cos_a.shape[0]
    work, where = np.empty((5, m)), np.empty(m, dtype=np.int64)
    order, dist = np.empty(poses.shape[0], dtype=np.int64), np.empty(poses.shape[0])
    while True:
        j0 = fetch_add(counter, 1) * chunk
        if j0 >= n:
            break
        for j in range(j0, min(n, j0 + chunk)):
            status[j] = _race_one(
                field, poses, cars[j], geometry, cos_a, sin_a, angle0, step, boxes, radius,
                seeds[j], noise, work, where, order, dist, ranges[j], out[j],
            )  # fmt: skip
