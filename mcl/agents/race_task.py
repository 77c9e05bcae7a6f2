"""The lap task against scripted opponents: [`LapTask`][mcl.agents.lap_env.LapTask] on ``RacecarRace-v0``.

``LapTaskConfig(opponents=K)`` puts the agent's car (car 0) in a
[`racecar_sim.race.single.RacecarRaceEnv`][racecar_sim.race.single.RacecarRaceEnv] with ``K`` scripted opponents (by default racing
drivers that know the other cars; pure pursuit on the centerline blind to them, or the wall
follower; each at its own speed). The task is the lap task's, on the
race's track (the map's centerline), with these differences:

* **start**: the race's grid ([grid_at][racecar_sim.race.single.RacecarRaceEnv.grid_at]: single
  file on the centerline, the opponents slowest first on pole, the agent in the *last* slot, so
  with the default speeds the fastest opponent starts just ahead of the agent). The grid stands
  behind the start line when ``start_s`` is 0 (the tests), or behind a uniformly drawn point of
  the track when ``start_s`` is None (training: every part of the track, with the pack ahead).
  Drawn points keep the grid off the half-lap point, where the race order
  wraps (`racecar_sim.world.laps`), and a point where the track has no room for the
  grid is drawn again.
* **reward**: progress minus the penalty on a step with *any* contact, wall or car (and in
  training the episode ends there, as at a wall).
* **observation**: the same 57 numbers; the opponents are in the scan (every lidar sees the
  other cars' boxes), nowhere else.
* **info**: ``lap["laps"]`` and ``lap["lap_times"]`` are the race's (a lap is a forward crossing
  of the start line, the first timed from the start), and ``race`` holds the episode's counts
  ([`RaceTally`][mcl.agents.race_tally.RaceTally]: rank, overtakes, overtaken, wall and car contacts).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from mcl.agents.lap_env import LapTask, LapTaskConfig
from mcl.agents.race_tally import RaceTally
from racecar_sim.race.single import RacecarRaceEnv

__all__ = ["RaceLapTask", "make_race_lap_env"]

_GRID_GAP = 0.3  # metres between cars on the grid (start_grid's default)
_GRID_DRAWS = 50  # random grid places tried before giving up


class RaceLapTask(LapTask):
    """The lap task on a `RacecarRaceEnv` (see the module doc).

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
        """(K + 1, 3) rear-axle world poses: the race's single-file grid (the agent last) behind
        ``start_s``, or behind a drawn point of the track."""
        cfg, track, car = self.config, self.track, self._car
        race = self.env.unwrapped
        if cfg.start_s is not None:
            return race.grid_at(cfg.start_s).tolist()
        length = track.length
        span = self.n_cars * (car.length + _GRID_GAP) + 1.0  # metres of track the grid covers
        for _ in range(_GRID_DRAWS):  # a drawn point where the track is too narrow: draw again
            at = self._rng.uniform(0.0, length - span)
            if at >= length / 2:  # keep [at - span, at] clear of the half-lap wrap
                at += span
            try:
                return race.grid_at(at).tolist()
            except ValueError:
                continue
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
    """``RacecarRace-v0`` (``config.opponents`` scripted cars) -> `RaceLapTask` ->
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
