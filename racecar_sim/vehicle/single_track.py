"""The single-track (bicycle) model with tire slip and a tire that saturates at the friction limit.

States (besides the pose): steering angle ``steer`` (rad), speed of the centre of gravity ``v``
(m/s, along the velocity), body slip angle ``beta`` (rad, between heading and velocity, positive
left) and yaw rate ``r`` (rad/s). The equations are those of the CommonRoad single-track model
(Althoff et al., *CommonRoad: Vehicle Models*, section 7, as used by f1tenth_gym) with the slip
angles and force directions kept exact instead of linearised, and the linear tire replaced by a
brush (Fiala) tire whose force saturates at the friction it has left::

    v'    = (Fxf cos(steer - beta) - Fyf sin(steer - beta) + Fxr cos(beta) + Fyr sin(beta)) / m
    beta' = (Fxf sin(steer - beta) + Fyf cos(steer - beta) - Fxr sin(beta) + Fyr cos(beta)) / (m v)
            - r
    r'    = (lf (Fxf sin(steer) + Fyf cos(steer)) - lr Fyr) / I
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
velocity, so a spinning car stays well defined (its slip angle is kept in [-pi, pi)).

The speed servo: the command [steer, speed] goes through the steering-rate and acceleration
limits of :func:`racecar_sim.vehicle.kinematic.actuate`, as the kinematic car's; its speed step
over a substep becomes ``a``, plus what makes up for the tires' drag (the lateral forces' part
along the velocity) within the limits. ``a`` is limited by the friction (``mu g``) and, above
``v_switch``, by the motor's power (``max_accel v_switch / v``, as CommonRoad). ``v`` is the speed
of the centre of gravity; the rear wheels roll at ``v cos(beta)``.

Low speed: the equations divide by ``v``. Below ``kinematic_below`` the car is the kinematic
bicycle (``beta = atan(lr tan(steer) / L)``, ``r = v cos(beta) tan(steer) / L``); up to
``dynamic_above`` the rates are blended, with a smoothstep weight of the speed, from the dynamic
ones to the kinematic states' own rates plus a pull towards them (time constant
:data:`KINEMATIC_PULL`), as CommonRoad's drift model blends its dynamic and kinematic rates
(f1tenth_gym switches at 0.5 m/s without blending). Reversing (at most ``max_reverse_speed``) is
kinematic.

Integration: each substep of ``h`` seconds the actuators move first; then ``(v, beta, r)`` are
integrated over it by the classical Runge-Kutta method (RK4), the steering angle moving linearly
from its old to its new value. The rear axle moves by the mean of its start and end car-frame
velocities along the chord of the arc of the mean yaw rate. See ``docs/dynamics.md`` for the
step-size error.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.vehicle.kinematic import actuate

__all__ = ["GRAVITY", "PARAM_FIELDS", "params_array", "substep"]

GRAVITY = 9.81
"""m/s², as CommonRoad and f1tenth_gym."""

PARAM_FIELDS = ("wheelbase", "lf", "lr", "cg_height", "mass_over_inertia", "friction",
                "cornering_front", "cornering_rear", "v_switch", "kinematic_below",
                "dynamic_above", "max_steer_rate", "max_accel", "max_decel")  # fmt: skip
"""Layout of the float64 parameter array (m, m, m, m, kg / (kg m²), -, 1/rad, 1/rad, m/s, m/s,
m/s, rad/s, m/s², m/s²)."""

# State indices, as racecar_sim.free_steps.STATE_FIELDS.
_STEER, _SPEED, _OMEGA, _BETA, _YAW_RATE, _UX, _UY = 6, 7, 8, 9, 10, 11, 12
KINEMATIC_PULL = 0.02
"""Seconds: how fast the states are pulled to the kinematic bicycle's where it takes over."""
_TINY_FRICTION = 1e-6  # friction left to a tire when the car brakes at the friction limit


