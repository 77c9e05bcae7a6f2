"""RaceEnv: several racecars on one track, as a PettingZoo ``ParallelEnv``.

Every car is the single env's car (``RacecarSim-v0``: its observation, action, noise and seeding)
and every ``RacecarSim-v0`` setting applies to every car. What a race adds (see
[`RaceWorld`][racecar_sim.race.world.RaceWorld]): each lidar sees the other cars' boxes exactly as it
sees walls, cars collide with each other as pymunk bodies, and on a track the info carries
progress, laps, lap times and race order (`racecar_sim.world.laps`). Needs the ``race`` extra
(pettingzoo; in the checkout ``.venv/bin/pip install -e '.[race]'``).
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import os
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

try:  # the race extra; without it RaceEnv still works (RacecarRace-v0 needs no pettingzoo)
    from pettingzoo import ParallelEnv
except ImportError:  # pragma: no cover - pettingzoo is in the dev extra
    ParallelEnv = object  # type: ignore[assignment,misc]

from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.race.drawing import CAR_COLOURS, draw_race
from racecar_sim.race.grid import start_grid
from racecar_sim.race.world import RaceWorld
from racecar_sim.render import MapRenderer, warn_no_render_mode
from racecar_sim.settings.config import EnvConfig, merge_settings
from racecar_sim.settings.validation import (
    check_action,
    check_number,
    check_options,
    describe,
    short,
)
from racecar_sim.vector_env import car_seeds
from racecar_sim.world.centerline import resolve_track
from racecar_sim.world.laps import LapCounter
from racecar_sim.world.track import LOOP_STARTS, Track

MAX_CARS = 100
"""Most cars in one race (each car is an env: physics, lidar, odometry; every pair is checked for
contact each step)."""

__all__ = ["CAR_COLOURS", "RaceEnv"]



class RaceEnv(ParallelEnv):
    """``n_cars`` racecars on one map: a PettingZoo ``ParallelEnv`` with agents ``car_0`` ...

    ## Spaces (per agent, as ``RacecarSim-v0``)
    Action ``Box([-max_steer, -max_reverse_speed], [max_steer, max_speed])``: steer (rad),
    speed (m/s), clipped to the box (NaN or infinity raise ``ValueError``). Observation
    ``Dict(scan=Box(0, max_range, (n_beams,)), odom=Box(-inf, inf, (3,)))``: the lidar's ranges
    (metres, walls and the other cars' boxes, with the beam noise) and the noisy car-frame twist.

    ## Step
    ``step(actions: dict[agent, action]) -> obs, rewards, terminations, truncations, infos``,
    every dict keyed by the agents alive before the step. The reward is the single env's (metres
    driven forwards along the heading, minus ``collision_penalty`` on a step with contact).
    ``terminated`` on any contact (wall or car) unless ``terminate_on_collision=False``;
    ``truncated`` after ``max_episode_steps``. A finished car leaves `agents` and stays where
    it stopped, still seen and touched by the others. A step before `reset()` (or after a
    refused one), or once every agent is done, raises ``ResetNeeded``.

    ## Info (per agent)
    ``pose`` (rear axle, world [x, y, theta]), ``twist``, ``collision`` (what the car touched
    this step: ``"wall"``, ``"car_3"``, ... the first of ``contacts``; ``""`` for nothing),
    ``contacts`` (all of them), ``time`` (s), ``new_scan``, ``rewards`` (named terms); on a track
    also ``progress`` (m along the centerline since the start), ``lap`` (completed laps),
    ``lap_times`` (s) and ``rank`` (1 = leading).

    ## Reset
    ``reset(seed=s)`` seeds car ``i`` with ``s + i`` (or a list of seeds);
    ``options={"poses": array (N, 3)}`` places the cars (rear-axle world poses; ``ValueError``
    naming the car that would overlap a wall or another car). Other options are ignored, as
    PettingZoo's API allows (its API test passes ``{"options": 1}``), except a near miss of
    ``"poses"`` (``"pose"``, ``"Poses"``): a ``ValueError``, since the race would otherwise start
    from the grid. Without poses the cars stand on the
    track's staggered start grid ([`start_grid()`][racecar_sim.race.grid.start_grid]; it holds track length
    / (car length + 0.3 m) cars, more is a ``ValueError``), or at random free places clear of each
    other when there is no track. The same seed gives the same race.

    Args:
        map: as ``RacecarSim-v0`` (a bundled name, a map YAML or an `OccupancyMap`).
        n_cars: number of cars (agents ``car_0`` ... ``car_{n_cars-1}``).
        config: as ``RacecarSim-v0``; keyword ``settings`` override it.
        track: a centerline CSV (f1tenth's format), ``"auto"``, a `Track`, or None: the
            bundled centerline on a bundled loop map (`LOOP_STARTS`), else no track;
            ``"auto"`` on any other loop map derives it
            ([`racecar_sim.world.centerline`][racecar_sim.world.centerline]).
        max_episode_steps: truncate every agent after this many steps (None: never).
        workers: threads casting the scans (default 1).
        render_mode: ``"rgb_array"`` or None.

    ## Version History
    * v0 (racecar-sim 0.2): N cars that see and touch each other, with laps and ranks on a track.
    * 0.3: the bundled loop maps' default track is read from their ``NAME_centerline.csv``
      (points to 0.1 mm); ``track="auto"`` works on any map whose free space runs round an
      island; ``n_cars`` that do not fit on the grid say so at construction.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012
        "name": "racecar_race_v0",
        "render_modes": ["rgb_array"],
        "render_fps": 40,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        map: str | os.PathLike[str] | OccupancyMap | None = None,
        n_cars: int = 2,
        *,
        config: str | os.PathLike[str] | Mapping[str, Any] | EnvConfig | None = None,
        track: str | os.PathLike[str] | Track | None = None,
        max_episode_steps: int | None = None,
        workers: int = 1,
        render_mode: str | None = None,
        **settings: Any,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode {render_mode!r} is not supported; use 'rgb_array' or None"
            )
        if max_episode_steps is not None and (
            not isinstance(max_episode_steps, int)
            or isinstance(max_episode_steps, bool)
            or max_episode_steps < 1
        ):
            raise ValueError(
                f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}"
            )
        check_number("RaceEnv", "n_cars", n_cars, low=1, high=MAX_CARS, integer=True)
        cfg = merge_settings(config, {"map": map, "track": track, **settings})
        grid = resolve_map(cfg.map, cfg.max_map_cells)
        spec = cfg.track
        if spec is None and grid.name in LOOP_STARTS:
            spec = "auto"
        self.track: Track | None = resolve_track(spec, grid)
        """The race's track (None: no progress, laps or grid)."""
        self.config = dataclasses.replace(cfg, map=grid, track=None)  # the cars' own settings
        self.world = RaceWorld(n_cars, self.config, workers=workers)
        self.render_mode = render_mode
        self.max_episode_steps = max_episode_steps
        first = self.world.cars[0]
        self.map = grid
        self.dt = self.world.dt
        self.car_params = first.car_params
        self.lidar_params = first.lidar_params
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / self.dt))}
        self.possible_agents: list[str] = [f"car_{i}" for i in range(n_cars)]
        self.agents: list[str] = []
        self._alive_set: set[str] = set()
        self._index = {a: i for i, a in enumerate(self.possible_agents)}
        self._obs_space: spaces.Dict = first.observation_space
        self._act_space: spaces.Box = first.action_space
        self._penalty = float(self.config.collision_penalty)
        self._terminate = bool(self.config.terminate_on_collision)
        self.laps: LapCounter | None = (
            LapCounter(self.track, n_cars) if self.track is not None else None
        )
        self._active = np.zeros(n_cars, dtype=np.bool_)
        self._n_steps = 0
        self._needs_reset = True  # until a reset goes through
        self._renderer: MapRenderer | None = None

    # ------------------------------------------------------------------ spaces
    @functools.cache  # noqa: B019 - the same object every call (PettingZoo)
    def observation_space(self, agent: str) -> spaces.Space:
        """The agent's observation space (every car's is the single env's)."""
        self._check_agent(agent)
        return self._obs_space

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> spaces.Space:
        """The agent's action space: [steer rad, speed m/s]."""
        self._check_agent(agent)
        return self._act_space

    def _check_agent(self, agent: str) -> None:
        if agent not in self._index:
            raise ValueError(
                f"unknown agent {agent!r}; agents are car_0 ... car_{len(self._index) - 1}"
            )

    # ------------------------------------------------------------------ state
    @property
    def poses(self) -> np.ndarray:
        """(N, 3) true rear-axle world poses of every car (a copy)."""
        return self.world.poses.copy()

    @property
    def cars(self) -> list:
        """Each car's [`RacecarEnv`][racecar_sim.env.RacecarEnv] (its physics, lidar and generator)."""
        return self.world.cars

    # ------------------------------------------------------------------ PettingZoo API
    def reset(
        self, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, dict[str, Any]]]:
        """Start a race (see the class doc); returns ``(observations, infos)`` per agent."""
        n = self.world.n_cars
        self._needs_reset = True  # until this reset goes through
        seeds = car_seeds(seed, n)
        options = check_options("RaceEnv.reset", options)
        for key in options:  # others are ignored, as PettingZoo's API has it; a typo is not
            if key != "poses" and difflib.get_close_matches(key.strip().lower(), ["poses"]):
                raise ValueError(
                    f"RaceEnv.reset: unknown option {short(key)} (did you mean 'poses'?)"
                )
        poses = options.get("poses")
        # The last race's ghosts leave the cars' spaces first: the grid's room check queries car
        # 0's space, where another car's ghost on a slot would take the slot's room.
        self.world.contacts.remove_all()
        where = "options['poses']" if poses is not None else "random starts"
        if poses is None and self.track is not None:
            where = f"start grid of n_cars = {n}"
            for car, s in zip(self.world.cars, seeds, strict=True):
                gym.Env.reset(car, seed=s)  # the grid draws nothing; seeding first keeps it simple
            try:
                poses = start_grid(
                    self.track, n, self.car_params, self.world.cars[0].physics.pose_is_free
                )
            except ValueError as exc:
                raise ValueError(f"RaceEnv.reset (n_cars = {n}, no options['poses']): {exc}") from None
        try:
            self.world.reset(seeds, poses)
        except ValueError as exc:
            raise ValueError(f"RaceEnv.reset {where}: {exc}") from None
        self._needs_reset = False
        self._set_agents(self.possible_agents[:])
        self._n_steps = 0
        if self.laps is not None:
            self.laps.reset(self.world.poses[:, :2])
        zero = np.zeros(n)
        no_contact = np.zeros(n, dtype=np.bool_)
        return self._observations(self.agents), self._infos(self.agents, no_contact, zero, zero)

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """Drive every live agent by its action ``[steer rad, speed m/s]`` for ``dt`` seconds.

        Raises:
            ValueError: ``actions`` is not a mapping, an action for an agent that is not alive, a
                missing action, or an action that is not two finite numbers (the agent named).
            gymnasium.error.ResetNeeded: `reset()` was never called (or was refused), or every
                agent is done.
        """
        if self._needs_reset:
            raise ResetNeeded("RaceEnv.step: call reset() before step(): the race has no state yet")
        n = self.world.n_cars
        alive = self.agents
        if not isinstance(actions, Mapping):
            raise ValueError(
                "RaceEnv.step: actions must be a dict {agent: [steer rad, speed m/s]} of the live "
                f"agents, got {describe(actions)}"
            )
        if not alive:
            raise ResetNeeded("RaceEnv.step: every agent is done; call reset() to race again")
        if actions.keys() != self._alive_set:
            extra = sorted(set(actions) - self._alive_set, key=repr)
            if extra:
                raise ValueError(
                    f"RaceEnv.step: actions for agents not alive: {short(extra, 120)}; "
                    f"alive: {short(alive, 120)}"
                )
            missing = [a for a in alive if a not in actions]
            raise ValueError(f"RaceEnv.step: no action for live agent {missing[0]!r}")
        given_actions = [actions[a] for a in alive]
        if all(type(v) is np.ndarray and v.shape == (2,) and v.dtype.kind in "fiu"
               for v in given_actions):  # fmt: skip
            given = np.array(given_actions, dtype=np.float64)  # the usual case: one cheap check
        else:
            given = None
        if given is None or not np.isfinite(given).all():
            # numbers of shape (2,) only: "12", b"12", ("0.1", "2") and [True, True] are refused,
            # naming the agent
            given = np.array(
                [
                    check_action(v, (2,), f"RaceEnv.step: action of {a}")
                    for a, v in zip(alive, given_actions, strict=True)
                ]
            )
        rows = self._rows(alive)
        if len(alive) == n:
            acts = given
        else:
            acts = np.zeros((n, 2))
            acts[rows] = given
        acts = self.world.fleet.clip(acts)  # to the action box (the core's)
        collided = self.world.step(acts, self._active)
        self._n_steps += 1
        if self.laps is not None:
            idx = np.flatnonzero(self._active)
            self.laps.update(self.world.poses[:, :2], self.world.time, self.dt, idx)
        progress = self.world.twists[:, 0] * self.dt
        penalty = np.where(collided, -self._penalty, 0.0)
        rewards = (progress + penalty)[rows].tolist()
        term = (collided & self._terminate)[rows].tolist()
        trunc = self.max_episode_steps is not None and self._n_steps >= self.max_episode_steps
        obs = self._observations(alive)
        infos = self._infos(alive, collided, progress, penalty)
        rew = dict(zip(alive, rewards, strict=True))
        terminations = dict(zip(alive, term, strict=True))
        truncations = dict.fromkeys(alive, bool(trunc))
        if trunc:
            self._set_agents([])
        elif any(term):
            self._set_agents([a for a, t in zip(alive, term, strict=True) if not t])
        return obs, rew, terminations, truncations, infos

    def _rows(self, agents: list[str]) -> np.ndarray | slice:
        """The cars of ``agents`` (in order) as an index: a slice when they are every car."""
        if len(agents) == len(self.possible_agents):
            return slice(None)
        return np.array([self._index[a] for a in agents], dtype=np.int64)

    def _set_agents(self, agents: list[str]) -> None:
        """The live agents (and the cars that drive) from now on."""
        self.agents = agents
        self._alive_set = set(agents)
        self._active[:] = False
        self._active[[self._index[a] for a in agents]] = True

    def render(self) -> np.ndarray | None:
        """RGB uint8 (H, W, 3): the map, every car's last scan hits and its box in its own colour
        (`CAR_COLOURS`), the track's centerline when there is one."""
        if self.render_mode is None:
            warn_no_render_mode()
            return None
        if self._renderer is None:
            self._renderer = MapRenderer(self.map)
        return draw_race(self._renderer, self.world, self.track, self.lidar_params.max_range)

    def close(self) -> None:
        """Release the renderer (the env stays usable)."""
        self._renderer = None

    # ------------------------------------------------------------------ internals
    def _observations(self, agents: list[str]) -> dict[str, dict[str, np.ndarray]]:
        # One copy of each array; the agents get rows of it (the world overwrites its own).
        rows = self._rows(agents)
        scans, odom = self.world.scans[rows], self.world.odom[rows]  # copies (or sliced below)
        if isinstance(rows, slice):
            scans, odom = scans.copy(), odom.copy()
        if "imu" not in self._obs_space.spaces:
            return {a: {"scan": s, "odom": o} for a, s, o in zip(agents, scans, odom, strict=True)}
        imu = self.world.imu[rows].copy()
        return {
            a: {"scan": s, "odom": o, "imu": m}
            for a, s, o, m in zip(agents, scans, odom, imu, strict=True)
        }

    def _infos(
        self, agents: list[str], collided: np.ndarray, progress: np.ndarray, penalty: np.ndarray
    ) -> dict:
        world = self.world
        ranks = self.laps.ranks() if self.laps is not None else None
        poses, twists = world.poses.copy(), world.twists.copy()  # rows of one copy each
        fresh, times = world.fresh.tolist(), world.car_time.tolist()
        prog, pen, hit = progress.tolist(), penalty.tolist(), collided.tolist()
        index = self._index
        infos = {}
        for a in agents:
            i = index[a]
            contacts = world.touched(i) if hit[i] else ()
            info = {
                "pose": poses[i],
                "twist": twists[i],
                "collision": contacts[0] if contacts else "",
                "contacts": contacts,
                "time": times[i],
                "new_scan": fresh[i],
                "rewards": {"progress": prog[i], "collision": pen[i]},
            }
            if ranks is not None:
                info.update(self.laps.info(ranks, i))
            infos[a] = info
        return infos
