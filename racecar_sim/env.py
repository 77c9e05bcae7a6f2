"""The Gymnasium environment: a racecar with a lidar and wheel odometry on an occupancy map."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from racecar_sim.car.physics import RacecarPhysics
from racecar_sim.car.start_poses import random_start, shared_start_cells
from racecar_sim.compile_log import install as log_first_compile
from racecar_sim.fleet import CarFleet
from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.render import CarRendering, MapRenderer, RenderHook
from racecar_sim.sensors.lidar import Lidar
from racecar_sim.sensors.odometry import Odometry
from racecar_sim.sensors.onboard import CarSensors
from racecar_sim.settings.config import (
    CarParams,
    EnvConfig,
    LidarParams,
    OdometryNoise,
    load_config,
    merge_settings,
)
from racecar_sim.settings.validation import (
    check_action,
    check_options,
    check_poses,
    check_seed,
    short,
)
from racecar_sim.world.centerline import resolve_track
from racecar_sim.world.laps import LapCounter
from racecar_sim.world.obstacles import Obstacles

log_first_compile()  # the first compile of a kernel of ours is logged (racecar_sim.compile_log)

__all__ = ["EnvConfig", "RacecarEnv", "RenderHook", "load_config"]

_OBSTACLE_REACH = 2.5  # metres: obstacles this close to the rear axle make physics use pymunk



class RacecarEnv(CarSensors, CarRendering, gym.Env):
    """A 1/10-scale racecar with a planar lidar and wheel odometry on a 2D occupancy-grid map.

    ## Description
    A headless simulator of an F1TENTH / MIT RSS style racecar. The car is a kinematic bicycle
    about its rear axle (``car_model="kinematic"``, the default) or a single-track model with tire
    slip and a friction limit (``car_model="single_track"``, `racecar_sim.car.models`), with
    steering-rate and acceleration limits, driving in a pymunk world
    whose walls are the map's occupied-cell edges, so it cannot pass through walls and every wall
    contact is reported. A lidar ``mount_offset`` ahead of the rear axle casts exact rays on the
    grid and adds beam-model noise; the odometry reports what a VESC measures (wheel speed and
    the steering angle through the bicycle formula, [`racecar_sim.sensors.vesc`][racecar_sim.sensors.vesc]) with Gaussian noise.
    Frames: ``world`` (the map's frame), ``car`` (x forward, y left, origin at the rear axle).

    ## Action Space
    ``Box([-max_steer, -max_reverse_speed], [max_steer, max_speed], (2,), float32)``: the front
    wheel angle to steer to (radians, positive turns left) and the speed to reach (m/s, negative
    reverses). Actions outside the box are clipped to it; an action with NaN or infinity raises
    ``ValueError``. The car follows the command within ``max_steer_rate``, ``max_accel`` and
    ``max_decel`` of its [`CarParams`][racecar_sim.settings.config.CarParams].

    ## Observation Space
    ``Dict``:

    * ``scan``: ``Box(0, max_range, (n_beams,), float32)``, lidar ranges in metres, beam ``i`` at
      ``-fov/2 + i * fov/(n_beams-1)`` radians from the heading (right to left). A new scan is
      taken at ``lidar_rate``: at reset, then at the end of the first step whose end time reaches
      each next multiple of ``1 / lidar_rate``. Between scans the last scan is repeated
      (``info["new_scan"]`` tells which steps carry a fresh one).
    * ``odom``: ``Box(-inf, inf, (3,), float32)``, the VESC's noisy car-frame twist ``[vx, vy,
      omega]`` (m/s, m/s, rad/s) at the end of the step, new every step: ``[wheel_speed, 0,
      wheel_speed * tan(steer) / wheelbase]`` ([`racecar_sim.sensors.vesc.wheel_twist()`][racecar_sim.sensors.vesc.wheel_twist]), so a sliding
      car's odometry disagrees with its true twist (``info["twist"]``) as a real car's does.
    * ``imu`` (only with the ``imu`` setting): ``Box(-inf, inf, (1,), float32)``, a gyro's yaw
      rate (rad/s): the true yaw rate over the step plus bias and noise.

    ## Rewards
    The reward is the sum of the named terms in ``info["rewards"]``: ``progress``, metres driven
    forwards along the car's heading this step (negative when reversing), and ``collision``,
    ``-collision_penalty`` on a step with wall contact (else 0).

    ## Starting State
    ``reset(options={"pose": [x, y, theta]})`` puts the car at rest at that world pose of its rear
    axle (``ValueError`` naming the pose if the car would overlap a wall or leave the map).
    Without a pose, the car starts at rest at a random position and heading drawn from
    ``self.np_random``, with ``start_clearance`` metres of free space around its footprint.

    ## Episode End
    ``terminated`` when the car touches a wall, unless ``terminate_on_collision=False`` (then the
    car stays against the wall and the contact is still reported in ``info["collision"]``).
    Never truncated by the env itself; pass ``max_episode_steps`` to ``gymnasium.make``.

    ## Info
    ``pose`` true rear-axle world pose ``[x, y, theta]`` (float64, theta in [-pi, pi)); ``twist``
    true car-frame twist averaged over the step; ``collision`` (bool); ``time`` (s since reset);
    ``new_scan`` (bool); ``rewards`` (dict of named terms). With a ``track`` setting also
    ``progress`` (m along its centerline since the start), ``lap`` (completed laps, counted when
    crossing the start line forwards), ``lap_times`` (s) and ``rank`` (1), as in a race
    (`racecar_sim.world.laps`).

    ## Arguments
    ``gymnasium.make("RacecarSim-v0", map=..., render_mode="rgb_array", **settings)`` where
    ``map`` is a bundled map name (``racecar_sim.maps.bundled_names()``), a map YAML path or an
    [`OccupancyMap`][racecar_sim.maps.OccupancyMap], and ``settings`` are the fields of
    `EnvConfig`: ``n_beams``, ``fov``, ``max_range``, ``mount_offset``, ``lidar_rate``,
    ``dt``, ``substep``, ``terminate_on_collision``, ``collision_penalty``, ``start_clearance``,
    ``range_sigma``, ``p_short``, ``short_lambda``, ``p_max``, ``p_rand``,
    ``odom_proportional``, ``odom_additive``, ``odom_lead``, ``imu``, ``car`` (a ``CarParams``
    or a mapping of its fields), ``car_model``. ``config`` names a YAML file (or is a mapping /
    `EnvConfig`) with the same keys; keyword arguments override it. Unknown keys raise
    ``ValueError`` naming them.
    ``render_mode="rgb_array"`` makes `render()` return an RGB ``uint8`` frame (H, W, 3) of
    the map, the car and the last scan's hits, plus whatever hooks added with
    `add_render_hook()` draw.

    ## Version History
    * v0 (racecar-sim 0.1): the kinematic car, the four-part beam model, Gaussian odometry.
      Every setting added since is off (or at v0's value) by default, so v0's settings give v0's
      episodes:
    * ``noise_profile``, ``scan_effects``, ``odom_bias`` (0.2): a real scanner's correlated
      failures and the VESC's bias replace the beam model's noise (measured profile
      ``mit_racecar``); ``odom_lead`` (0.2): the odometry reads each command that many seconds
      before the body moves on it.
    * ``obstacles``, ``scene`` (0.2): unmapped boxes, people, openings and furniture the lidar sees
      and the car touches.
    * ``imu`` (0.2): adds ``imu`` to the observation space (a new key; ``scan`` and ``odom`` keep
      their draws first, so the same seed gives the same scans and odometry).
    * ``car_model="single_track"`` (0.2): tire slip and a friction limit; the odometry then
      disagrees with ``info["twist"]`` while the car slides.
    * ``track`` (0.2): adds ``progress``, ``lap``, ``lap_times`` and ``rank`` to ``info``.
    * 0.3: ``track="auto"`` works on any map whose free space runs round an island; the bundled
      loop maps' tracks are read from their CSVs (points to 0.1 mm), so ``progress`` on them may
      differ from 0.2's in the fourth decimal. The 0.2 module paths (``racecar_sim.config``, ...)
      import with a ``FutureWarning`` until 0.4. The car steps through the core that the vector
      env and the race share ([`CarFleet`][racecar_sim.fleet.CarFleet] with one car: ``fleet``,
      ``car_index``); its clock and command delay are the core's (``fleet.clocks``,
      ``fleet.delays``, no longer ``clock`` and ``command_delay``); episodes are unchanged.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 40}  # noqa: RUF012

    def __init__(
        self,
        map: str | os.PathLike[str] | OccupancyMap | None = None,
        *,
        config: str | os.PathLike[str] | Mapping[str, Any] | EnvConfig | None = None,
        render_mode: str | None = None,
        **settings: Any,
    ) -> None:
        super().__init__()
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode {render_mode!r} is not supported; use one of "
                f"{self.metadata['render_modes']} or None"
            )
        self.config = merge_settings(config, {"map": map, **settings})
        self.render_mode = render_mode
        cfg = self.config
        self.map: OccupancyMap = resolve_map(cfg.map, cfg.max_map_cells)
        self.car_params: CarParams = cfg.car
        self.lidar_params: LidarParams = cfg.lidar_params()
        self.odometry_noise: OdometryNoise = cfg.odometry_noise()
        self.dt = float(cfg.dt)
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / self.dt))}

        self.physics = RacecarPhysics(
            self.map, self.car_params, substep=cfg.substep, car_model=cfg.car_model
        )
        self.lidar = Lidar(self.map, self.lidar_params)
        self.odometry = Odometry(self.odometry_noise)
        self.fleet = CarFleet([self], cfg, self.lidar.period, self.odometry, self.lidar_params.n_beams)
        """The core this car steps through ([`CarFleet`][racecar_sim.fleet.CarFleet]): its clock
        and scan schedule, its commands on their way to the body (``odom_lead``), its pose, last
        scan and odometry are row ``car_index`` there (a fleet of one of its own, unless a vector
        env or a race made it `join()` theirs)."""
        self.car_index = 0
        """This car's row in `fleet`."""
        self.imu = cfg.imu
        # Honest-world extras (None = off): correlated lidar failures, odometry bias, obstacles.
        self.scan_effects = cfg.scan_effects
        self.odom_bias = cfg.odom_bias
        self.obstacles: Obstacles | None = None
        if cfg.obstacles is not None and cfg.obstacles.active:
            self.obstacles = Obstacles(cfg.obstacles, self.map, self.physics.space)

        car = self.car_params
        self.action_space = spaces.Box(
            low=np.array([-car.max_steer, -car.max_reverse_speed], dtype=np.float32),
            high=np.array([car.max_steer, car.max_speed], dtype=np.float32),
            dtype=np.float32,
        )
        self.observation_space = spaces.Dict(
            {
                "scan": spaces.Box(
                    0.0, self.lidar_params.max_range, (self.lidar_params.n_beams,), np.float32
                ),
                "odom": spaces.Box(-np.inf, np.inf, (3,), np.float32),
            }
        )
        if self.imu is not None:
            self.observation_space["imu"] = spaces.Box(-np.inf, np.inf, (1,), np.float32)
        self._penalty = float(cfg.collision_penalty)
        self._terminate = cfg.terminate_on_collision

        # On a track (the ``track`` setting): progress, laps, lap times and rank in the info.
        self.track = None
        self._laps = None
        if cfg.track is not None:
            self.track = resolve_track(cfg.track, self.map)
            self._laps = LapCounter(self.track, 1)
        self._start_cells: np.ndarray | None = None  # flat cell indices (K,), shared per map
        self._render_hooks: list[RenderHook] = []
        self._renderer: MapRenderer | None = None
        self._needs_reset = True  # until the first reset

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        """Seconds since the reset (the car's clock in the core: steps x dt)."""
        return self.fleet.clocks.time(self.car_index)

    @property
    def pose(self) -> np.ndarray:
        """True rear-axle world pose [x, y, theta] (metres, radians in [-pi, pi))."""
        return self.physics.pose

    def join(self, fleet: CarFleet, index: int) -> None:
        """Make this car row ``index`` of ``fleet`` (an N-car core built over it, before the
        first reset): from now on its clock, scan schedule, command delay, pose, last scan and
        odometry live there, and `reset()` / `step()` go through it (the vector env and the race
        do this, so each car has one clock, kept where they step it)."""
        self.fleet = fleet
        self.car_index = int(index)

    def teleport(self, pose: np.ndarray) -> None:
        """Move the car to ``pose`` at rest without telling anyone (kidnapped-robot tests).

        The clock, the scan schedule and the last scan are kept; the next observation simply comes
        from the new place.

        Raises:
            ValueError: the car would overlap a wall or leave the map at ``pose``.
        """
        self.physics.teleport(pose)

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode; ``options={"pose": [x, y, theta]}`` fixes the start pose.

        Raises:
            ValueError: an unknown option, or a pose that is not finite, inside a wall or off map.
        """
        options = check_options("RacecarEnv.reset", options)
        super().reset(seed=check_seed("RacecarEnv.reset", seed))
        unknown = sorted(set(options) - {"pose"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {short(unknown, 200)}; known: ['pose']")
        if options.get("pose") is None:
            self.physics.reset(self.random_start())
        else:
            pose = check_poses("RacecarEnv.reset options['pose']", options["pose"])
            try:
                self.physics.reset(pose)
            except ValueError as exc:
                raise ValueError(f"reset options['pose'] = {short(pose.tolist())} is not usable: {exc}") from exc
        if self.obstacles is not None:
            # Their own stream from the env's: the same seed places the same obstacles.
            obstacle_rng = np.random.default_rng(int(self.np_random.integers(2**63)))
            self.obstacles.spawn(obstacle_rng, self.physics.pose)
        self.fleet.reset([self.car_index])
        self._needs_reset = False
        pose = self.physics.pose
        self._take_scan(pose)
        twist = self.physics.twist
        obs = self.observation(twist)
        if self._laps is not None:
            self._laps.reset(pose[None, :2])
        info = self._info(pose, twist, False, True, 0.0, 0.0)
        return obs, info

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Drive ``dt`` seconds towards ``action`` = [steer (rad), speed (m/s)] (clipped to the box).

        Raises:
            ValueError: the action is not two finite numbers (a numeric array of shape (2,), or a
                list / tuple of two ints or floats; strings, bools and mappings are refused).
            gymnasium.error.ResetNeeded: `reset()` was never called.
        """
        if self._needs_reset:
            raise ResetNeeded("call reset() before step(): the env has no state yet")
        if type(action) is np.ndarray and action.shape == (2,) and action.dtype.kind in "fiu":
            steer, speed = action.tolist()  # the usual case: one cheap check
        else:
            steer, speed = check_action(action, (2,)).tolist()
        if not (math.isfinite(steer) and math.isfinite(speed)):
            raise ValueError(f"action must be finite [steer, speed], got {short(action)}")
        physics = self.physics
        if self.obstacles is not None:
            self.obstacles.step(self.dt, physics.pose)
            # pymunk must see obstacles near the car (free steps only know the map's walls)
            physics.free_steps = not self.obstacles.near(physics.pose, _OBSTACLE_REACH)
        # The core: clip to the box, the command delay, the physics, the clock (racecar_sim.fleet).
        collided, fresh, pose = self.fleet.step_one(self.car_index, steer, speed)
        if fresh:
            self._take_scan(pose)
        twist = physics.twist
        progress = float(twist[0]) * self.dt
        penalty = -self._penalty if collided else 0.0
        obs = self.observation(twist)
        if self._laps is not None:
            self._laps.update(pose[None, :2], self.time, self.dt)
        info = self._info(pose, twist, collided, fresh, progress, penalty)
        terminated = collided and self._terminate
        return obs, progress + penalty, terminated, False, info

    # ------------------------------------------------------------------ internals
    def _info(
        self,
        pose: np.ndarray,
        twist: np.ndarray,
        collided: bool,
        fresh: bool,
        progress: float,
        penalty: float,
    ) -> dict[str, Any]:
        info = {
            "pose": pose,
            "twist": twist,
            "collision": collided,
            "time": self.time,
            "new_scan": fresh,
            "rewards": {"progress": progress, "collision": penalty},
        }
        if self._laps is not None:
            info.update(self._laps.info(np.ones(1, dtype=np.int64), 0))
        return info

    def random_start(self) -> np.ndarray:
        """A collision-free rear-axle world pose [x, y, theta] with ``start_clearance`` metres of
        room, drawn from ``np_random`` (the cells with that room: one table per map and car size,
        shared by every env on the map)."""
        if self._start_cells is None:
            self._start_cells = shared_start_cells(
                self.map, self.car_params, self.config.start_clearance
            )
        return random_start(self.physics, self._start_cells, self.np_random)
