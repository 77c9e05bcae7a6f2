"""numba kernel of the physics' free steps (see :mod:`racecar_sim.physics`, "Free steps").

Far from every wall a pymunk substep only moves the car's body by the velocity set at the previous
substep and then calls the velocity function. :func:`free_step` performs the same floating-point
operations in the same order (``p + (v + 0) * h``, ``a + (w + 0) * h``, then the bicycle velocity
at the mid-substep heading), so the result is bit for bit pymunk's; it first checks on the map's
distance field that no wall is within reach during the step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["CONSTANT_FIELDS", "STATE_FIELDS", "free_step", "se2_log_twist"]

STATE_FIELDS = ("x", "y", "angle", "vx", "vy", "w", "steer", "speed", "omega")
"""Layout of the float64 state array: rear-axle world pose (m, rad, angle unwrapped as pymunk's),
body velocity (m/s, rad/s), wheel angle (rad), wheel speed (m/s), commanded turn rate (rad/s)."""

CONSTANT_FIELDS = ("max_steer_rate", "max_accel", "max_decel", "wheelbase", "ahead", "reach",
                   "centre_speed", "origin_x", "origin_y", "cos_yaw", "sin_yaw", "inv_res",
                   "height", "width", "margin")  # fmt: skip
"""Layout of the float64 constants array: car limits (rad/s, m/s², m/s², m); rear axle to the
footprint's centre (m); the footprint's half diagonal plus one cell diagonal (m); the bound on the
centre's speed per unit wheel speed; the map's origin, yaw, 1 / resolution and size (cells); the
margin kept from the walls (m)."""


@nb.njit(cache=True)
def se2_log_twist(dx, dy, theta0, dtheta, dt):
    """Constant car-frame twist (vx, vy, omega) moving heading ``theta0`` by (dx, dy), dtheta in dt."""
    c, s = math.cos(theta0), math.sin(theta0)
    lx, ly = c * dx + s * dy, c * dy - s * dx
    if abs(dtheta) < 1e-6:
        a, b = 1.0 - dtheta * dtheta / 6.0, 0.5 * dtheta
    else:
        a, b = math.sin(dtheta) / dtheta, (1.0 - math.cos(dtheta)) / dtheta
    k = 1.0 / ((a * a + b * b) * dt)
    return (a * lx + b * ly) * k, (a * ly - b * lx) * k, dtheta / dt


@nb.njit(cache=True)
def free_step(distance, const, state, target_steer, target_speed, n_sub, h, dt, twist) -> bool:
    """Drive ``n_sub`` substeps of ``h`` seconds without pymunk if no wall is within reach.

    Args:
        distance: (H, W) the map's distance field, metres between cell centres.
        const: float64 laid out as :data:`CONSTANT_FIELDS`.
        state: float64 laid out as :data:`STATE_FIELDS`, updated in place.
        target_steer, target_speed: the command, already clipped to the car's limits.
        twist: (3,) output, the step's car-frame twist (SE(2) logarithm over ``dt``).

    Returns:
        False (nothing changed) when a wall could be reached within the step.
    """
    x, y, a = state[0], state[1], state[2]
    steer, speed = state[6], state[7]
    reach = dt * max(abs(speed), abs(target_speed)) * const[6]
    ddx = x + const[4] * math.cos(a) - const[7]
    ddy = y + const[4] * math.sin(a) - const[8]
    c, s, inv_res = const[9], const[10], const[11]
    height, width = int(const[12]), int(const[13])
    col = int(math.floor((c * ddx + s * ddy) * inv_res))
    row = height - 1 - int(math.floor((c * ddy - s * ddx) * inv_res))
    if not (0 <= row < height and 0 <= col < width):
        return False
    if not distance[row, col] > const[5] + reach + const[14]:
        return False
    vx, vy, w = state[3], state[4], state[5]
    max_dsteer = const[0] * h
    accel = const[1] * h
    decel = const[2] * h
    inv_wheelbase = 1.0 / const[3]
    half_h = 0.5 * h
    omega = state[8]
    x0, y0, a0 = x, y, a
    for _ in range(n_sub):
        steer += min(max(target_steer - steer, -max_dsteer), max_dsteer)
        if speed > 0.0 and target_speed < speed:  # braking forwards: stop before reversing
            speed = max(speed - decel, target_speed, 0.0)
        elif speed < 0.0 and target_speed > speed:  # braking backwards
            speed = min(speed + decel, target_speed, 0.0)
        else:
            speed += min(max(target_speed - speed, -accel), accel)
        omega = speed * math.tan(steer) * inv_wheelbase
        # pymunk's position update (zero bias velocity without contacts), then _set_velocity.
        x = x + (vx + 0.0) * h
        y = y + (vy + 0.0) * h
        a = a + (w + 0.0) * h
        heading = a + omega * half_h
        vx = speed * math.cos(heading)
        vy = speed * math.sin(heading)
        w = omega
    state[0], state[1], state[2] = x, y, a
    state[3], state[4], state[5] = vx, vy, w
    state[6], state[7], state[8] = steer, speed, omega
    twist[0], twist[1], twist[2] = se2_log_twist(x - x0, y - y0, a0, a - a0, dt)
    return True


def free_constants(car, occupancy_map, margin: float) -> np.ndarray:
    """The constants array (:data:`CONSTANT_FIELDS`) for a :class:`CarParams` and a map."""
    ahead = car.length / 2 - car.rear_overhang
    res = occupancy_map.resolution
    yaw = occupancy_map.yaw
    return np.array(
        [
            car.max_steer_rate, car.max_accel, car.max_decel, car.wheelbase, ahead,
            0.5 * math.hypot(car.length, car.width) + math.sqrt(2.0) * res,
            1.0 + abs(ahead) * math.tan(car.max_steer) / car.wheelbase,
            float(occupancy_map.origin[0]), float(occupancy_map.origin[1]), math.cos(yaw),
            math.sin(yaw), 1.0 / res, occupancy_map.height, occupancy_map.width, margin,
        ]
    )  # fmt: skip
