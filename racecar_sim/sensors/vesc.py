"""What the car's electronics measure of its own motion: the VESC's wheel odometry, its lead over
the body's motion, and an optional IMU gyro.

Wheel odometry (``obs["odom"]``)
    A VESC knows the motor's speed (ERPM through the gear ratio: the *wheel* speed) and the steering
    servo's angle; the MIT racecar's ``vesc_to_odom`` turns them into a car-frame twist with the
    kinematic bicycle formula::

        vx = wheel_speed,   vy = 0,   omega = wheel_speed * tan(steer) / wheelbase

    (`wheel_twist()`). It never sees the body slide: in a slide the true yaw rate and lateral
    speed differ from these, exactly as on the real car. The reading is instantaneous, taken at the
    end of each env step.

Lead (``odom_lead`` seconds)
    On the real car ``/vesc/odom`` leads the motion that the scans see by about 0.13 s
    (`mcl.calibration.odometry_fit.best_lag()`): the motor and the servo act on a command at
    once and the VESC reports them, but the body follows later (drivetrain and tire compliance,
    servo linkage). Simulated causally: the *body* (the physics) receives each command ``n =
    round(odom_lead / dt)`` steps late (`CommandDelay`), while the odometry reports the
    wheel state the actuators already have, which is the state the physics will reach ``n`` steps
    later: the physics' current wheel speed and steering angle driven through the car's steering
    rate and acceleration limits by the ``n`` commands still on their way (`actuate()`, the
    same arithmetic as `racecar_sim.car.physics.RacecarPhysics.step()`). Nothing is read from the
    future: the odometry is computed from commands already given.

IMU (``obs["imu"]``, off unless ``imu`` is set)
    A gyro's yaw rate: the true yaw rate of the body over the step (``info["twist"][2]``) plus a
    constant bias and white noise (`ImuParams`). It sees the slide that the wheel odometry
    misses.
"""

from __future__ import annotations

import math
from collections import deque

import numba as nb
import numpy as np

from racecar_sim.car.models.kinematic import actuate as substep_actuate
from racecar_sim.sensors.imu import ImuParams
from racecar_sim.settings.config import CarParams

__all__ = ["CommandDelay", "ImuParams", "actuate", "lead_steps", "vesc_odometry", "wheel_twist"]


def wheel_twist(wheel_speed: float, steer: float, wheelbase: float) -> tuple[float, float, float]:
    """The VESC's car-frame twist (vx m/s, vy m/s, omega rad/s) from the wheel speed (m/s) and the
    front wheel angle (radians): the kinematic bicycle formula, no lateral speed."""
    return wheel_speed, 0.0, wheel_speed * math.tan(steer) / wheelbase


@nb.njit(cache=True)
def vesc_odometry(
    steer: np.ndarray,
    wheel_speed: np.ndarray,
    wheelbase: float,
    z: np.ndarray,
    prop: np.ndarray,
    add: np.ndarray,
    out: np.ndarray,
) -> None:
    """The noisy VESC odometry of K cars: `wheel_twist()` of each, then the noise of
    [`racecar_sim.sensors.odometry.Odometry.noisy()`][racecar_sim.sensors.odometry.Odometry.noisy] (the same double operations, so the same floats).

    Args:
        steer: (K,) front wheel angles, radians.
        wheel_speed: (K,) rear wheel speeds, m/s.
        wheelbase: metres.
        z: (K, 6) each car's six standard normals, the first three proportional.
        prop: (3,) the proportional noise scales (vx, vy, omega).
        add: (3,) the additive noise scales (m/s, m/s, rad/s).
        out: (K, 3) float32, the car-frame twists [vx m/s, vy m/s, omega rad/s].
    """
    for j in range(steer.shape[0]):
        ws = wheel_speed[j]
        twist = (ws, 0.0, ws * math.tan(steer[j]) / wheelbase)
        for c in range(3):
            out[j, c] = twist[c] * (1.0 + prop[c] * z[j, c]) + add[c] * z[j, 3 + c]


def actuate(
    steer: float,
    speed: float,
    target_steer: float,
    target_speed: float,
    car: CarParams,
    dt: float,
    substep: float,
) -> tuple[float, float]:
    """The wheel angle (rad) and wheel speed (m/s) after ``dt`` seconds of a command already
    clipped to the car's limits, from ``steer``, ``speed``: the steering-rate, acceleration and
    braking limits (`racecar_sim.car.models.kinematic.actuate()`) substep by substep, as
    `racecar_sim.car.physics.RacecarPhysics.step()` applies them (no wall is known here). The
    kinematic car's wheels follow exactly this; the single-track car's speed servo also meets the
    friction and motor-power limits, which this leaves out."""
    n_sub = max(1, math.ceil(dt / substep - 1e-9))
    h = dt / n_sub
    max_dsteer = car.max_steer_rate * h
    accel = car.max_accel * h
    decel = car.max_decel * h
    for _ in range(n_sub):
        steer, speed = substep_actuate(
            steer, speed, target_steer, target_speed, max_dsteer, accel, decel
        )
    return steer, speed


def lead_steps(lead: float, dt: float) -> int:
    """Whole env steps of ``lead`` seconds at ``dt`` seconds per step (rounded to the nearest)."""
    return int(round(lead / dt))


class CommandDelay:
    """The commands on their way from the VESC to the body: a FIFO of ``n`` clipped commands.

    Args:
        n: steps of delay (0: every command goes through at once).
        car: the car's limits (for `wheels_ahead()`).
        dt: seconds per env step; substep: the physics' longest substep, seconds.
    """

    def __init__(self, n: int, car: CarParams, dt: float, substep: float) -> None:
        self.n = int(n)
        self.car = car
        self.dt = float(dt)
        self.substep = float(substep)
        self._queue: deque[tuple[float, float]] = deque()

    def reset(self, steer: float, speed: float) -> None:
        """Empty the queue, filled with the command that holds the wheels at ``steer``, ``speed``."""
        self._queue = deque([(steer, speed)] * self.n)

    def push(self, steer: float, speed: float) -> tuple[float, float]:
        """Queue the new command; returns the one that reaches the body now (n steps old)."""
        if self.n == 0:
            return steer, speed
        self._queue.append((steer, speed))
        return self._queue.popleft()

    def wheels_ahead(self, steer: float, speed: float) -> tuple[float, float]:
        """The wheel angle and speed the actuators have now, for a body whose wheels are at
        ``steer`` (rad), ``speed`` (m/s): those driven by the commands still queued."""
        for target_steer, target_speed in self._queue:
            steer, speed = actuate(
                steer, speed, target_steer, target_speed, self.car, self.dt, self.substep
            )
        return steer, speed
