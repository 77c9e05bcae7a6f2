"""The car as pymunk sees it: a dynamic body whose origin (and centre of gravity) is the rear axle,
a box footprint of ``length x width`` starting ``rear_overhang`` behind the axle (car frame: x
forward, y left, metres), and a detached copy of the footprint for overlap queries at any pose."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymunk

from racecar_sim.car.models.params import CarParams
from racecar_sim.car.walls import WALL_FRICTION

__all__ = ["CAR_COLLISION_TYPE", "CarBody", "footprint_corners", "make_car_body"]

CAR_COLLISION_TYPE = 1
_CAR_CATEGORY = 0b10  # pymunk shape-filter category bit of the car
_EXTENT_MARGIN = 0.5  # metres added to the farthest corner's distance from the rear axle


def footprint_corners(car: CarParams) -> np.ndarray:
    """(4, 2) car-frame corners of the footprint, metres from the rear axle (rear right, front
    right, front left, rear left)."""
    front = car.length - car.rear_overhang
    half = car.width / 2
    return np.array(
        [[-car.rear_overhang, -half], [front, -half], [front, half], [-car.rear_overhang, half]]
    )


@dataclass
class CarBody:
    """The pymunk parts of one car (see `make_car_body()`).

    Attributes:
        body: the dynamic body, origin at the rear axle.
        shape: its footprint polygon (collision type `CAR_COLLISION_TYPE`).
        query_body: a kinematic body carrying `query_shape`, never added to a space.
        query_shape: the same footprint, seeing the walls but not the car itself.
        corners: (4, 2) car-frame corners (`footprint_corners()`).
        extent: metres from the rear axle to the farthest corner, plus a margin.
    """

    body: pymunk.Body
    shape: pymunk.Poly
    query_body: pymunk.Body
    query_shape: pymunk.Poly
    corners: np.ndarray
    extent: float


def make_car_body(car: CarParams, space: pymunk.Space) -> CarBody:
    """Build the car's body and footprint and add them to ``space``; the moment of inertia is the
    box's about the rear axle (its own plus ``mass * |centroid|^2``)."""
    corners_array = footprint_corners(car)
    corners = [tuple(p) for p in corners_array.tolist()]
    extent = float(np.hypot(*corners_array.T).max()) + _EXTENT_MARGIN
    centroid = corners_array.mean(axis=0)
    moment = pymunk.moment_for_poly(car.mass, corners) + car.mass * float(centroid @ centroid)
    body = pymunk.Body(car.mass, moment, body_type=pymunk.Body.DYNAMIC)
    shape = pymunk.Poly(body, corners)
    shape.collision_type = CAR_COLLISION_TYPE
    shape.friction = WALL_FRICTION
    shape.elasticity = 0.0
    space.add(body, shape)
    query_body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    query_shape = pymunk.Poly(query_body, corners)
    shape.filter = pymunk.ShapeFilter(categories=_CAR_CATEGORY)
    query_shape.filter = pymunk.ShapeFilter(mask=pymunk.ShapeFilter.ALL_MASKS() ^ _CAR_CATEGORY)
    return CarBody(body, shape, query_body, query_shape, corners_array, extent)
