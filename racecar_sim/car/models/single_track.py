"""The single-track (bicycle) model with tire slip and a tire that saturates at the friction limit.

States (besides the pose): steering angle ``steer`` (rad), the car-frame velocity of the centre of
gravity, forward ``u`` (which is also the rear wheels' rolling speed, what the speed command
controls) and left ``vy`` (m/s), and the yaw rate ``r`` (rad/s); the body slip angle is
``atan2(vy, u)``. The forces are those of the CommonRoad single-track model (Althoff et al.,
*CommonRoad: Vehicle Models*, section 7, as used by f1tenth_gym) with the slip angles and force
directions kept exact instead of linearised, and the linear tire replaced by a brush (Fiala) tire
whose force saturates at the friction it has left::

    u'  = (Fxf cos(steer) - Fyf sin(steer) + Fxr) / m + vy r
    vy' = (Fxf sin(steer) + Fyf cos(steer) + Fyr) / m - u r
    r'  = (lf (Fxf sin(steer) + Fyf cos(steer)) - lr Fyr) / I
    Fzf = m (g lr - a h) / L        Fzr = m (g lf + a h) / L        (longitudinal load transfer)
    Fxf = a Fzf / g                 Fxr = a Fzr / g                 (drive and brakes: m a in all)
    tan(alpha) = -(lateral / |longitudinal|) velocity of the axle in its wheel's frame
    Fy = Fiala(tan(alpha), C = mu C_S Fz, D = Fz sqrt(mu^2 - (a / g)^2))

``Fiala(z, C, D) = C z - C^2 |z| z / (3 D) + C^3 z^3 / (27 D^2)`` up to ``|z| = 3 D / C`` and
``D sign(z)`` beyond. Its slope at zero is CommonRoad's linear tire (``mu C_S Fz`` per radian), so
the two agree while the tires are far from the limit. ``D`` is the friction circle of combined
slip: the drive's (or brakes') force ``m a`` acts along the wheels, shared between the axles in
proportion to their load (four-wheel drive and brakes), so each axle's lateral force is left
``Fz sqrt(mu^2 - (a/g)^2)`` and no axle's force exceeds ``mu Fz`` when the car accelerates or
brakes in a turn. A wheel rolling backwards or not at all is sliding: its force opposes its lateral
velocity, so a spinning or reversing car stays well defined.

The speed servo: the command [steer, speed] goes through the steering-rate and acceleration
limits of `racecar_sim.car.models.kinematic.actuate()`, as the kinematic car's, acting on the
wheel speed ``u`` (as a VESC's speed control does); its step over a substep becomes ``a``, plus
what makes up for the tires and the turn (their part of ``u'``) within the limits. ``a`` is
limited by the friction (``mu g``) and, above ``v_switch``, by the motor's power
(``max_accel v_switch / u``, as CommonRoad).

Low speed: the slip angles divide by the wheels' speeds and the lateral dynamics get stiff. Below
``kinematic_below`` (speed of the centre of gravity) the car is the kinematic bicycle (the rear axle
does not slide: ``r = u tan(steer) / L``, ``vy = lr r``); up to ``dynamic_above`` the rates are
blended, with a smoothstep weight of the speed, from the dynamic ones to the kinematic states' own
rates plus a pull towards them (time constant `KINEMATIC_PULL`), as CommonRoad's drift model
blends its dynamic and kinematic rates (f1tenth_gym switches at 0.5 m/s without blending).

Integration: each substep of ``h`` seconds the actuators move first; then ``(u, vy, r)`` are
integrated over it by the classical Runge-Kutta method (RK4), the steering angle moving linearly
from its old to its new value, in as many equal pieces as the stiffness of the lateral dynamics
needs for RK4 to be stable (one at speed). The rear axle moves by the mean of its start and end
car-frame velocities along the chord of the arc of the mean yaw rate. See ``docs/dynamics.md`` for
the step-size error.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.car.models.kinematic import actuate

__all__ = ["GRAVITY", "KINEMATIC_PULL", "PARAM_FIELDS", "params_array", "settle", "substep"]

GRAVITY = 9.81
"""m/s², as CommonRoad and f1tenth_gym."""

PARAM_FIELDS = ("wheelbase", "lf", "lr", "cg_height", "mass_over_inertia", "friction",
                "cornering_front", "cornering_rear", "v_switch", "kinematic_below",
                "dynamic_above", "max_steer_rate", "max_accel", "max_decel")  # fmt: skip
"""Layout of the float64 parameter array (m, m, m, m, kg / (kg m²), -, 1/rad, 1/rad, m/s, m/s,
m/s, rad/s, m/s², m/s²)."""

# State indices, as racecar_sim.car.free_steps.STATE_FIELDS.
_STEER, _SPEED, _OMEGA, _LATERAL, _YAW_RATE, _UX, _UY = 6, 7, 8, 9, 10, 11, 12
KINEMATIC_PULL = 0.02
"""Seconds: how fast the states are pulled to the kinematic bicycle's where it takes over."""
_TINY_FRICTION = 1e-6  # friction left to a tire when the car brakes at the friction limit


