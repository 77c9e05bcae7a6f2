"""Car physics: a pymunk world with the map's walls and a racecar (kinematic or single-track).

Frames: ``world`` (the map's frame, metres, radians) and ``car`` (x forward, y left, origin at the
rear axle). The car's pose is the world pose [x, y, theta] of the *rear axle*.

Walls
    Every edge between a free cell and an occupied (or unknown) cell becomes a static pymunk
    segment lying exactly on that cell edge; collinear neighbouring edges are merged into one
    segment. The map border counts as a wall (cells beyond the image are occupied), so the walls
    are exactly where the grid says, with no thickness added. Static shapes are kept in pymunk's
    spatial hash, so a step only looks at the segments near the car; and the space only holds the
    walls within a few metres of where pymunk is used ([`racecar_sim.car.walls`][racecar_sim.car.walls]: computed once per
    map, made into pymunk shapes per car when first needed), so a car is built in milliseconds.

Car
    The pymunk body and footprint of [`racecar_sim.car.body`][racecar_sim.car.body]. A command [steer, speed] first
    goes through the steering-rate and acceleration / braking limits, then through the angle and
    speed limits. Each substep the body's velocity is set from the kinematic bicycle model about
    the rear axle: speed along the heading, ``omega = speed * tan(steer) / wheelbase``.

    The velocity is set in the body's ``velocity_func``, which pymunk calls *before* its contact
    solver. The solver then removes whatever part of that velocity drives into a wall (plus a
    small push-out of any overlap) before the positions are integrated at the next substep, so the
    car cannot pass through walls and wall contact is a real pymunk collision. The linear velocity
    points along the mid-substep heading ``theta + omega * h / 2`` so that each free substep moves
    the axle along the exact chord of its arc. While a wall blocks the car its speed is cut to
    what it actually makes along its heading (the wheels do not spin), so backing away from a
    wall starts at once.

    With ``car_model="single_track"`` ([`racecar_sim.car.models.single_track`][racecar_sim.car.models.single_track]: tire slip, a
    friction limit) each substep first advances the model, then sets the body's velocity to the
    model's rear-axle velocity for the substep *before* ``space.step`` (so a command acts at once,
    not a substep late), unless the previous substep touched a wall: then the solver's velocity
    stands and the model's slip, yaw rate and speed are taken from it. Without a contact the solver
    leaves the velocity alone, so this is still exactly what the free steps compute.

Free steps
    Far from every wall pymunk has nothing to solve: a substep only moves the body by its velocity
    (``p += v h``, ``a += w h``) and then calls the velocity function. [`RacecarPhysics.step()`][RacecarPhysics.step]
    does exactly these floating-point operations itself, without pymunk, when the car cannot
    reach a wall within the step: the distance field at the footprint's centre exceeds its half
    diagonal, the farthest it can move in ``dt`` and a margin; and no contact is cached (pymunk
    keeps a contact for ``collision_persistence`` steps after it ends, so a few pymunk substeps
    without contact must have passed). The result is bit for bit what pymunk computes (tested);
    the body is brought up to date before pymunk is used again.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from racecar_sim.car.body import CAR_COLLISION_TYPE, make_car_body
from racecar_sim.car.free_steps import (
    CONSTANT_FIELDS,
    STATE_FIELDS,
    body_velocity,
    free_constants,
    free_step,
    se2_log_twist,
)
from racecar_sim.car.models import check_car_model
from racecar_sim.car.models.kinematic import actuate
from racecar_sim.car.models.single_track import settle
from racecar_sim.car.models.single_track import substep as single_track_substep
from racecar_sim.car.state import CarState, wrap_angle
from racecar_sim.car.walls import (
    WALL_COLLISION_TYPE,
    WallLoader,
    tiles_for,
    wall_segments,
)
from racecar_sim.maps import OccupancyMap
from racecar_sim.settings.config import CarParams
from racecar_sim.settings.validation import check_poses

__all__ = ["CAR_COLLISION_TYPE", "WALL_COLLISION_TYPE", "RacecarPhysics", "wall_segments"]

"""pymunk collision type of the car's shape."""

_COLLISION_SLOP = 1e-3  # metres of overlap pymunk tolerates before pushing shapes apart
_HASH_COUNT = 1000  # spatial hash buckets; pymunk clears them all every step, so keep it small
_FREE_MARGIN = 0.05  # metres kept between the footprint's reach and the walls on a free step


