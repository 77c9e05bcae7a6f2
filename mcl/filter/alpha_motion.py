"""Motion noise that grows with the motion: the odometry motion model of Probabilistic Robotics
(table 5.6, the ``sample_motion_model_odometry`` that ROS amcl's ``diff`` model implements), numba.

The car-frame displacement ``[dx, dy, dtheta]`` of one update (metres, radians) is split into a turn
towards the direction of travel, a straight translation and a second turn::

    trans = hypot(dx, dy),   rot1 = atan2(dy, dx) (0 when trans is below 1e-9 m),
    rot2 = dtheta - rot1,

and each part gets Gaussian noise whose standard deviation grows with the motion::

    sd_rot1  = sqrt(a1 rot1² + a2 trans²)
    sd_trans = sqrt(a3 trans² + a4 (rot1² + rot2²))
    sd_rot2  = sqrt(a1 rot2² + a2 trans²)

(as amcl, a move backwards gets the noise of the same move forwards: the rotations in these sums
are taken modulo pi to the nearer of 0 and pi). The noisy displacement is
``[t cos r1, t sin r1, r1 + r2]`` from the noisy parts, plus a constant Gaussian floor per update
(``floor``, metres, metres, radians) so that a car at rest keeps some spread. Per update at a fixed
rate, ``trans`` is speed x dt and the rotations are turn rate x dt: the noise grows with speed and
turn rate, which is where a sliding car's odometry is wrong ([`racecar_sim.sensors.vesc`][racecar_sim.sensors.vesc]).

Draws: six standard normals per particle from one `racecar_sim.raycast.rand` stream, in the order
particle 0 (rot1, trans, rot2, floor dx, floor dy, floor dtheta), particle 1, ...
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from mcl.filter.step_kernels import wrap
from racecar_sim.raycast.rand import normal

__all__ = ["alpha_odometry_into", "alpha_sd"]

_MIN_TRANS = 1e-9  # metres: below this the direction of travel is undefined (rot1 = 0)


@nb.njit(cache=True, inline="always")
def _rot_size(a):
    """|a| taken to the nearer of 0 and pi (a backwards move's rotations as a forward one's)."""
    w = abs(wrap(a))
    return min(w, math.pi - w)


@nb.njit(cache=True)
def alpha_sd(odometry, alphas):
    """(rot1, trans, rot2, sd_rot1, sd_trans, sd_rot2) of a car-frame displacement (3,) for the
    noise coefficients ``alphas`` (4,) = a1..a4 (see the module docstring)."""
    dx, dy, dth = odometry[0], odometry[1], odometry[2]
    trans = math.sqrt(dx * dx + dy * dy)
    rot1 = math.atan2(dy, dx) if trans >= _MIN_TRANS else 0.0
    rot2 = dth - rot1
    r1 = _rot_size(rot1)
    r2 = _rot_size(rot2)
    a1, a2, a3, a4 = alphas[0], alphas[1], alphas[2], alphas[3]
    sd_rot1 = math.sqrt(a1 * r1 * r1 + a2 * trans * trans)
    sd_trans = math.sqrt(a3 * trans * trans + a4 * (r1 * r1 + r2 * r2))
    sd_rot2 = math.sqrt(a1 * r2 * r2 + a2 * trans * trans)
    return rot1, trans, rot2, sd_rot1, sd_trans, sd_rot2


@nb.njit(cache=True)
def alpha_odometry_into(odometry, alphas, floor, seed, out):
    """``out`` (N, 3): one noisy car-frame displacement per particle for ``odometry`` (3,), the
    coefficients ``alphas`` (4,) and the constant ``floor`` (3,) standard deviations, from the
    `racecar_sim.raycast.rand` stream ``seed`` (draw order in the module docstring)."""
    rot1, trans, rot2, sd_rot1, sd_trans, sd_rot2 = alpha_sd(odometry, alphas)
    f0, f1, f2 = floor[0], floor[1], floor[2]
    state = np.uint64(seed)
    for i in range(out.shape[0]):
        state, z0 = normal(state)
        state, z1 = normal(state)
        state, z2 = normal(state)
        state, z3 = normal(state)
        state, z4 = normal(state)
        state, z5 = normal(state)
        r1 = rot1 + sd_rot1 * z0
        t = trans + sd_trans * z1
        r2 = rot2 + sd_rot2 * z2
        out[i, 0] = t * math.cos(r1) + f0 * z3
        out[i, 1] = t * math.sin(r1) + f1 * z4
        out[i, 2] = r1 + r2 + f2 * z5
