"""Free steps of many cars in one numba call, for the vector env.

Each car keeps its own [`RacecarPhysics`][racecar_sim.car.physics.RacecarPhysics]; here their free-step state
([`STATE_FIELDS`][racecar_sim.car.free_steps.STATE_FIELDS]) and twist arrays become rows of two shared arrays,
so that one kernel call steps every car that may step without pymunk (far from walls, no contact
cached) exactly as [`RacecarPhysics.step()`][RacecarPhysics.step] would: the same checks, the same
[`free_step()`][racecar_sim.car.free_steps.free_step], the same bookkeeping. A car the kernel declines (a wall
within reach) and a car that may not step freely take [`RacecarPhysics.step()`][RacecarPhysics.step] as usual.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.car.free_steps import STATE_FIELDS, free_step
from racecar_sim.car.physics import RacecarPhysics

__all__ = ["FreeStepBatch"]

_TWO_PI = 2.0 * math.pi


@nb.njit(cache=True)
def _free_steps(distance, const, states, cars, targets, n_sub, h, dt, twists, ok) -> None:
    for j in range(cars.shape[0]):
        k = cars[j]
        ok[j] = free_step(
            distance, const, states[k], targets[k, 0], targets[k, 1], n_sub, h, dt, twists[k]
        )


class FreeStepBatch:
    """The free steps of the cars ``physics`` (one map, one car model), stepped together.

    Each car keeps its free-step state and twist in rows of ``states`` and ``twists``
    (``RacecarPhysics.share_state``).
    """

    def __init__(self, physics: list[RacecarPhysics]) -> None:
        self.physics = physics
        n = len(physics)
        self.states = np.zeros((n, len(STATE_FIELDS)))
        self.twists = np.zeros((n, 3))
        for i, p in enumerate(physics):
            p.share_state(self.states[i], self.twists[i])
        first = physics[0]
        car = first.car
        self._const = first.free_constants
        self._distance = first.map.distance
        self._low = np.array([-car.max_steer, -car.max_reverse_speed])
        self._high = np.array([car.max_steer, car.max_speed])

    def step(self, cars: list[int], commands: np.ndarray, dt: float) -> tuple[np.ndarray, list[int]]:
        """Step cars ``cars`` by their rows of ``commands`` (N, 2) = [steer rad, speed m/s] (finite)
        for ``dt`` seconds.

        Returns:
            (collided per car of ``cars``, the cars that stepped freely: their pose is in
            `states`, see `poses()`).
        """
        physics = self.physics
        free: list[int] = []
        for i in cars:
            if physics[i].may_step_freely():
                free.append(i)
        collided = np.zeros(len(cars), dtype=np.bool_)
        done: set[int] = set()
        if free:
            p0 = physics[free[0]]
            n_sub = max(1, math.ceil(dt / p0.substep - 1e-9))
            h = dt / n_sub
            targets = np.minimum(np.maximum(commands, self._low), self._high)
            idx = np.array(free, dtype=np.int64)
            ok = np.zeros(len(free), dtype=np.bool_)
            _free_steps(
                self._distance, self._const, self.states, idx, targets, n_sub, h, dt, self.twists,
                ok,
            )  # fmt: skip
            for j in np.flatnonzero(ok).tolist():
                physics[free[j]].stepped_freely(h)
            if len(free) == len(cars) and ok.all():  # the usual case: every car stepped freely
                return collided, free
            done = {free[j] for j in np.flatnonzero(ok).tolist()}
        stepped_free = [i for i in cars if i in done]
        for j, i in enumerate(cars):
            if i not in done:
                collided[j] = physics[i].step((commands[i, 0], commands[i, 1]), dt)
        return collided, stepped_free

    def poses(self, cars: list[int]) -> np.ndarray:
        """(len(cars), 3) rear-axle world poses of cars that stepped freely (as
        [`RacecarPhysics.pose`][RacecarPhysics.pose]: the heading wrapped to [-pi, pi))."""
        rows = self.states[cars, :3]
        rows[:, 2] = np.remainder(rows[:, 2] + math.pi, _TWO_PI) - math.pi
        return rows
