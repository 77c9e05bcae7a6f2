"""Random start poses: where the car's box fits with room around it, and a collision-free pose
drawn there (world frame, rear axle, metres and radians)."""

from __future__ import annotations

import math
import threading
import weakref

import numpy as np

from racecar_sim.car.models.params import CarParams
from racecar_sim.car.physics import RacecarPhysics
from racecar_sim.maps import MapError, OccupancyMap

__all__ = ["START_TRIES", "random_start", "shared_start_cells", "start_cells"]

START_TRIES = 1000
"""Random start poses tried before giving up."""


def start_cells(occupancy_map: OccupancyMap, car: CarParams, clearance: float) -> np.ndarray:
    """Row-major flat indices (K,) of the cells where the car's box fits at any heading with
    ``clearance`` metres of room (8 bytes a cell, not a (K, 2) array of centres).

    Raises:
        MapError: no cell has that room (naming ``start_clearance`` when the car fits without it).
    """
    half_diagonal = 0.5 * math.hypot(car.length, car.width)
    slack = math.sqrt(2.0) * occupancy_map.resolution  # cell-centre distances vs points in cells
    need = half_diagonal + slack
    distance = occupancy_map.distance
    cells = np.flatnonzero(distance >= need + clearance)
    if len(cells):
        return cells
    if clearance > 0 and np.any(distance >= need):
        most = float(distance.max()) - need
        raise MapError(
            f"map {occupancy_map.name!r} has no place where the car has start_clearance = "
            f"{clearance:g} m of room around it (at most {max(most, 0.0):.2f} m here); "
            "lower start_clearance"
        )
    raise MapError(
        f"map {occupancy_map.name!r} has no place {2 * need:.2f} m wide where the car fits"
    )


_shared: dict[tuple[int, float, float, float], tuple[weakref.ref, np.ndarray]] = {}
_shared_lock = threading.Lock()


def shared_start_cells(
    occupancy_map: OccupancyMap, car: CarParams, clearance: float
) -> np.ndarray:
    """`start_cells`, built once per map object, car size and clearance and shared (a
    read-only array) by every car that asks while the map lives: on the Stata basement the table
    is about 2.7 MB, which each car of a vector env or a race would otherwise hold.

    Raises:
        MapError: as `start_cells`.
    """
    key = (id(occupancy_map), float(car.length), float(car.width), float(clearance))
    with _shared_lock:
        hit = _shared.get(key)
        if hit is not None and hit[0]() is occupancy_map:
            return hit[1]
    cells = start_cells(occupancy_map, car, clearance)
    cells.setflags(write=False)

    def forget(_ref: weakref.ref, key: tuple = key) -> None:
        with _shared_lock:
            entry = _shared.get(key)
            if entry is not None and entry[0] is _ref:
                del _shared[key]

    with _shared_lock:
        _shared[key] = (weakref.ref(occupancy_map, forget), cells)
    return cells


def random_start(
    physics: RacecarPhysics, cells: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """A rear-axle world pose [x, y, theta] whose footprint is free, its box centre in one of
    ``cells`` (from `start_cells()`), the heading uniform; drawn from ``rng``.

    Raises:
        MapError: no free pose in `START_TRIES` tries.
    """
    car = physics.car
    occupancy_map = physics.map
    ahead = car.length / 2 - car.rear_overhang  # metres from the rear axle to the box centre
    res = occupancy_map.resolution
    width = occupancy_map.width
    for _ in range(START_TRIES):
        row, col = divmod(int(cells[rng.integers(len(cells))]), width)
        centre = occupancy_map.grid_to_world(np.array([row, col]))
        cx, cy = centre + (rng.random(2) - 0.5) * res
        theta = rng.uniform(-math.pi, math.pi)
        pose = np.array([cx - ahead * math.cos(theta), cy - ahead * math.sin(theta), theta])
        if physics.pose_is_free(pose):
            return pose
    raise MapError(
        f"map {occupancy_map.name!r}: found no free start pose for the car in {START_TRIES} tries"
    )
