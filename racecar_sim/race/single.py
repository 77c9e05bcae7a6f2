"""RacecarRace-v0: one agent (car 0) against scripted opponents, as a plain Gymnasium env.

``gymnasium.make("RacecarRace-v0", opponents=K, opponent_driver=...)`` races the agent's car
against ``K`` scripted cars, each at its own speed: by default racing drivers that know the
other cars (they follow at a safe gap, pass where the track is wide enough and give way; see
[RacingDriver][racecar_sim.race.racing_driver.RacingDriver]), or the project's drivers blind to
them (pure pursuit on the centerline, the lidar wall follower). The grid puts the opponents
slowest first, on pole, and the agent last: the faster cars catch the slower ones and have to
pass them. The world is a [RaceEnv][racecar_sim.race.env.RaceEnv] of ``K + 1`` cars, so car 0
sees the opponents in its scan and can hit them; its spaces, reward and info are the race's for
``car_0``. Opponents that crash stop where they are (still in the way); the episode ends when
car 0 touches anything (unless ``terminate_on_collision=False``). Works without pettingzoo; SB3,
``check_env`` and ``make_vec`` take it as any Gymnasium env.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from racecar_sim.drivers import PurePursuit, WallFollower
from racecar_sim.maps import OccupancyMap
from racecar_sim.race.env import RaceEnv
from racecar_sim.race.grid import start_grid
from racecar_sim.race.racing_driver import RacingDriver
from racecar_sim.race.racing_rules import RacingRules
from racecar_sim.race.traffic import Traffic
from racecar_sim.settings.config import EnvConfig
from racecar_sim.world.track import Track, with_widths

__all__ = ["DRIVERS", "RacecarRaceEnv"]

DRIVERS = ("racing", "pure_pursuit", "wall_follower")
"""Names of the opponents' drivers: ``"racing"`` knows the other cars
([RacingDriver][racecar_sim.race.racing_driver.RacingDriver]); ``"pure_pursuit"`` drives the
centerline blind to them; ``"wall_follower"`` sees them only as lidar hits."""

OpponentDriver = Callable[[Mapping[str, Any], np.ndarray], np.ndarray]


class RacecarRaceEnv(gym.Env):
    """Car 0 is the agent; ``opponents`` scripted cars race it (see the module doc).

    Args:
        map: as ``RacecarSim-v0``.
        opponents: number of scripted cars (0 or more).
        opponent_driver: ``"racing"`` (the default: knows the other cars; needs a track),
            ``"pure_pursuit"`` (on the centerline, blind to the other cars; needs a track),
            ``"wall_follower"``, a driver callable ``fn(obs, pose) -> [steer, speed]``, or a list
            of these, one per opponent.
        opponent_speeds: m/s per opponent (default 2.0, 2.4, 2.8, ... : each its own speed).
            The grid puts the opponents slowest first (pole) and the agent last.
        opponent_rules: the ``"racing"`` drivers' numbers
            ([RacingRules][racecar_sim.race.racing_rules.RacingRules] or a mapping of its fields).
        track: as [RaceEnv][racecar_sim.race.env.RaceEnv].
        config: as [RaceEnv][racecar_sim.race.env.RaceEnv].
        settings: as [RaceEnv][racecar_sim.race.env.RaceEnv] (every car's).
        render_mode: ``"rgb_array"`` or None.

    ``info`` is car 0's race info plus ``opponent_poses`` (K, 3) (rear axles, world).
    ``traffic`` is the race in the track's frame, which the racing opponents read; a
    ``RacingDriver(env.traffic, 0, speed)`` drives car 0 the same way.

    Raises:
        ValueError: a negative count, an unknown driver name, speeds not one per opponent, or
            pure pursuit or racing without a track.

    ## Version History
    * v0 (racecar-sim 0.2): car 0 against scripted opponents (``RacecarRace-v0``).
    * 0.3: the track as in [`RaceEnv`][racecar_sim.race.env.RaceEnv] (bundled CSVs, ``"auto"``
      on any map whose free space runs round an island).
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 40}  # noqa: RUF012

    def __init__(
        self,
        map: str | os.PathLike[str] | OccupancyMap | None = None,
        *,
        opponents: int = 1,
        opponent_driver: str | OpponentDriver | Sequence[str | OpponentDriver] = "racing",
        opponent_speeds: Sequence[float] | None = None,
        opponent_rules: RacingRules | Mapping[str, Any] | None = None,
        track: str | os.PathLike[str] | Track | None = None,
        config: str | os.PathLike[str] | Mapping[str, Any] | EnvConfig | None = None,
        render_mode: str | None = None,
        **settings: Any,
    ) -> None:
        super().__init__()
        if not isinstance(opponents, int) or isinstance(opponents, bool) or opponents < 0:
            raise ValueError(f"opponents must be a non-negative integer, got {opponents!r}")
        if opponent_speeds is None:
            speeds = [2.0 + 0.4 * k for k in range(opponents)]
        else:
            try:
                speeds = [float(v) for v in opponent_speeds]
            except (TypeError, ValueError):
                speeds = []
            if len(speeds) != opponents:
                speeds = [math.nan]  # refused below, with the car's top speed in the message
        self.race = RaceEnv(map, n_cars=opponents + 1, track=track, config=config,
                            render_mode=render_mode, **settings)  # fmt: skip
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.race.metadata["render_fps"]}
        self.observation_space = self.race.observation_space("car_0")
        self.action_space = self.race.action_space("car_0")
        self.car_params = self.race.car_params
        self.lidar_params = self.race.lidar_params
        self.map = self.race.map
        self.track = self.race.track
        top = self.car_params.max_speed
        if len(speeds) != opponents or not all(0 < v <= top for v in speeds):
            raise ValueError(
                f"opponent_speeds must be {opponents} speeds in (0, {top}] m/s, "
                f"got {opponent_speeds!r}"
            )
        self.traffic: Traffic | None = None
        """Where every car is on the track, for the ``"racing"`` opponents (None without a
        track); updated after every reset and step."""
        if self.track is not None:
            self.traffic = Traffic(with_widths(self.track, self.map), opponents + 1,
                                   self.car_params)  # fmt: skip
        self._rules = opponent_rules
        # the grid: single file, the opponents slowest first (on pole), the agent last
        self.grid_order: tuple[int, ...] = (
            *(1 + k for k in sorted(range(opponents), key=lambda k: speeds[k])), 0
        )
        """The cars from pole backwards on the start grid."""
        self.grid: np.ndarray | None = self.grid_at(0.0) if self.track is not None else None
        """(K + 1, 3) the cars' start poses (rear axles, world) when reset gives none: the
        grid behind the start line (None without a track)."""
        kinds = (
            list(opponent_driver)
            if isinstance(opponent_driver, list | tuple)
            else [opponent_driver] * opponents
        )
        if len(kinds) != opponents:
            raise ValueError(
                f"opponent_driver: {len(kinds)} drivers given for {opponents} opponents"
            )
        self.drivers: list[OpponentDriver] = [
            self._driver(kind, speed, k + 1)
            for k, (kind, speed) in enumerate(zip(kinds, speeds, strict=True))
        ]
        self._obs: dict[str, dict[str, np.ndarray]] = {}
        self._infos: dict[str, dict[str, Any]] = {}

    def _driver(self, kind: str | OpponentDriver, speed: float, car: int) -> OpponentDriver:
        if callable(kind):
            return kind
        if kind == "racing":
            if self.traffic is None:
                raise ValueError("opponent_driver='racing' needs a track (track=CSV or 'auto')")
            return RacingDriver(self.traffic, car, speed=speed, rules=self._rules)
        if kind == "pure_pursuit":
            if self.track is None:
                raise ValueError(
                    "opponent_driver='pure_pursuit' needs a track (track=CSV or 'auto')"
                )
            return PurePursuit(self.track.points, speed=speed, loop=True, car=self.car_params)
        if kind == "wall_follower":
            return WallFollower.for_env(self.race.cars[car], speed=speed)
        raise ValueError(f"opponent_driver {kind!r} is not one of {list(DRIVERS)} or a callable")

    def grid_at(self, at: float) -> np.ndarray:
        """(K + 1, 3) rear-axle world poses, by car: the start grid behind arc length ``at``
        (metres) of the track, single file on the centerline in ``grid_order``, one car length
        plus 0.3 m apart ([start_grid][racecar_sim.race.grid.start_grid] without stagger).

        Single file, because a grid two abreast of cars at different speeds leaves as a
        convoy two abreast, which on a track two cars wide nobody can pass.

        Raises:
            ValueError: no track, or a slot where the car does not fit on the centerline.
        """
        if self.track is None:
            raise ValueError("RacecarRaceEnv.grid_at: the race has no track")
        is_free = self.race.cars[0].physics.pose_is_free
        poses = start_grid(self.track, len(self.grid_order), self.car_params, is_free,
                           stagger=0.0, at=at)  # fmt: skip
        return poses[np.argsort(self.grid_order)]

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start a race; ``options`` as [RaceEnv.reset][racecar_sim.race.env.RaceEnv.reset]
        (``{"poses": (K + 1, 3)}``; without poses the cars stand on ``grid``)."""
        super().reset(seed=seed)
        if seed is None:  # a fresh stream of seeds from the env's generator
            seed = int(self.np_random.integers(2**31))
        for driver in self.drivers:
            reset = getattr(driver, "reset", None)
            if callable(reset):
                reset()
        if self.grid is not None and not (options and "poses" in options):
            options = {**(options or {}), "poses": self.grid}
        self._obs, self._infos = self.race.reset(seed=seed, options=options)
        if self.traffic is not None:
            self.traffic.reset(self.race.poses)
        return self._obs["car_0"], self._info("car_0")

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Drive car 0 by ``action`` = [steer rad, speed m/s] and the opponents by their drivers."""
        race = self.race
        if "car_0" not in race.agents:
            raise RuntimeError("car 0's episode has ended; call reset()")
        actions: dict[str, Any] = {"car_0": action}
        for k, driver in enumerate(self.drivers, start=1):
            agent = f"car_{k}"
            if agent in race.agents:
                actions[agent] = driver(self._obs[agent], self._infos[agent]["pose"])
        obs, rewards, terms, truncs, infos = race.step(actions)
        self._obs.update(obs)
        self._infos.update(infos)
        if self.traffic is not None:
            self.traffic.update(self.race.poses, race.world.time)
        return obs["car_0"], rewards["car_0"], terms["car_0"], truncs["car_0"], self._info("car_0")

    def render(self) -> np.ndarray | None:
        """The race's frame (every car in its own colour, car 0 first colour)."""
        return self.race.render()

    def close(self) -> None:
        self.race.close()

    @property
    def car_infos(self) -> dict[str, dict[str, Any]]:
        """The race info of every car at the last reset or step, by agent (``"car_0"`` ...);
        a car whose episode ended keeps its last."""
        return {agent: dict(info) for agent, info in self._infos.items()}

    def _info(self, agent: str) -> dict[str, Any]:
        info = dict(self._infos[agent])
        info["opponent_poses"] = self.race.world.poses[1:].copy()
        return info