def params_array(car) -> np.ndarray:
    """The parameter array (`PARAM_FIELDS`) of a [`CarParams`][racecar_sim.settings.config.CarParams]."""
    lr = car.cg_to_rear
    return np.array(
        [
            car.wheelbase, car.wheelbase - lr, lr, car.cg_height, car.mass / car.yaw_inertia,
            car.friction, car.cornering_front, car.cornering_rear, car.v_switch,
            car.kinematic_below, car.dynamic_above, car.max_steer_rate, car.max_accel,
            car.max_decel,
        ]
    )  # fmt: skip


@nb.njit(cache=True)
def fiala(z, c, d):
    """Brush (Fiala) tire force per unit load at slip ``z = tan(alpha)``.

    ``c``: cornering stiffness per unit load (1/rad), ``d``: friction coefficient left (peak force
    per unit load). Linear ``c z`` at small slip, ``d sign(z)`` beyond ``|z| = 3 d / c``.
    """
    q = c * z
    if abs(q) >= 3.0 * d:
        return d if q > 0.0 else -d
    return q - q * abs(q) / (3.0 * d) + q * q * q / (27.0 * d * d)


@nb.njit(cache=True)
def rates(u, vy, r, a, cos_d, sin_d, p):
    """(u', vy', r') of the single-track model (module docstring): car-frame velocity of the centre
    of gravity ``u`` (forward), ``vy`` (left), m/s, yaw rate ``r`` (rad/s), drive acceleration
    ``a`` (m/s²) and the steering angle's cos and sin."""
    lf, lr, hcg, mu = p[1], p[2], p[3], p[5]
    vyf, vyr = vy + lf * r, vy - lr * r  # lateral velocity of the axles, car frame
    # tan(slip angle) = -(lateral / longitudinal velocity) in each wheel's frame; a wheel that
    # rolls backwards slides the same way, one that does not roll at all is saturated.
    along_f = u * cos_d + vyf * sin_d
    across_f = vyf * cos_d - u * sin_d
    zf = -across_f / max(abs(along_f), 1e-9)
    zr = -vyr / max(abs(u), 1e-9)
    ag = a / GRAVITY
    left = math.sqrt(max(mu * mu - ag * ag, _TINY_FRICTION))
    inv_l = 1.0 / p[0]
    zf_load = (GRAVITY * lr - a * hcg) * inv_l  # Fzf / m, m/s²
    zr_load = (GRAVITY * lf + a * hcg) * inv_l
    fyf = zf_load * fiala(zf, mu * p[6], left)  # lateral forces / m, m/s², in the wheels' frames
    fyr = zr_load * fiala(zr, mu * p[7], left)
    xf, xr = zf_load * ag, zr_load * ag  # longitudinal forces / m (the drive shared by load)
    du = xf * cos_d - fyf * sin_d + xr + vy * r
    dvy = xf * sin_d + fyf * cos_d + fyr - u * r
    dr = p[4] * (lf * (xf * sin_d + fyf * cos_d) - lr * fyr)
    return du, dvy, dr


@nb.njit(cache=True)
def blend_weight(speed, p):
    """Weight of the dynamic rates at ``speed`` (of the centre of gravity, m/s): 0 below
    ``kinematic_below``, 1 above ``dynamic_above``, a smoothstep between."""
    lo, hi = p[9], p[10]
    if speed <= lo:
        return 0.0
    if speed >= hi:
        return 1.0
    s = (speed - lo) / (hi - lo)
    return s * s * (3.0 - 2.0 * s)


@nb.njit(cache=True)
def blended_rates(u, vy, r, a, cos_d, sin_d, tan_d, dsteer, p):
    """(u', vy', r'): the dynamic rates weighted by `blend_weight()`, the rest the kinematic
    bicycle's (its states' rates at steering rate ``dsteer`` rad/s, plus a pull towards them with
    time constant `KINEMATIC_PULL`)."""
    w = blend_weight(math.sqrt(u * u + vy * vy), p)
    du, dvy, dr = a, 0.0, 0.0
    if w > 0.0:
        du, dvy, dr = rates(u, vy, r, a, cos_d, sin_d, p)
        if w == 1.0:
            return du, dvy, dr
    inv_l = 1.0 / p[0]
    lr = p[2]
    r_k = u * tan_d * inv_l  # the kinematic bicycle: the rear axle does not slide
    dr_k = (a * tan_d + u * dsteer / (cos_d * cos_d)) * inv_l
    k = 1.0 - w
    inv_tau = 1.0 / KINEMATIC_PULL
    return (w * du + k * a, w * dvy + k * (lr * dr_k + (lr * r_k - vy) * inv_tau),
            w * dr + k * (dr_k + (r_k - r) * inv_tau))  # fmt: skip