class RacecarPhysics(CarState):
    """A racecar driving among the walls of an occupancy map (see the module docstring).

    Args:
        occupancy_map: the map; its free/occupied cell edges become the walls.
        car: the car's geometry and limits.
        substep: longest physics substep in seconds; `step()` splits ``dt`` into equal
            substeps no longer than this. At the default 5 ms a car at 7 m/s moves 3.5 cm (less
            than a typical 5 cm cell) per substep, which bounds how far it can overlap a wall.
        car_model: ``"kinematic"`` (the bicycle above) or ``"single_track"`` (tire slip and a
            friction limit, [`racecar_sim.car.models.single_track`][racecar_sim.car.models.single_track]): the velocity each substep
            sets is then the single-track model's rear-axle velocity, walls act the same way.

    The car starts at rest at the first free cell with room for it; call `reset()`.
    """

    def __init__(
        self,
        occupancy_map: OccupancyMap,
        car: CarParams | None = None,
        substep: float = 0.005,
        car_model: str = "kinematic",
    ) -> None:
        if not (isinstance(substep, int | float) and math.isfinite(substep) and substep > 0):
            raise ValueError(f"substep must be a positive number of seconds, got {substep!r}")
        self.map = occupancy_map
        self.car = car if car is not None else CarParams()
        if not isinstance(self.car, CarParams):
            raise TypeError(f"car must be a CarParams, got {type(self.car).__name__}")
        self.substep = float(substep)
        self.car_model = check_car_model(car_model)
        self._single_track = self.car_model == "single_track"

        self.space = pymunk.Space()
        self.space.collision_slop = _COLLISION_SLOP
        self.space.use_spatial_hash(self._hash_dim(), _HASH_COUNT)
        # The map's walls, only those near the car in its space (racecar_sim.car.walls).
        self._walls = WallLoader(self.space, tiles_for(occupancy_map))
        self.n_segments = len(self._walls.tiles)

        parts = make_car_body(self.car, self.space)
        self._local_corners = parts.corners
        self._extent = parts.extent
        self.body, self.shape = parts.body, parts.shape
        self._query_body, self._query_shape = parts.query_body, parts.query_shape
        self.body.velocity_func = self._set_velocity
        self.space.on_collision(CAR_COLLISION_TYPE, WALL_COLLISION_TYPE, pre_solve=self._on_contact)

        self._steer = 0.0  # radians, front wheel angle
        self._speed = 0.0  # m/s along the heading, rear axle
        self._omega = 0.0  # rad/s commanded by the bicycle model this substep
        self._half_h = 0.0  # seconds, half the current substep
        self._contact = False
        self._twist = np.zeros(3)

        # Free steps (module doc): the body and wheel state (racecar_sim.car.free_steps) kept here while
        # pymunk is not used, whether it is current and pymunk's body lags behind it, and pymunk
        # substeps since the last contact (a contact stays cached for collision_persistence steps).
        self.free_steps = True
        """Take free steps without pymunk far from walls (same results; False forces pymunk)."""
        self._free = np.zeros(len(STATE_FIELDS))
        self._free_valid = False
        self._body_stale = False
        self._quiet_needed = int(self.space.collision_persistence) + 1
        self._quiet = self._quiet_needed
        self._placed = True  # no pymunk step since the last placement
        self._free_const = free_constants(self.car, occupancy_map, _FREE_MARGIN, self.car_model)
        self._model_params = self._free_const[len(CONSTANT_FIELDS) :]
        self._distance = occupancy_map.distance
        self._place(self._first_free_pose(), 0.0, 0.0)

    # ------------------------------------------------------------------ setup helpers
    def _hash_dim(self) -> float:
        """Spatial hash cell size in metres: about the car's size, at least a few map cells."""
        return max(self.car.length, 4 * self.map.resolution)

    def _first_free_pose(self) -> np.ndarray:
        """Some pose where the car fits, for the state before the first reset."""
        need = math.hypot(self.car.length, self.car.width)
        distance = self.map.distance
        # The first cell in row-major order with room (else the roomiest), without a (K, 2) copy.
        room = distance >= need
        flat = int(np.argmax(room)) if room.any() else int(np.argmax(distance))
        del room
        xy = self.map.grid_to_world(np.array(np.unravel_index(flat, distance.shape)))
        return np.array([xy[0], xy[1], 0.0])

    # ------------------------------------------------------------------ pymunk callbacks
    def _set_velocity(self, body: pymunk.Body, gravity, damping, dt) -> None:
        """Velocity integration replaced by the car model's velocity (see module doc)."""
        if self._single_track:  # set before the step (see step); the solver corrects it
            return
        heading = body.angle + self._omega * self._half_h
        body.velocity = (self._speed * math.cos(heading), self._speed * math.sin(heading))
        body.angular_velocity = self._omega

    def _on_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
        self._contact = True

    def mark_contact(self) -> None:
        """Record that the car touched something in the current pymunk substep (for collision
        handlers that replace this class's own wall handler, such as the race's)."""
        self._contact = True

    def pose_is_free(self, pose: np.ndarray) -> bool:
        """Whether the car's footprint at ``pose`` overlaps no wall and lies on the map.

        Exact to the wall segments: no segment may touch the footprint, and the footprint's centre
        must be in a free cell (so a footprint buried inside a thick wall counts as blocked).
        """
        x, y, theta = self._check_pose(pose, "pose")
        centre = self.footprint((x, y, theta)).mean(axis=0)
        if not bool(self.map.is_free(centre)):
            return False
        self._query_body.position = (x, y)
        self._query_body.angle = theta
        self._query_shape.cache_bb()
        # The car's space: the walls near the car, obstacles, other cars' boxes; then the walls
        # there, in the map's shared query space (none are added to the car's own).
        if self.space.shape_query(self._query_shape):
            return False
        return not self._walls.tiles.overlaps(self._query_shape, x, y, self._extent)

    @staticmethod
    def _check_pose(pose, name: str) -> tuple[float, float, float]:
        arr = check_poses(name, pose)
        return float(arr[0]), float(arr[1]), float(arr[2])

    # ------------------------------------------------------------------ commands
    def _place(self, pose: np.ndarray, speed: float, steer: float) -> None:
        x, y, theta = pose
        self._steer = float(np.clip(steer, -self.car.max_steer, self.car.max_steer))
        self._speed = float(np.clip(speed, -self.car.max_reverse_speed, self.car.max_speed))
        self._omega = self._speed * math.tan(self._steer) / self.car.wheelbase
        ux = self._speed
        if self._single_track:  # starts on the kinematic bicycle's slip and yaw rate
            f = self._free
            f[6], f[7] = self._steer, self._speed
            settle(f, self._model_params)
            self._omega = float(f[8])
            ux = float(f[11])
        body = self.body
        self._free_valid = False
        self._body_stale = False
        # pymunk keeps the body's bias velocity (its push out of a wall) until the next position
        # update, so the first step after a placement goes through pymunk.
        self._quiet = self._quiet_needed - 1
        self._placed = True
        # Re-adding the car drops pymunk's cached contacts, so a reset starts from a clean state
        # (the same reset gives the same motion whatever happened before).
        self.space.remove(body, self.shape)
        body.position = (float(x), float(y))
        body.angle = wrap_angle(float(theta))
        body.velocity = (ux * math.cos(body.angle), ux * math.sin(body.angle))
        body.angular_velocity = self._omega
        body.force = (0.0, 0.0)
        body.torque = 0.0
        self.space.add(body, self.shape)
        self._contact = False
        self._twist[:] = (ux, 0.0, self._omega)  # in place: a vector env shares it

    def reset(self, pose: np.ndarray, speed: float = 0.0, steer: float = 0.0) -> None:
        """Put the car at ``pose`` (rear-axle world [x, y, theta]) driving at ``speed`` (m/s) with
        the wheels at ``steer`` (radians); both are clipped to the car's limits.

        Raises:
            ValueError: the pose is not three finite numbers, or the car would overlap a wall or
                leave the map there.
        """
        checked = self._check_pose(pose, "pose")
        for name, value in (("speed", speed), ("steer", steer)):
            if not math.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value!r}")
        if not self.pose_is_free(np.array(checked)):
            raise ValueError(
                f"pose {list(checked)} puts the car inside a wall or off map {self.map.name!r}"
            )
        self._place(np.array(checked), speed, steer)

    def teleport(self, pose: np.ndarray) -> None:
        """Move the car to ``pose`` at rest (speed 0, wheels straight), keeping no old motion.

        Raises:
            ValueError: as `reset()`.
        """
        self.reset(pose, 0.0, 0.0)

    def step(self, command, dt: float) -> bool:
        """Drive for ``dt`` seconds towards ``command`` = [steer (rad), speed (m/s)].

        The command is clipped to the car's limits; steering follows it at ``max_steer_rate``,
        speed at ``max_accel`` when speeding up and ``max_decel`` when slowing down (a sign change
        brakes to a stop first).

        Returns:
            Whether the car touched a wall during the step.

        Raises:
            ValueError: the command is not two finite numbers, or ``dt`` is not positive.
        """
        car = self.car
        steer_cmd, speed_cmd = float(command[0]), float(command[1])
        if not (math.isfinite(steer_cmd) and math.isfinite(speed_cmd)) or len(command) != 2:
            raise ValueError(f"command must be two finite numbers [steer, speed], got {command!r}")
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        target_steer = min(max(steer_cmd, -car.max_steer), car.max_steer)
        target_speed = min(max(speed_cmd, -car.max_reverse_speed), car.max_speed)
        n_sub = max(1, math.ceil(dt / self.substep - 1e-9))
        h = dt / n_sub
        max_dsteer = car.max_steer_rate * h
        accel = car.max_accel * h
        decel = car.max_decel * h
        inv_wheelbase = 1.0 / car.wheelbase
        if self.free_steps and self._quiet >= self._quiet_needed:
            f = self._free
            self._load_free_state()
            if free_step(
                self._distance, self._free_const, f, target_steer, target_speed, n_sub, h, dt,
                self._twist,
            ):  # fmt: skip
                self.stepped_freely(h)
                return False
        self._sync_body()
        self._free_valid = False
        body = self.body
        x0, y0 = body.position
        # Walls within reach of the car during this step (its farthest corner, plus its speed).
        reach = self._extent + dt * max(abs(self._speed), abs(target_speed))
        # Contact impulses live in pymunk's arbiters: keep the walls in while a contact may be
        # cached (not after a placement, which dropped them), so that a new block drops none.
        keep = self._quiet < self._quiet_needed and not self._placed
        self._walls.ensure(x0, y0, reach, keep=keep)
        self._placed = False
        a0 = body.angle
        self._half_h = 0.5 * h
        self._contact = False
        collided = False
        steer = self._steer
        speed = self._speed
        f = self._free
        for _ in range(n_sub):
            if self._single_track:
                f[6], f[7] = steer, speed
                single_track_substep(f, target_steer, target_speed, self._model_params, h)
                steer, speed = float(f[6]), float(f[7])
                self._omega = float(f[8])
                if self._quiet > 0:  # no contact last substep: the solver left the velocity alone
                    body.velocity = body_velocity(body.angle, self._omega, self._half_h, f[11],
                                                  f[12])  # fmt: skip
                    body.angular_velocity = self._omega
            else:
                steer, speed = actuate(
                    steer, speed, target_steer, target_speed, max_dsteer, accel, decel
                )
                self._omega = speed * math.tan(steer) * inv_wheelbase
            self._steer = steer
            self._speed = speed
            self.space.step(h)
            self._quiet += 1
            if self._contact:
                # Blocked by a wall: the wheels turn no faster than the car can move (no wheel
                # spin), so the speed becomes the solved velocity along the heading.
                collided = True
                self._contact = False
                self._quiet = 0
                vx, vy = body.velocity
                heading = body.angle
                speed = vx * math.cos(heading) + vy * math.sin(heading)
                if self._single_track:
                    across = vy * math.cos(heading) - vx * math.sin(heading)
                    speed = self._slide_after_contact(speed, across)
                speed = min(max(speed, -car.max_reverse_speed), car.max_speed)
                self._speed = speed
        x1, y1 = body.position
        # The same numba function as the free steps' (identical doubles either way).
        self._twist[:] = se2_log_twist(x1 - x0, y1 - y0, a0, body.angle - a0, dt)
        return collided

    def _slide_after_contact(self, ux: float, uy: float) -> float:
        """The single-track states from the solved rear-axle velocity (car frame, m/s) and yaw
        rate after a wall contact; returns the new wheel speed (``ux``)."""
        f = self._free
        r = float(self.body.angular_velocity)
        f[9] = uy + self.car.cg_to_rear * r
        f[10] = r
        return ux