def params_array(car) -> np.ndarray:
    """The parameter array (:data:`PARAM_FIELDS`) of a :class:`~racecar_sim.config.CarParams`."""
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
def rates(v, beta, r, a, cos_d, sin_d, p):
    """(v', beta', r') of the single-track model (module docstring) at speed ``v`` > 0 (m/s),
    body slip ``beta`` (rad), yaw rate ``r`` (rad/s), drive acceleration ``a`` (m/s²) and the
    steering angle's cos and sin."""
    lf, lr, hcg, mu = p[1], p[2], p[3], p[5]
    cb, sb = math.cos(beta), math.sin(beta)
    vx, vy = v * cb, v * sb
    vyf, vyr = vy + lf * r, vy - lr * r  # lateral velocity of the axles, car frame
    # tan(slip angle) = -(lateral / longitudinal velocity) in each wheel's frame; a wheel that
    # rolls backwards or not at all slides (saturated), its force against its lateral velocity.
    along_f = vx * cos_d + vyf * sin_d
    across_f = vyf * cos_d - vx * sin_d
    zf = -across_f / max(abs(along_f), 1e-9)
    zr = -vyr / max(abs(vx), 1e-9)
    ag = a / GRAVITY
    left = math.sqrt(max(mu * mu - ag * ag, _TINY_FRICTION))
    inv_l = 1.0 / p[0]
    zf_load = (GRAVITY * lr - a * hcg) * inv_l  # Fzf / m, m/s²
    zr_load = (GRAVITY * lf + a * hcg) * inv_l
    fyf = zf_load * fiala(zf, mu * p[6], left)  # lateral forces / m, m/s², in the wheels' frames
    fyr = zr_load * fiala(zr, mu * p[7], left)
    xf, xr = zf_load * ag, zr_load * ag  # longitudinal forces / m (the drive shared by load)
    # cos / sin of (steer - beta): the front wheel's heading seen from the velocity
    c_fb, s_fb = cos_d * cb + sin_d * sb, sin_d * cb - cos_d * sb
    dv = xf * c_fb - fyf * s_fb + xr * cb + fyr * sb
    dbeta = (xf * s_fb + fyf * c_fb - xr * sb + fyr * cb) / v - r
    dr = p[4] * (lf * (xf * sin_d + fyf * cos_d) - lr * fyr)
    return dv, dbeta, dr


@nb.njit(cache=True)
def blend_weight(v, p):
    """Weight of the dynamic states at speed ``v``: 0 below ``kinematic_below``, 1 above
    ``dynamic_above``, a smoothstep between."""
    lo, hi = p[9], p[10]
    if v <= lo:
        return 0.0
    if v >= hi:
        return 1.0
    s = (v - lo) / (hi - lo)
    return s * s * (3.0 - 2.0 * s)


@nb.njit(cache=True)
def blended_rates(v, beta, r, a, cos_d, sin_d, tan_d, dsteer, p):
    """(v', beta', r'): the dynamic rates weighted by :func:`blend_weight` at ``v``, the rest the
    kinematic bicycle's (its states' rates at steering rate ``dsteer`` rad/s, plus a pull towards
    them with time constant :data:`KINEMATIC_PULL`)."""
    w = blend_weight(v, p)
    dv, dbeta, dr = a, 0.0, 0.0
    if w > 0.0:
        dv, dbeta, dr = rates(v, beta, r, a, cos_d, sin_d, p)
        if w == 1.0:
            return dv, dbeta, dr
    q = p[2] / p[0]  # lr / L
    qt = q * tan_d
    beta_k = math.atan(qt)
    sec2 = 1.0 / (cos_d * cos_d)
    dbeta_k = q * sec2 * dsteer / (1.0 + qt * qt)
    cb = math.cos(beta_k)
    r_k = v * cb * tan_d / p[0]
    dr_k = (a * cb * tan_d - v * math.sin(beta_k) * dbeta_k * tan_d + v * cb * sec2 * dsteer) / p[0]
    u = 1.0 - w
    inv_tau = 1.0 / KINEMATIC_PULL
    return (w * dv + u * a, w * dbeta + u * (dbeta_k + (beta_k - beta) * inv_tau),
            w * dr + u * (dr_k + (r_k - r) * inv_tau))  # fmt: skip