@nb.njit(cache=True)
def _stiffness(u, p):
    """A bound on the fastest rate (1/s) of the lateral dynamics at forward speed ``u``."""
    lf, lr = p[1], p[2]
    axle = p[5] * GRAVITY * (p[6] * lr + p[7] * lf) / p[0]  # m/s² per rad, both axles
    return axle * (1.0 + p[4] * max(lf, lr) ** 2) / max(abs(u), 0.05)


@nb.njit(cache=True)
def substep(state, target_steer, target_speed, p, h):
    """Advance the model states of ``state`` (racecar_sim.car.free_steps layout) by ``h`` seconds.

    Writes the new steer, speed (the rear wheels' rolling speed = the car-frame forward velocity),
    lateral velocity of the centre of gravity, yaw rate, and the rear axle's car-frame velocity
    for the substep (``ux``, ``uy``, m/s, along the chord) and turn rate (``omega``, rad/s).
    """
    steer0, u0 = state[_STEER], state[_SPEED]
    vy0, r0 = state[_LATERAL], state[_YAW_RATE]
    mu_g = p[5] * GRAVITY
    accel = min(p[12], mu_g)
    if u0 > p[8]:
        accel = min(accel, p[12] * p[8] / u0)  # the motor's power limit above v_switch
    decel = min(p[13], mu_g)
    steer1, u_servo = actuate(steer0, u0, target_steer, target_speed, p[11] * h, accel * h,
                              decel * h)  # fmt: skip
    dsteer = (steer1 - steer0) / h
    c0, s0, t0 = math.cos(steer0), math.sin(steer0), math.tan(steer0)
    c1, s1, t1 = math.cos(steer1), math.sin(steer1), math.tan(steer1)
    # The drive's (or brakes') acceleration: the servo's step of the wheel speed, making up for
    # what the tires and the turn do to it now, within the limits.
    a = (u_servo - u0) / h
    if blend_weight(math.sqrt(u0 * u0 + vy0 * vy0), p) > 0.0:
        other = blended_rates(u0, vy0, r0, a, c0, s0, t0, dsteer, p)[0] - a
        a = min(max(a - other, -decel), accel)
    # RK4 in as many equal pieces as the lateral dynamics' stiffness needs (one at speed).
    n = min(16, max(1, math.ceil(h * _stiffness(min(abs(u0), abs(u_servo)), p) / 2.0)))
    k = h / n
    u, vy, r = u0, vy0, r0
    for i in range(n):
        da = steer0 + (steer1 - steer0) * i / n
        dm = da + 0.5 * (steer1 - steer0) / n
        db = steer0 + (steer1 - steer0) * (i + 1) / n
        if n == 1:
            ca, sa, ta, cb, sb, tb = c0, s0, t0, c1, s1, t1
        else:
            ca, sa, ta = math.cos(da), math.sin(da), math.tan(da)
            cb, sb, tb = math.cos(db), math.sin(db), math.tan(db)
        cm, sm, tm = math.cos(dm), math.sin(dm), math.tan(dm)
        hk = 0.5 * k
        k1u, k1y, k1r = blended_rates(u, vy, r, a, ca, sa, ta, dsteer, p)
        k2u, k2y, k2r = blended_rates(u + hk * k1u, vy + hk * k1y, r + hk * k1r, a, cm, sm, tm,
                                      dsteer, p)  # fmt: skip
        k3u, k3y, k3r = blended_rates(u + hk * k2u, vy + hk * k2y, r + hk * k2r, a, cm, sm, tm,
                                      dsteer, p)  # fmt: skip
        k4u, k4y, k4r = blended_rates(u + k * k3u, vy + k * k3y, r + k * k3r, a, cb, sb, tb,
                                      dsteer, p)  # fmt: skip
        u += k / 6.0 * (k1u + 2.0 * k2u + 2.0 * k3u + k4u)
        vy += k / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y)
        r += k / 6.0 * (k1r + 2.0 * k2r + 2.0 * k3r + k4r)
    lr = p[2]
    ux = 0.5 * (u0 + u)
    uy = 0.5 * (vy0 - lr * r0 + vy - lr * r)
    omega = 0.5 * (r0 + r)
    x = 0.5 * omega * h
    chord = 1.0 - x * x / 6.0 if abs(x) < 1e-4 else math.sin(x) / x
    state[_STEER], state[_SPEED], state[_OMEGA] = steer1, u, omega
    state[_LATERAL], state[_YAW_RATE] = vy, r
    state[_UX], state[_UY] = ux * chord, uy * chord


@nb.njit(cache=True)
def settle(state, p):
    """Set the lateral velocity, yaw rate and the rear axle's velocity of ``state`` to the
    kinematic bicycle's at its steer and speed (a car placed by a reset)."""
    tan_d = math.tan(state[_STEER])
    u = state[_SPEED]
    r = u * tan_d / p[0]
    state[_LATERAL], state[_YAW_RATE], state[_OMEGA] = p[2] * r, r, r
    state[_UX], state[_UY] = u, 0.0
