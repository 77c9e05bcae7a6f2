"""Cars touching cars: each car's pymunk space holds the cars near it as moving boxes.

Every car keeps its own [`RacecarPhysics`][racecar_sim.car.physics.RacecarPhysics] (its space, its walls, its
free steps), so the race's car is exactly the single env's car. Before a step, the cars that could
touch within it (bounding circles closer than their reach) see each other: car ``j`` appears in
car ``i``'s space as a kinematic box ("ghost") at ``j``'s pose, moving with ``j``'s velocity over
the step, and the other way round. pymunk's contact solver then stops each car at the other's
box (no overlap beyond pymunk's slop), and a ghost that keeps moving pushes the car it hits, so two
cars driven into each other separate. Cars near another car step through pymunk; the others keep
their free steps. The ghost boxes go when the cars are apart again.

Contacts are recorded per car and step: ``-1`` for a wall, ``j`` for car ``j``.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from racecar_sim.car.physics import CAR_COLLISION_TYPE, WALL_COLLISION_TYPE, RacecarPhysics

__all__ = ["GHOST_COLLISION_TYPE", "WALL", "CarContacts", "box_centres", "near_pairs"]

GHOST_COLLISION_TYPE = 3
"""pymunk collision type of another car's box in a car's space."""
WALL = -1
"""Contact index of a wall (or anything of the map)."""
_MARGIN = 0.1  # metres added to the reach of two cars before they see each other


def box_centres(poses: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(N, 2) world centres of the boxes of cars at rear-axle world ``poses`` (N, 3), the box's
    centre at ``centre`` (2,) in the car frame (metres)."""
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    out = np.empty((len(poses), 2))
    out[:, 0] = poses[:, 0] + (c * centre[0] - s * centre[1])
    out[:, 1] = poses[:, 1] + (s * centre[0] + c * centre[1])
    return out


def near_pairs(
    centres: np.ndarray, radius: float, travel: np.ndarray, pairs: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    """(P, 2) index pairs i < j of the cars that could touch within a step.

    Args:
        centres: (N, 2) world centres of the boxes, metres.
        radius: metres from a box's centre to its corners.
        travel: (N,) metres each box's centre can move within the step.
        pairs: every pair (i, j), i < j, as ``numpy.triu_indices(N, 1)``.
    """
    i, j = pairs
    d = centres[i] - centres[j]
    near = np.hypot(d[:, 0], d[:, 1]) < 2.0 * radius + travel[i] + travel[j] + _MARGIN
    return np.stack([i[near], j[near]], axis=1)


class CarContacts:
    """Which cars see which in their pymunk spaces, and what each car touched in a step.

    Args:
        physics: every car's physics (one map, one car model).
    """

    def __init__(self, physics: list[RacecarPhysics]) -> None:
        self.physics = physics
        n = len(physics)
        self.touched: list[set[int]] = [set() for _ in range(n)]
        """Per car, what it touched since `clear()`: `WALL` or other cars' indices."""
        self._ghosts: dict[tuple[int, int], tuple[pymunk.Body, pymunk.Poly]] = {}
        self._shown: set[tuple[int, int]] = set()  # (i, j): car j's ghost is in car i's space
        self._busy: set[int] = set()  # cars with a ghost in their space (no free steps)
        self._hit: set[int] = set()  # cars whose touched set is not empty
        self._owner: dict[int, int] = {}  # id(ghost shape) -> the car it stands for
        corners = [tuple(p) for p in physics[0].local_corners.tolist()]
        self._corners = corners
        for i, p in enumerate(physics):
            space = p.space
            space.on_collision(CAR_COLLISION_TYPE, WALL_COLLISION_TYPE, pre_solve=self._wall(i))
            space.on_collision(CAR_COLLISION_TYPE, GHOST_COLLISION_TYPE, pre_solve=self._car(i))

    # ------------------------------------------------------------------ pymunk callbacks
    def _wall(self, i: int):
        physics, touched, hit = self.physics[i], self.touched[i], self._hit

        def on_wall(arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
            physics.mark_contact()
            touched.add(WALL)
            hit.add(i)

        return on_wall

    def _car(self, i: int):
        physics, touched, owner, hit = self.physics[i], self.touched[i], self._owner, self._hit

        def on_car(arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
            physics.mark_contact()
            a, b = arbiter.shapes
            touched.add(owner[id(b if a.collision_type == CAR_COLLISION_TYPE else a)])
            hit.add(i)

        return on_car

    # ------------------------------------------------------------------ per step
    def clear(self) -> None:
        """Forget the contacts of the last step."""
        for i in self._hit:
            self.touched[i].clear()
        self._hit.clear()

    def remove_all(self) -> None:
        """Take every ghost out of every space (a reset)."""
        for i, j in list(self._shown):
            self._hide(i, j)
        for p in self.physics:
            p.free_steps = True
        self._busy = set()

    def show(self, pairs: np.ndarray, poses: np.ndarray, velocities: np.ndarray) -> None:
        """Show each other the cars of ``pairs`` (P, 2), hide the rest.

        Args:
            pairs: index pairs from `near_pairs()`.
            poses: (N, 3) rear-axle world poses at the start of the step.
            velocities: (N, 3) world velocities [vx, vy, omega] of the rear axles (m/s, rad/s)
                over the step; the ghosts move with them.
        """
        if not len(pairs) and not self._shown:  # nobody near anybody, as before
            return
        want: set[tuple[int, int]] = set()
        for i, j in pairs.tolist():
            want.add((i, j))
            want.add((j, i))
        for key in self._shown - want:
            self._hide(*key)
        for i, j in want:
            body = self._ghost(i, j)
            body.position = (float(poses[j, 0]), float(poses[j, 1]))
            body.angle = float(poses[j, 2])
            body.velocity = (float(velocities[j, 0]), float(velocities[j, 1]))
            body.angular_velocity = float(velocities[j, 2])
            if (i, j) not in self._shown:
                self.physics[i].space.add(body, self._ghosts[(i, j)][1])
                self._shown.add((i, j))
        busy = {i for i, _ in want}
        for i in busy ^ self._busy:  # pymunk must see the other car's box
            self.physics[i].free_steps = i not in busy
        self._busy = busy

    def _ghost(self, i: int, j: int) -> pymunk.Body:
        ghost = self._ghosts.get((i, j))
        if ghost is None:
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            shape = pymunk.Poly(body, self._corners)
            shape.collision_type = GHOST_COLLISION_TYPE
            shape.friction = self.physics[i].shape.friction
            shape.elasticity = 0.0
            ghost = (body, shape)
            self._ghosts[(i, j)] = ghost
            self._owner[id(shape)] = j
        return ghost[0]

    def _hide(self, i: int, j: int) -> None:
        body, shape = self._ghosts[(i, j)]
        self.physics[i].space.remove(body, shape)
        self._shown.discard((i, j))


def bounding_radius(local_corners: np.ndarray) -> float:
    """Metres from the box's centre to its farthest corner."""
    centre = local_corners.mean(axis=0)
    return float(math.sqrt(((local_corners - centre) ** 2).sum(axis=1).max()))
