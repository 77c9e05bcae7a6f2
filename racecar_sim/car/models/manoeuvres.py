"""Open-loop manoeuvres of a car model in free space: command sequences and skidpad circles.

These drive [`racecar_sim.car.free_steps.advance()`][racecar_sim.car.free_steps.advance], which is what `RacecarPhysics` does far
from walls (bit for bit), so they measure the simulator's car, not a copy of it. Used by the unit
tests of the vehicle models and by ``racecar-sim bench dynamics``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from racecar_sim.car.free_steps import STATE_FIELDS, advance, free_constants

__all__ = ["Circle", "drive", "skidpad"]

_X, _Y, _A, _STEER, _SPEED, _OMEGA, _LATERAL, _R = 0, 1, 2, 6, 7, 8, 9, 10


def drive(car, car_model: str, commands: np.ndarray, dt: float, substep: float = 0.005) -> np.ndarray:
    """Drive from rest at the origin (heading 0) through ``commands`` (K, 2) = [steer rad, speed
    m/s] held ``dt`` seconds each, in substeps no longer than ``substep`` seconds.

    Returns:
        (K + 1, 8) float64 rows [x, y, theta (unwrapped), steer, wheel speed, slip angle, yaw
        rate, speed] after each step, the start first: the rear axle's world pose (m, rad), the
        steering angle (rad), the rear wheels' rolling speed (m/s), the body slip angle at the
        centre of gravity (rad), the yaw rate (rad/s) and the speed of the centre of gravity
        (m/s). The kinematic car's slip angle is the geometric ``atan(lr tan(steer) / L)``.
    """
    const = free_constants(car, None, 0.0, car_model)
    state = np.zeros(len(STATE_FIELDS))
    twist = np.zeros(3)
    n_sub = max(1, math.ceil(dt / substep - 1e-9))
    h = dt / n_sub
    lo = (-car.max_steer, -car.max_reverse_speed)
    hi = (car.max_steer, car.max_speed)
    commands = np.asarray(commands, dtype=np.float64)
    out = np.zeros((len(commands) + 1, 8))
    q = car.cg_to_rear / car.wheelbase
    kinematic = car_model == "kinematic"
    for k in range(len(commands) + 1):
        if k:
            steer = min(max(commands[k - 1, 0], lo[0]), hi[0])
            speed = min(max(commands[k - 1, 1], lo[1]), hi[1])
            advance(const, state, steer, speed, n_sub, h, dt, twist)
        u = state[_SPEED]
        if kinematic:
            slip, yaw_rate = math.atan(q * math.tan(state[_STEER])), state[_OMEGA]
            speed = u / math.cos(slip)
        else:
            slip, yaw_rate = math.atan2(state[_LATERAL], u), state[_R]
            speed = math.hypot(u, state[_LATERAL])
        out[k] = (state[_X], state[_Y], state[_A], state[_STEER], u, slip, yaw_rate, speed)
    return out


@dataclass(frozen=True)
class Circle:
    """A steady-state circle at fixed steer and speed (all of the centre of gravity).

    Attributes:
        steer: rad. speed: m/s, the speed of the centre of gravity (over the ground).
        radius: m, ``speed / yaw_rate``. rear_radius: m, the rear axle's, ``speed cos(slip) /
        yaw_rate``. yaw_rate: rad/s. lateral_accel: m/s², ``speed * yaw_rate``.
        slip_angle: rad, body slip angle at the centre of gravity.
        steady: whether the yaw rate over the last second varied by under 1 %.
    """

    steer: float
    speed: float
    radius: float
    rear_radius: float
    yaw_rate: float
    lateral_accel: float
    slip_angle: float
    steady: bool


def skidpad(
    car, car_model: str, steer: float, speed: float, dt: float = 0.01, duration: float = 10.0,
    substep: float = 0.005,
) -> Circle:  # fmt: skip
    """Drive at fixed ``steer`` (rad) and wheel ``speed`` (m/s) for ``duration`` seconds from rest
    and measure the circle of the centre of gravity at the end."""
    n = max(2, round(duration / dt))
    rows = drive(car, car_model, np.tile([steer, speed], (n, 1)), dt, substep)
    last = rows[-max(2, round(1.0 / dt)) :]
    v, beta, r = rows[-1, 7], rows[-1, 5], rows[-1, 6]
    spread = float(np.ptp(last[:, 6]))
    steady = spread <= 0.01 * max(abs(float(np.mean(last[:, 6]))), 1e-9)
    radius = v / r if r != 0 else math.inf
    return Circle(
        steer=steer, speed=v, radius=radius, rear_radius=radius * math.cos(beta), yaw_rate=r,
        lateral_accel=v * r, slip_angle=beta, steady=steady,
    )  # fmt: skip
