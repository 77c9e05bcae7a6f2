"""numba kernel of the physics' free steps (see [`racecar_sim.car.physics`][racecar_sim.car.physics], "Free steps").

Far from every wall a pymunk substep only moves the car's body by the velocity set at the previous
substep and then calls the velocity function. `free_step()` performs the same floating-point
operations in the same order (``p + (v + 0) * h``, ``a + (w + 0) * h``, then the bicycle velocity
at the mid-substep heading), so the result is bit for bit pymunk's; it first checks on the map's
distance field that no wall is within reach during the step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.car.models import MODEL_INDEX, model_params
from racecar_sim.car.models.kinematic import actuate
from racecar_sim.car.models.single_track import substep as single_track_substep

__all__ = ["CONSTANT_FIELDS", "STATE_FIELDS", "advance", "body_velocity", "free_step", "se2_log_twist"]

STATE_FIELDS = ("x", "y", "angle", "vx", "vy", "w", "steer", "speed", "omega", "lateral",
                "yaw_rate", "ux", "uy")  # fmt: skip
"""Layout of the float64 state array: rear-axle world pose (m, rad, angle unwrapped as pymunk's),
body velocity (m/s, rad/s), wheel angle (rad), speed (m/s: the rear wheels' rolling speed, the
car-frame forward velocity), turn rate of the substep (rad/s); the single-track car's car-frame
lateral velocity of its centre of gravity (m/s), yaw rate (rad/s) and the rear axle's car-frame
velocity for the substep (m/s)."""

CONSTANT_FIELDS = ("max_steer_rate", "max_accel", "max_decel", "wheelbase", "ahead", "reach",
                   "centre_speed", "origin_x", "origin_y", "cos_yaw", "sin_yaw", "inv_res",
                   "height", "width", "margin", "model")  # fmt: skip
"""Layout of the float64 constants array: car limits (rad/s, m/s², m/s², m); rear axle to the
footprint's centre (m); the footprint's half diagonal plus one cell diagonal (m); the bound on the
centre's speed per unit wheel speed; the map's origin, yaw, 1 / resolution and size (cells); the
margin kept from the walls (m); the car model's index ([`racecar_sim.car.models.MODEL_INDEX`][racecar_sim.car.models.MODEL_INDEX]),
followed by its parameters ([`racecar_sim.car.models.model_params()`][racecar_sim.car.models.model_params])."""

_MODEL = len(CONSTANT_FIELDS) - 1  # index of the model; its parameters follow


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
        const: float64 laid out as `CONSTANT_FIELDS`.
        state: float64 laid out as `STATE_FIELDS`, updated in place.
        target_steer, target_speed: the command, already clipped to the car's limits.
        twist: (3,) output, the step's car-frame twist (SE(2) logarithm over ``dt``).

    Returns:
        False (nothing changed) when a wall could be reached within the step.
    """
    x, y, a = state[0], state[1], state[2]
    speed = state[7]
    reach = dt * max(abs(speed), abs(target_speed)) * const[6]
    if const[_MODEL] != 0.0:  # the single-track car also turns about its centre and may slide
        p = const[_MODEL + 1 :]
        growth = p[4] * max(p[1], p[2]) * p[5] * 9.81 * dt  # the most its yaw rate may change
        reach += dt * (abs(state[9]) + (p[2] + abs(const[4])) * (abs(state[10]) + growth))
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
    advance(const, state, target_steer, target_speed, n_sub, h, dt, twist)
    return True


@nb.njit(cache=True)
def advance(const, state, target_steer, target_speed, n_sub, h, dt, twist) -> None:
    """`free_step()`'s motion without its wall check: ``n_sub`` substeps of ``h`` seconds of
    the car model ``const`` names, in free space (the same doubles as pymunk far from walls)."""
    if const[_MODEL] != 0.0:
        _free_single_track(const[_MODEL + 1 :], state, target_steer, target_speed, n_sub, h, dt,
                           twist)  # fmt: skip
        return
    x, y, a = state[0], state[1], state[2]
    steer, speed = state[6], state[7]
    vx, vy, w = state[3], state[4], state[5]
    max_dsteer = const[0] * h
    accel = const[1] * h
    decel = const[2] * h
    inv_wheelbase = 1.0 / const[3]
    half_h = 0.5 * h
    omega = state[8]
    x0, y0, a0 = x, y, a
    for _ in range(n_sub):
        steer, speed = actuate(steer, speed, target_steer, target_speed, max_dsteer, accel, decel)
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


@nb.njit(cache=True)
def _free_single_track(p, state, target_steer, target_speed, n_sub, h, dt, twist) -> None:
    """`free_step()`'s substeps for the single-track car (no wall within reach)."""
    x, y, a = state[0], state[1], state[2]
    vx, vy, w = state[3], state[4], state[5]
    half_h = 0.5 * h
    x0, y0, a0 = x, y, a
    for _ in range(n_sub):
        # The substep's velocity, set before pymunk's position update (racecar_sim.car.physics: no
        # contact, so the solver left the last velocity alone), then that update.
        single_track_substep(state, target_steer, target_speed, p, h)
        w = state[8]
        vx, vy = body_velocity(a, w, half_h, state[11], state[12])
        x = x + (vx + 0.0) * h
        y = y + (vy + 0.0) * h
        a = a + (w + 0.0) * h
    state[0], state[1], state[2] = x, y, a
    state[3], state[4], state[5] = vx, vy, w
    twist[0], twist[1], twist[2] = se2_log_twist(x - x0, y - y0, a0, a - a0, dt)


@nb.njit(cache=True)
def body_velocity(angle, omega, half_h, ux, uy):
    """World velocity (m/s) of the rear axle for a substep: car-frame (ux, uy) turned to the
    heading at mid-substep, ``angle + omega * half_h`` (the single-track car's velocity function)."""
    heading = angle + omega * half_h
    c, s = math.cos(heading), math.sin(heading)
    return ux * c - uy * s, ux * s + uy * c


def free_constants(car, occupancy_map, margin: float, car_model: str = "kinematic") -> np.ndarray:
    """The constants array (`CONSTANT_FIELDS`) for a `CarParams`, a map (None: no
    map, for `advance()` only) and a car model name."""
    ahead = car.length / 2 - car.rear_overhang
    if occupancy_map is None:  # advance never reads the map's fields
        from racecar_sim.maps import OccupancyMap

        occupancy_map = OccupancyMap(occupied=np.zeros((1, 1), dtype=bool), resolution=1.0)
    res = occupancy_map.resolution
    yaw = occupancy_map.yaw
    return np.array(
        [
            car.max_steer_rate, car.max_accel, car.max_decel, car.wheelbase, ahead,
            0.5 * math.hypot(car.length, car.width) + math.sqrt(2.0) * res,
            1.0 + abs(ahead) * math.tan(car.max_steer) / car.wheelbase,
            float(occupancy_map.origin[0]), float(occupancy_map.origin[1]), math.cos(yaw),
            math.sin(yaw), 1.0 / res, occupancy_map.height, occupancy_map.width, margin,
            MODEL_INDEX[car_model], *model_params(car, car_model),
        ]
    )  # fmt: skip
