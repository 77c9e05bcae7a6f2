"""The kinematic bicycle about the rear axle, and the actuator limits every car model shares.

The car has no slip: each substep its rear axle moves along the heading at ``speed`` (the rear
wheels' rolling speed, m/s) and it turns at ``omega = speed * tan(steer) / wheelbase`` (rad/s).
The command [steer (rad), speed (m/s)] is followed within the steering-rate and acceleration
limits (`actuate()`), once per substep of ``h`` seconds.

These are plain floating-point operations in a fixed order, so calling them from Python (the
pymunk path of [`racecar_sim.car.physics`][racecar_sim.car.physics]) and from numba ([`racecar_sim.car.free_steps`][racecar_sim.car.free_steps]) gives
the same doubles.
"""

from __future__ import annotations

import math

import numba as nb

__all__ = ["actuate", "yaw_rate"]


@nb.njit(cache=True)
def actuate(steer, speed, target_steer, target_speed, max_dsteer, accel, decel):
    """One substep of the actuators: (steer rad, speed m/s) moved towards the (clipped) targets.

    ``max_dsteer`` is the steering-rate limit times the substep (rad), ``accel`` / ``decel`` the
    speed change allowed when speeding up / braking (m/s). A sign change brakes to a stop first.
    """
    steer += min(max(target_steer - steer, -max_dsteer), max_dsteer)
    if speed > 0.0 and target_speed < speed:  # braking forwards: stop before reversing
        speed = max(speed - decel, target_speed, 0.0)
    elif speed < 0.0 and target_speed > speed:  # braking backwards
        speed = min(speed + decel, target_speed, 0.0)
    else:  # at rest, or speeding up in the direction of motion
        speed += min(max(target_speed - speed, -accel), accel)
    return steer, speed


@nb.njit(cache=True)
def yaw_rate(speed, steer, inv_wheelbase):
    """Turn rate of the kinematic bicycle, rad/s, for a rear-axle ``speed`` (m/s) and ``steer`` (rad)."""
    return speed * math.tan(steer) * inv_wheelbase
