"""The lap task: drive round the default map's loop from the scan and a pose (true or estimated).

`LapTask` wraps a ``RacecarSim-v0`` env, usually inside an
[`mcl.LocalizationWrapper`][mcl.LocalizationWrapper], into the flat observation / reward an RL library expects:

* **observation** (float32 vector, every entry roughly in [-1, 1]): the scan min-pooled into
  ``scan_bins`` sectors (divided by the lidar's max range); from the *pose source* (``"truth"``:
  ``info["pose"]``, ``"estimate"``: ``obs["pose_estimate"]``) the loop ``lookahead`` metres ahead
  as car-frame points (divided by 5 m), the lateral offset from the loop (m) and the heading
  relative to the loop (sin, cos); the odometry's forward speed (/ max speed) and turn rate (/ 3
  rad/s); the previous action.
* **action** ``[-1, 1]^2``: steering as a fraction of the car's max steer, and speed mapped
  linearly onto ``[min_speed, max_speed]`` m/s (forward only).
* **reward**: metres of progress along the loop this step, measured on the *true* pose, minus
  ``collision_penalty`` on a step with wall contact.
* **info**: the env's (and the wrapper's ``localization``) plus ``lap``: ``s`` (m along the loop,
  truth), ``progress`` (m since reset, truth), ``laps`` (completed), ``lap_times`` (s of each
  completed lap), ``collisions`` (steps with wall contact so far).

Episodes start at rest on the loop: at ``start_s`` metres (None: uniform along the loop), moved
sideways and turned by Gaussian noise, drawn from the task's own generator (spawned from the reset
seed, never from ``env.np_random``, so the simulated world's noise stays the same).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mcl.agents.track import Track, track_for_map
from mcl.filter.params import ParticleFilterParams
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from mcl.wrappers.localization import TRACKING_INIT_SPREAD, LocalizationConfig
from mcl.wrappers.single import LocalizationWrapper
from racecar_sim.env import RacecarEnv
from racecar_sim.maps import DEFAULT_MAP
from racecar_sim.race.single import DRIVERS
from racecar_sim.settings.validation import check_number

__all__ = ["POSE_SOURCES", "LapTask", "LapTaskConfig", "make_lap_env", "make_vector_env"]

POSE_SOURCES: tuple[str, ...] = ("truth", "estimate", "none")
"""Which pose the observation is built from (``none``: the pose features are held at the values of
a car on the loop heading along it, so the policy drives from the scan alone)."""

_TASK_STREAM = 3  # spawn index of the task's start-pose stream in the reset seed's SeedSequence
_LOOKAHEAD_SCALE = 5.0  # metres: look-ahead points are divided by this
_TURN_SCALE = 3.0  # rad/s: turn rate is divided by this


@dataclass(frozen=True)
class LapTaskConfig:
    """Settings of the lap task and of the env stack `make_lap_env()` builds.

    Attributes:
        map: bundled map name (one with a known loop start, see `track_for_map()`).
        pose_source: ``"truth"``, ``"estimate"`` or ``"none"``: the pose the observation is
            built from (none: a scan-only baseline, see `POSE_SOURCES`).
        localize: put MCL in the loop (None: only when the pose source is the estimate).
        n_particles: particles of the filter.
        filter_beams: beams per particle of the sensor model.
        scan_bins: sectors of the min-pooled scan in the observation.
        lookahead: metres ahead along the loop of the look-ahead points.
        min_speed, max_speed: m/s, the speed range of the action.
        collision_penalty: reward subtracted on a step with wall contact.
        terminate_on_collision: end the episode at the first wall contact (training).
        episode_seconds: simulated seconds before the episode is truncated.
        start_s: metres along the loop of the start (None: uniform along the loop).
        start_lateral_sd, start_heading_sd: m and rad, the start's Gaussian noise.
        env: extra [`racecar_sim.env.EnvConfig`][racecar_sim.env.EnvConfig] settings as (name, value) pairs, e.g.
            ``(("car_model", "single_track"),)``.
        opponents: scripted cars racing the agent (0: the agent drives alone in
            ``RacecarSim-v0``; more: ``RacecarRace-v0`` on the map's centerline, the agent
            starting last on the grid, [`mcl.agents.race_task`][mcl.agents.race_task]).
        opponent_driver: their driver (``"racing"``: knows the other cars, follows, passes and
            gives way; ``"pure_pursuit"`` on the centerline blind to them; ``"wall_follower"``).
        opponent_speeds: m/s, one per opponent (None: ``RacecarRace-v0``'s 2.0, 2.4, 2.8, ...).
    """

    map: str = DEFAULT_MAP
    pose_source: str = "estimate"
    localize: bool | None = None
    n_particles: int = 300
    filter_beams: int = 60
    scan_bins: int = 40
    lookahead: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 4.5)
    min_speed: float = 0.5
    max_speed: float = 4.0
    collision_penalty: float = 5.0
    terminate_on_collision: bool = True
    episode_seconds: float = 40.0
    start_s: float | None = None
    start_lateral_sd: float = 0.15
    start_heading_sd: float = 0.15
    env: tuple[tuple[str, Any], ...] = ()
    opponents: int = 0
    opponent_driver: str = "racing"
    opponent_speeds: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.pose_source not in POSE_SOURCES:
            raise ValueError(
                f"LapTaskConfig.pose_source = {self.pose_source!r}; choose one of {POSE_SOURCES}"
            )
        owner = "LapTaskConfig"
        for name in ("n_particles", "filter_beams", "scan_bins"):
            check_number(owner, name, getattr(self, name), low=1, integer=True)
        for name in ("min_speed", "max_speed", "episode_seconds"):
            check_number(owner, name, getattr(self, name), low=0, low_open=True)
        for name in ("collision_penalty", "start_lateral_sd", "start_heading_sd"):
            check_number(owner, name, getattr(self, name), low=0)
        if self.start_s is not None:
            check_number(owner, "start_s", self.start_s, low=0)
        if not 0 < self.min_speed < self.max_speed:
            raise ValueError(
                f"LapTaskConfig: need 0 < min_speed < max_speed, got {self.min_speed}, "
                f"{self.max_speed} m/s"
            )
        object.__setattr__(self, "lookahead", tuple(float(d) for d in self.lookahead))
        if not self.lookahead or not all(math.isfinite(d) for d in self.lookahead):
            raise ValueError("LapTaskConfig.lookahead must hold finite distances in metres")
        object.__setattr__(self, "env", tuple((str(k), v) for k, v in dict(self.env).items()))
        self._check_opponents()

    def _check_opponents(self) -> None:
        check_number("LapTaskConfig", "opponents", self.opponents, low=0, integer=True)
        if self.opponent_driver not in DRIVERS:
            raise ValueError(
                f"LapTaskConfig.opponent_driver = {self.opponent_driver!r}; choose one of {DRIVERS}"
            )
        if self.opponent_speeds is not None:
            speeds = tuple(float(v) for v in self.opponent_speeds)
            if len(speeds) != self.opponents:
                raise ValueError(
                    f"LapTaskConfig.opponent_speeds: {len(speeds)} speeds for "
                    f"{self.opponents} opponents"
                )
            object.__setattr__(self, "opponent_speeds", speeds)
        if self.opponents and self.localized:
            raise ValueError(
                "LapTaskConfig: a race (opponents > 0) runs no MCL; use pose_source 'truth' or "
                "'none'"
            )

    @property
    def car_model(self) -> str:
        """The car's model (``"kinematic"`` unless ``env`` sets ``car_model``)."""
        return str(dict(self.env).get("car_model", "kinematic"))

    @property
    def localized(self) -> bool:
        """Whether MCL runs in the loop."""
        return self.pose_source == "estimate" if self.localize is None else bool(self.localize)

    def localization(self) -> LocalizationConfig:
        """The filter's settings: a tracking filter started around the true start pose."""
        return LocalizationConfig(
            sensor=SensorModelParams(num_beams_per_particle=self.filter_beams, parallel=False),
            filter=ParticleFilterParams(
                n_particles=self.n_particles, init_spread=TRACKING_INIT_SPREAD
            ),
        )


class LapTask(gym.Wrapper):
    """The lap task on a ``RacecarSim-v0`` env (see the module docstring).

    Args:
        env: the env, with a [`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] inside when the pose
            source is ``"estimate"``.
        config: the task.
        track: the loop (default: the wall follower's loop of ``config.map``).
    """

    pose_option = "pose"
    """The reset option `start_pose()`'s value goes into (a race takes ``"poses"``)."""

    def __init__(self, env: gym.Env, config: LapTaskConfig, track: Track | None = None) -> None:
        super().__init__(env)
        if config.pose_source == "estimate" and "pose_estimate" not in env.observation_space.spaces:
            raise ValueError(
                "LapTask: pose_source 'estimate' needs a LocalizationWrapper inside (no "
                "obs['pose_estimate'])"
            )
        self.config = config
        self.track = track if track is not None else track_for_map(config.map)
        inner = env.unwrapped
        self._car = inner.car_params
        self._max_range = float(inner.lidar_params.max_range)
        self._n_beams = int(inner.lidar_params.n_beams)
        self._bins = np.linspace(0, self._n_beams, config.scan_bins + 1).astype(int)[:-1]
        self._ahead = np.asarray(config.lookahead)
        size = config.scan_bins + 2 * len(config.lookahead) + 3 + 2 + 2
        self.observation_space = spaces.Box(-np.inf, np.inf, (size,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._rng = np.random.default_rng()
        self._last_action = np.zeros(2)
        self._s = 0.0
        self._progress = 0.0
        self._laps: list[float] = []
        self._lap_start = 0.0
        self._collisions = 0

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset on the loop (``options[self.pose_option]`` overrides the start)."""
        options = dict(options or {})
        if options.get(self.pose_option) is None:
            options[self.pose_option] = self.start_pose(seed)
        obs, info = self.env.reset(seed=seed, options=options)
        self.begin(info)
        return self.observe(obs, info), self.add_lap_info(info)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Drive one env step with the scaled action; reward = true progress - wall penalty."""
        obs, _, terminated, truncated, info = self.env.step(self.command(action))
        reward = self.track_step(info)
        return self.observe(obs, info), reward, terminated, truncated, self.add_lap_info(info)

    # ------------------------------------------------------------------ the task, step by step
    # (public so that a batched env can run one task per car: start_pose -> env reset -> begin,
    # then command -> env step -> track_step and observe)
    def start_pose(self, seed: int | None = None) -> list[float]:
        """The next episode's start pose (world [x, y, theta]); a seed restarts the draws."""
        if seed is not None:
            stream = np.random.SeedSequence(seed).spawn(_TASK_STREAM + 1)[-1]
            self._rng = np.random.default_rng(stream)
        return self._start_pose()

    def begin(self, info: dict[str, Any]) -> None:
        """Start the bookkeeping of an episode from the reset's info (true pose)."""
        self._last_action = np.zeros(2)
        self._s, _ = self.track.project(info["pose"])
        self._progress = 0.0
        self._laps = []
        self._lap_start = 0.0
        self._collisions = 0

    def command(self, action: Any) -> np.ndarray:
        """The env action [steer rad, speed m/s] of a task action in [-1, 1]^2 (remembered)."""
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(2), -1.0, 1.0)
        cfg = self.config
        self._last_action = a
        steer = a[0] * self._car.max_steer
        speed = cfg.min_speed + 0.5 * (a[1] + 1.0) * (cfg.max_speed - cfg.min_speed)
        return np.array([steer, speed])

    def track_step(self, info: dict[str, Any]) -> float:
        """Progress, laps and wall contact of the step whose info (true pose, time, collision)
        is given; returns the step's reward."""
        s, _ = self.track.project(info["pose"])
        ds = self.track.advance(self._s, s)
        self._s = s
        self._progress += ds
        t = float(info["time"])
        if self._progress >= (len(self._laps) + 1) * self.track.length:
            self._laps.append(t - self._lap_start)
            self._lap_start = t
        collided = bool(info["collision"])
        self._collisions += collided
        return ds - (self.config.collision_penalty if collided else 0.0)

    # ------------------------------------------------------------------ internals
    def _start_pose(self) -> list[float]:
        cfg, track, rng = self.config, self.track, self._rng
        s = rng.uniform(0.0, track.length) if cfg.start_s is None else float(cfg.start_s)
        heading = track.heading_at(s)
        inner = self.env.unwrapped
        for scale in (1.0, 0.5, 0.0):
            lateral = scale * cfg.start_lateral_sd * rng.standard_normal()
            theta = heading + scale * cfg.start_heading_sd * rng.standard_normal()
            x, y = track.point_at(s) + lateral * np.array([-math.sin(heading), math.cos(heading)])
            pose = [float(x), float(y), float(math.remainder(theta, 2 * math.pi))]
            if inner.physics.pose_is_free(np.array(pose)):
                return pose
        return pose  # the env names the pose if even the loop point is not free

    def observe(self, obs: dict[str, Any], info: dict[str, Any]) -> np.ndarray:
        """The task's observation of an env observation and info (see the module docstring)."""
        cfg = self.config
        scan = np.minimum.reduceat(np.asarray(obs["scan"], dtype=np.float64), self._bins)
        if cfg.pose_source == "none":  # on the loop, heading along it, the loop straight ahead
            ahead = np.stack([self._ahead, np.zeros_like(self._ahead)], axis=1) / _LOOKAHEAD_SCALE
            lateral, rel = 0.0, 0.0
        else:
            pose = np.asarray(
                info["pose"] if cfg.pose_source == "truth" else obs["pose_estimate"],
                dtype=np.float64,
            )
            s, lateral = self.track.project(pose)
            ahead = self.track.ahead(pose, s, self._ahead) / _LOOKAHEAD_SCALE
            rel = math.remainder(pose[2] - self.track.heading_at(s), 2 * math.pi)
        odom = np.asarray(obs["odom"], dtype=np.float64)
        return np.concatenate(
            [
                np.clip(scan / self._max_range, 0.0, 1.0),
                np.clip(ahead.ravel(), -2.0, 2.0),
                [np.clip(lateral, -2.0, 2.0), math.sin(rel), math.cos(rel)],
                [odom[0] / cfg.max_speed, odom[2] / _TURN_SCALE],
                self._last_action,
            ]
        ).astype(np.float32)

    def add_lap_info(self, info: dict[str, Any]) -> dict[str, Any]:
        """``info`` with the episode's ``lap`` bookkeeping added."""
        lap = {
            "s": self._s,
            "progress": self._progress,
            "laps": len(self._laps),
            "lap_times": list(self._laps),
            "collisions": self._collisions,
        }
        return {**info, "lap": lap}


@lru_cache(maxsize=2)
def _shared_sensor_model(map_name: str, config: LapTaskConfig) -> SensorModel:
    """One sensor model per process for every env of a task (the table is built once)."""
    from dataclasses import replace

    env = RacecarEnv(map_name, **dict(config.env))
    params = replace(
        config.localization().sensor, mount_offset=float(env.lidar_params.mount_offset)
    )
    return SensorModel(env.map, params, beam_angles=np.asarray(env.lidar.angles))


def make_lap_env(
    config: LapTaskConfig | None = None,
    *,
    render_mode: str | None = None,
    log_path: str | None = None,
) -> gym.Env:
    """``RacecarEnv`` -> [``LocalizationWrapper``] -> `LapTask` -> ``TimeLimit``: the car
    alone (with opponents: [`mcl.agents.task_env.make_task_env()`][mcl.agents.task_env.make_task_env])."""
    config = config if config is not None else LapTaskConfig()
    if config.opponents:
        raise ValueError(
            "make_lap_env drives the car alone; a config with opponents needs "
            "mcl.agents.task_env.make_task_env"
        )
    settings = {"terminate_on_collision": config.terminate_on_collision, **dict(config.env)}
    env: gym.Env = RacecarEnv(config.map, render_mode=render_mode, **settings)
    if config.localized:
        env = LocalizationWrapper(
            env,
            config.localization(),
            log_path=log_path,
            sensor_model=_shared_sensor_model(config.map, config),
        )
    env = LapTask(env, config)
    steps = max(1, round(config.episode_seconds / env.unwrapped.dt))
    return gym.wrappers.TimeLimit(env, max_episode_steps=steps)


def make_vector_env(config: LapTaskConfig | None = None, n_envs: int = 4) -> gym.vector.VectorEnv:
    """``n_envs`` lap envs stepped in this process (Gymnasium's sync vector env, autoreset)."""
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise ValueError(f"n_envs = {n_envs!r} must be a positive integer")
    return gym.vector.SyncVectorEnv([lambda: make_lap_env(config) for _ in range(n_envs)])
