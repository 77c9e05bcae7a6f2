"""RacecarRace-v0: one agent (car 0) against scripted opponents, as a plain Gymnasium env.

``gymnasium.make("RacecarRace-v0", opponents=K, opponent_driver=...)`` races the agent's car
against ``K`` cars driven by the project's drivers (:mod:`racecar_sim.drivers`): pure pursuit on
the track's centerline or the lidar wall follower, each at its own speed. The world is a
:class:`~racecar_sim.race.env.RaceEnv` of ``K + 1`` cars, so car 0 sees the opponents in its scan
and can hit them; its spaces, reward and info are the race's for ``car_0``. Opponents that crash
stop where they are (still in the way); the episode ends when car 0 touches anything (unless
``terminate_on_collision=False``). Works without pettingzoo; SB3, ``check_env`` and ``make_vec``
take it as any Gymnasium env.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from racecar_sim.config import EnvConfig
from racecar_sim.drivers import PurePursuit, WallFollower
from racecar_sim.maps import OccupancyMap
from racecar_sim.race.env import RaceEnv
from racecar_sim.race.track import Track

__all__ = ["DRIVERS", "RacecarRaceEnv"]

DRIVERS = ("pure_pursuit", "wall_follower")
"""Names of the opponents' drivers."""

OpponentDriver = Callable[[Mapping[str, Any], np.ndarray], np.ndarray]


class RacecarRaceEnv(gym.Env):
    """Car 0 is the agent; ``opponents`` scripted cars race it (see the module doc).

    Args:
        map: as ``RacecarSim-v0``.
        opponents: number of scripted cars (0 or more).
        opponent_driver: ``"pure_pursuit"`` (on the centerline; needs a track), ``"wall_follower"``,
            a driver callable ``fn(obs, pose) -> [steer, speed]``, or a list of these, one per
            opponent.
        opponent_speeds: m/s per opponent (default 2.0, 2.4, 2.8, ... : each its own speed).
        track, config, settings: as :class:`~racecar_sim.race.env.RaceEnv`.
        render_mode: ``"rgb_array"`` or None.

    ``info`` is car 0's race info plus ``opponent_poses`` (K, 3) (rear axles, world).

    Raises:
        ValueError: a negative count, an unknown driver name, speeds not one per opponent, or
            pure pursuit without a track.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 40}  # noqa: RUF012

    def __init__(
        self,
        map: str | os.PathLike[str] | OccupancyMap | None = None,
        *,
        opponents: int = 1,
        opponent_driver: str | OpponentDriver | Sequence[str | OpponentDriver] = "pure_pursuit",
        opponent_speeds: Sequence[float] | None = None,
        track: str | os.PathLike[str] | Track | None = None,
        config: str | os.PathLike[str] | Mapping[str, Any] | EnvConfig | None = None,
        render_mode: str | None = None,
        **settings: Any,
    ) -> None:
        super().__init__()
        if not isinstance(opponents, int) or isinstance(opponents, bool) or opponents < 0:
            raise ValueError(f"opponents must be a non-negative integer, got {opponents!r}")
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
        if opponent_speeds is None:
            speeds = [2.0 + 0.4 * k for k in range(opponents)]
        else:
            speeds = [float(v) for v in opponent_speeds]
            if len(speeds) != opponents or not all(
                0 < v <= self.car_params.max_speed for v in speeds
            ):
                raise ValueError(
                    f"opponent_speeds must be {opponents} speeds in (0, {self.car_params.max_speed}] m/s, "
                    f"got {list(opponent_speeds)}"
                )
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
        if kind == "pure_pursuit":
            if self.track is None:
                raise ValueError(
                    "opponent_driver='pure_pursuit' needs a track (track=CSV or 'auto')"
                )
            return PurePursuit(self.track.points, speed=speed, loop=True, car=self.car_params)
        if kind == "wall_follower":
            return WallFollower.for_env(self.race.cars[car], speed=speed)
        raise ValueError(f"opponent_driver {kind!r} is not one of {list(DRIVERS)} or a callable")

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start a race; ``options`` as :meth:`RaceEnv.reset` (``{"poses": (K + 1, 3)}``)."""
        super().reset(seed=seed)
        if seed is None:  # a fresh stream of seeds from the env's generator
            seed = int(self.np_random.integers(2**31))
        for driver in self.drivers:
            reset = getattr(driver, "reset", None)
            if callable(reset):
                reset()
        self._obs, self._infos = self.race.reset(seed=seed, options=options)
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
        return obs["car_0"], rewards["car_0"], terms["car_0"], truncs["car_0"], self._info("car_0")

    def render(self) -> np.ndarray | None:
        """The race's frame (every car in its own colour, car 0 first colour)."""
        return self.race.render()

    def close(self) -> None:
        self.race.close()

    def _info(self, agent: str) -> dict[str, Any]:
        info = dict(self._infos[agent])
        info["opponent_poses"] = self.race.world.poses[1:].copy()
        return info
