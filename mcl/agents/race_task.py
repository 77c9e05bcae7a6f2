"""The lap task against scripted opponents: :class:`~mcl.agents.lap_env.LapTask` on ``RacecarRace-v0``.

``LapTaskConfig(opponents=K)`` puts the agent's car (car 0) in a
:class:`racecar_sim.race.single.RacecarRaceEnv` with ``K`` scripted opponents (pure pursuit on
the centerline or the wall follower, each at its own speed). The task is the lap task's, on the
race's track (the map's centerline), with these differences:

* **start**: the race's staggered grid (:func:`racecar_sim.race.grid.start_grid`) with the agent
  in the *last* slot and opponent ``k`` in slot ``k - 1`` (with the default speeds the slowest,
  2.0 m/s, starts on pole and the fastest just ahead of the agent). The grid stands behind the start line when ``start_s`` is 0 (the tests), or behind a
  uniformly drawn point of the track when ``start_s`` is None (training: every part of the track,
  with the pack ahead). Drawn points keep the grid off the half-lap point, where the race order
  wraps (:mod:`racecar_sim.race.laps`), and a point where the track has no room for the
  grid is drawn again.
* **reward**: progress minus the penalty on a step with *any* contact, wall or car (and in
  training the episode ends there, as at a wall).
* **observation**: the same 57 numbers; the opponents are in the scan (every lidar sees the
  other cars' boxes), nowhere else.
* **info**: ``lap["laps"]`` and ``lap["lap_times"]`` are the race's (a lap is a forward crossing
  of the start line, the first timed from the start), and ``race`` holds the episode's counts
  (:class:`~mcl.agents.race_tally.RaceTally`: rank, overtakes, overtaken, wall and car contacts).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from mcl.agents.lap_env import LapTask, LapTaskConfig
from mcl.agents.race_tally import RaceTally
from racecar_sim.race.grid import start_grid
from racecar_sim.race.single import RacecarRaceEnv

__all__ = ["RaceLapTask", "make_race_lap_env"]

_GRID_GAP = 0.3  # metres between cars on the grid (start_grid's default)
_GRID_DRAWS = 50  # random grid places tried before giving up


class RaceLapTask(LapTask):
    """The lap task on a :class:`RacecarRaceEnv` (see the module doc).

    Raises:
        ValueError: the race has no track (a map with no known loop and no track given).
    """

    pose_option = "poses"

    def __init__(self, env: gym.Env, config: LapTaskConfig) -> None:
        race = env.unwrapped
        if not isinstance(race, RacecarRaceEnv):
            raise ValueError(f"RaceLapTask needs a RacecarRaceEnv, got {type(race).__name__}")
        if race.track is None:
            raise ValueError(
                f"map {config.map!r}: a race needs a track (a bundled loop map or track=CSV)"
            )
        super().__init__(env, config, track=race.track)
        self.n_cars = len(race.drivers) + 1
        self.tally = RaceTally()
        self._race_laps: tuple[int, list[float]] = (0, [])

    def _start_pose(self) -> list[list[float]]:
        """(K + 1, 3) rear-axle world poses: the grid with the agent (row 0) in the last slot."""
        cfg, track, car = self.config, self.track, self._car
        is_free = self.env.unwrapped.race.cars[0].physics.pose_is_free
        order = [self.n_cars - 1, *range(self.n_cars - 1)]
        if cfg.start_s is not None:
            grid = start_grid(track, self.n_cars, car, is_free, gap=_GRID_GAP, at=cfg.start_s)
            return grid[order].tolist()
        length = track.length
        span = self.n_cars * (car.length + _GRID_GAP) + 1.0  # metres of track the grid covers
        for _ in range(_GRID_DRAWS):  # a drawn point where the track is too narrow: draw again
            at = self._rng.uniform(0.0, length - span)
            if at >= length / 2:  # keep [at - span, at] clear of the half-lap wrap
                at += span
            try:
                grid = start_grid(track, self.n_cars, car, is_free, gap=_GRID_GAP, at=at)
            except ValueError:
                continue
            return grid[order].tolist()
        raise ValueError(f"no room for a grid of {self.n_cars} cars in {_GRID_DRAWS} draws")

    def begin(self, info: dict[str, Any]) -> None:
        """The lap task's bookkeeping, and the race's counts from the reset's info."""
        super().begin(info)
        self.tally.begin(info)
        self._race_laps = (int(info["lap"]), list(info["lap_times"]))

    def track_step(self, info: dict[str, Any]) -> float:
        """The lap task's reward (any contact costs the penalty); the step counted."""
        reward = super().track_step(info)
        self.tally.update(info)
        self._race_laps = (int(info["lap"]), list(info["lap_times"]))
        return reward

    def add_lap_info(self, info: dict[str, Any]) -> dict[str, Any]:
        """``info`` with ``lap`` (laps and lap times the race's) and ``race`` (the counts)."""
        out = super().add_lap_info(info)
        laps, times = self._race_laps
        out["lap"] = {**out["lap"], "laps": laps, "lap_times": times}
        out["race"] = {**self.tally.counts(), "opponents": self.n_cars - 1}
        return out


def make_race_lap_env(config: LapTaskConfig, *, render_mode: str | None = None) -> gym.Env:
    """``RacecarRace-v0`` (``config.opponents`` scripted cars) -> :class:`RaceLapTask` ->
    ``TimeLimit``."""
    if config.opponents < 1:
        raise ValueError(
            "make_race_lap_env: the config has no opponents (use make_task_env or make_lap_env)"
        )
    settings = {"terminate_on_collision": config.terminate_on_collision, **dict(config.env)}
    env: gym.Env = RacecarRaceEnv(
        config.map,
        opponents=config.opponents,
        opponent_driver=config.opponent_driver,
        opponent_speeds=config.opponent_speeds,
        render_mode=render_mode,
        **settings,
    )
    dt = env.race.dt
    env = RaceLapTask(env, config)
    return gym.wrappers.TimeLimit(env, max_episode_steps=max(1, round(config.episode_seconds / dt)))
