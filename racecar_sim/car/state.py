"""The car's state, wherever it is kept: in pymunk's body, or in the free steps' array while the car
drives far from every wall ([`racecar_sim.car.free_steps`][racecar_sim.car.free_steps]); its read-outs
(pose, twist, wheel speed, slip angle, footprint) and the hand-over between the two.

[`CarState`][racecar_sim.car.state.CarState] is the base of
[`RacecarPhysics`][racecar_sim.car.physics.RacecarPhysics], which sets its fields and steps it.
Frames: ``world`` (the map's, metres, radians) and ``car`` (x forward, y left, origin at the rear
axle).
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from racecar_sim.car.free_steps import CONSTANT_FIELDS
from racecar_sim.settings.config import CarParams

__all__ = ["CarState", "wrap_angle"]

_TWO_PI = 2.0 * math.pi


def wrap_angle(angle: float) -> float:
    """Angle in radians wrapped to [-pi, pi)."""
    return (angle + math.pi) % _TWO_PI - math.pi


class CarState:
    """The car's state and its read-outs; the fields are set by the physics that steps it.

    Fields: ``body`` (pymunk), ``car`` (its settings); ``_free`` (float64 free-step state laid out
    as `racecar_sim.car.free_steps.STATE_FIELDS`) and whether it is current (``_free_valid``) and
    pymunk's body lags behind it (``_body_stale``); the wheels' ``_steer`` (radians), ``_speed``
    (m/s), ``_omega`` (rad/s) and ``_half_h`` (seconds); the last step's ``_twist``.
    """

    body: pymunk.Body
    car: CarParams
    free_steps: bool
    _free: np.ndarray
    _free_valid: bool
    _body_stale: bool
    _free_const: np.ndarray
    _local_corners: np.ndarray
    _single_track: bool
    _steer: float
    _speed: float
    _omega: float
    _half_h: float
    _twist: np.ndarray
    _quiet: int
    _quiet_needed: int

    @property
    def pose(self) -> np.ndarray:
        """(3,) world [x, y, theta] of the rear axle; metres, radians wrapped to [-pi, pi)."""
        if self._free_valid:
            f = self._free
            return np.array([f[0], f[1], wrap_angle(float(f[2]))])
        x, y = self.body.position
        return np.array([x, y, wrap_angle(self.body.angle)])

    @property
    def twist(self) -> np.ndarray:
        """(3,) true car-frame [vx, vy, omega] (m/s, m/s, rad/s) of the rear axle.

        Over the last `step()`: the constant car-frame twist that takes the pose before the
        step to the pose after it in ``dt`` (the SE(2) logarithm of the relative pose over
        ``dt``), so integrating it as an arc reproduces the step's motion exactly. Driving freely on
        a constant command it equals ``[speed, 0, speed * tan(steer) / wheelbase]``; against a
        wall it is the motion that actually happened. After `reset()` it is the commanded
        bicycle twist.
        """
        return self._twist.copy()

    @property
    def steer(self) -> float:
        """Current front wheel angle, radians (positive turns left)."""
        return self._steer

    @property
    def speed(self) -> float:
        """Current speed of the rear wheels, m/s (negative when reversing): the car-frame forward
        velocity of the rear axle (for the single-track car also of its centre of gravity).

        It follows the command within the acceleration limits; while a wall blocks the car it is
        cut to the speed the car actually makes along its heading.
        """
        return self._speed

    @property
    def wheel_speed(self) -> float:
        """Rolling speed of the driven (rear) wheels, m/s, forward positive: what a VESC measures.

        Both car models' wheels roll at the car-frame forward velocity of the rear axle, so this
        is `speed`; a sliding single-track car's true speed over the ground is higher.
        """
        return self._speed

    @property
    def slip_angle(self) -> float:
        """Body slip angle at the centre of gravity, radians (velocity left of the heading is
        positive): the single-track car's ``atan2(vy, u)``; the kinematic car's geometric
        ``atan(cg_to_rear * tan(steer) / wheelbase)``."""
        if self._single_track:
            return math.atan2(float(self._free[9]), self._speed)
        return math.atan(self.car.cg_to_rear * math.tan(self._steer) / self.car.wheelbase)

    @property
    def local_corners(self) -> np.ndarray:
        """(4, 2) the car's box in the car frame (x forward, y left, origin at the rear axle),
        metres: rear right, front right, front left, rear left (a copy)."""
        return self._local_corners.copy()

    @property
    def free_constants(self) -> np.ndarray:
        """The free steps' constants, float64 laid out as
        `racecar_sim.car.free_steps.CONSTANT_FIELDS` (read-only: shared with the kernel)."""
        return self._free_const

    @property
    def speed_bound(self) -> float:
        """The bound on the box centre's speed per unit wheel speed (free-step constant
        ``centre_speed``): the centre moves at most this many metres per metre of the wheels."""
        return float(self._free_const[CONSTANT_FIELDS.index("centre_speed")])

    def world_velocity(self) -> tuple[float, float, float]:
        """World [vx, vy, omega] of the rear axle (m/s, m/s, rad/s) as the next substep will move
        it: the free steps' state when that is current, else pymunk's body."""
        if self._free_valid:
            f = self._free
            return float(f[3]), float(f[4]), float(f[5])
        vx, vy = self.body.velocity
        return float(vx), float(vy), float(self.body.angular_velocity)

    def footprint(self, pose: np.ndarray | None = None) -> np.ndarray:
        """(4, 2) world corners of the car's box (rear right, front right, front left, rear left).

        Args:
            pose: rear-axle world pose [x, y, theta]; the car's current pose when None.
        """
        x, y, theta = self.pose if pose is None else np.asarray(pose, dtype=np.float64)
        c, s = math.cos(theta), math.sin(theta)
        rot = np.array([[c, s], [-s, c]])
        return self._local_corners @ rot + np.array([x, y])

    def share_state(self, state: np.ndarray, twist: np.ndarray) -> None:
        """Keep the free-step state (`racecar_sim.car.free_steps.STATE_FIELDS`) and the twist
        in the given float64 arrays from now on (their values copied in): rows of the arrays a
        batch of cars steps in one kernel call (`racecar_sim.car.free_batch.FreeStepBatch`).
        This class only ever updates them in place."""
        state[:] = self._free
        twist[:] = self._twist
        self._free = state
        self._twist = twist

    def may_step_freely(self) -> bool:
        """Whether the next step may be taken without pymunk (free steps on, no contact cached);
        if so, the free-step state is brought up to date for the kernel. Whether a wall is within
        reach the kernel decides (`racecar_sim.car.free_steps.free_step`)."""
        if not (self.free_steps and self._quiet >= self._quiet_needed):
            return False
        if not self._free_valid:
            self._load_free_state()
        return True

    def stepped_freely(self, h: float) -> None:
        """Take over a free step that a kernel made on the shared state (substeps of ``h``
        seconds): the wheels' state from it, pymunk's body behind it."""
        f = self._free
        self._steer, self._speed, self._omega = float(f[6]), float(f[7]), float(f[8])
        self._half_h = 0.5 * h
        self._free_valid = True
        self._body_stale = True

    def _load_free_state(self) -> None:
        """Bring the free-step state array up to date (from pymunk's body unless it is current)."""
        f = self._free
        if not self._free_valid:
            body = self.body
            f[0], f[1] = body.position
            f[2] = body.angle
            f[3], f[4] = body.velocity
            f[5] = body.angular_velocity
        f[6], f[7], f[8] = self._steer, self._speed, self._omega

    def _sync_body(self) -> None:
        """Write the state of free steps into pymunk's body before pymunk is used."""
        if self._body_stale and self._free_valid:
            x, y, a, vx, vy, w = self._free[:6].tolist()
            body = self.body
            body.position = (x, y)
            body.angle = a
            body.velocity = (vx, vy)
            body.angular_velocity = w
        self._body_stale = False