@nb.njit(cache=True)
def substep(state, target_steer, target_speed, p, h):
    """Advance the model states of ``state`` (racecar_sim.free_steps layout) by ``h`` seconds.

    Writes the new steer, speed, beta, yaw rate, and the rear axle's car-frame velocity for the
    substep (``ux``, ``uy``, m/s, chord-corrected) and turn rate (``omega``, rad/s).
    """
    steer0, v0 = state[_STEER], state[_SPEED]
    beta0, r0 = state[_BETA], state[_YAW_RATE]
    mu_g = p[5] * GRAVITY
    accel = min(p[12], mu_g)
    if v0 > p[8]:
        accel = min(accel, p[12] * p[8] / v0)  # the motor's power limit above v_switch
    decel = min(p[13], mu_g)
    steer1, v_servo = actuate(steer0, v0, target_steer, target_speed, p[11] * h, accel * h,
                              decel * h)  # fmt: skip
    dsteer = (steer1 - steer0) / h
    steerm = 0.5 * (steer0 + steer1)
    c0, s0, t0 = math.cos(steer0), math.sin(steer0), math.tan(steer0)
    cm, sm, tm = math.cos(steerm), math.sin(steerm), math.tan(steerm)
    c1, s1, t1 = math.cos(steer1), math.sin(steer1), math.tan(steer1)
    # The drive's (or brakes') acceleration: the servo's step, making up for the tires' drag as it
    # is now, within its limits.
    a = (v_servo - v0) / h
    w0 = blend_weight(v0, p)
    if w0 > 0.0:
        drag = rates(v0, beta0, r0, a, c0, s0, p)[0] - a
        a = min(max(a - w0 * drag, -decel), accel)
    hh = 0.5 * h
    k1v, k1b, k1r = blended_rates(v0, beta0, r0, a, c0, s0, t0, dsteer, p)
    k2v, k2b, k2r = blended_rates(v0 + hh * k1v, beta0 + hh * k1b, r0 + hh * k1r, a, cm, sm, tm,
                                  dsteer, p)  # fmt: skip
    k3v, k3b, k3r = blended_rates(v0 + hh * k2v, beta0 + hh * k2b, r0 + hh * k2r, a, cm, sm, tm,
                                  dsteer, p)  # fmt: skip
    k4v, k4b, k4r = blended_rates(v0 + h * k3v, beta0 + h * k3b, r0 + h * k3r, a, c1, s1, t1,
                                  dsteer, p)  # fmt: skip
    v1 = v0 + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    beta1 = beta0 + h / 6.0 * (k1b + 2.0 * k2b + 2.0 * k3b + k4b)
    r1 = r0 + h / 6.0 * (k1r + 2.0 * k2r + 2.0 * k3r + k4r)
    if not -math.pi <= beta1 < math.pi:  # a spin: keep the slip angle in [-pi, pi)
        beta1 = (beta1 + math.pi) % (2.0 * math.pi) - math.pi
    lr = p[2]
    ux = 0.5 * (v0 * math.cos(beta0) + v1 * math.cos(beta1))
    uy = 0.5 * (v0 * math.sin(beta0) - lr * r0 + v1 * math.sin(beta1) - lr * r1)
    omega = 0.5 * (r0 + r1)
    x = 0.5 * omega * h
    chord = 1.0 - x * x / 6.0 if abs(x) < 1e-4 else math.sin(x) / x
    state[_STEER], state[_SPEED], state[_OMEGA] = steer1, v1, omega
    state[_BETA], state[_YAW_RATE] = beta1, r1
    state[_UX], state[_UY] = ux * chord, uy * chord


@nb.njit(cache=True)
def settle(state, p):
    """Set beta, yaw rate and the rear axle's velocity of ``state`` to the kinematic bicycle's at
    its steer and speed (a car placed by a reset)."""
    tan_d = math.tan(state[_STEER])
    inv_l = 1.0 / p[0]
    beta = math.atan(p[2] * tan_d * inv_l)
    v = state[_SPEED]
    r = v * math.cos(beta) * tan_d * inv_l
    state[_BETA], state[_YAW_RATE], state[_OMEGA] = beta, r, r
    state[_UX], state[_UY] = v * math.cos(beta), 0.0
