"""LocalizedRaceEnv: one particle filter per car of a race (a PettingZoo ``ParallelEnv``).

``LocalizedRaceEnv(racecar_sim.RaceEnv(map=..., n_cars=N), config)`` runs, for every agent, what
[`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] runs for one car: predict with the car's odometry each
step, weigh and resample with its scan when it is fresh, and put the estimate into its
observation. The other cars are in every scan and never in the filter's map, so each filter
localizes among opponents (beam skipping, ``SensorModelParams.beam_skip``, is what keeps it
locked on; `mcl.filter.beam_skip`). The filters share one sensor model (its tables built once for
the map and lidar) and one motion model, as [`LocalizedVectorEnv`][mcl.wrappers.vector.LocalizedVectorEnv]'s do;
each car has its own particles and its own generator, derived from the car's reset seed (``s + i``
for car ``i``, the race's own seeding) as the single wrapper derives its own
([`filter_rng()`][mcl.wrappers.localization.filter_rng]).

Observation (per agent): the race's dict plus ``pose_estimate`` [x m, y m, theta rad] (world).
Info (per agent): the race's plus ``localization``, the single wrapper's report
([`localization_report()`][mcl.wrappers.localization.localization_report]: estimate, position and heading error against
the car's true ``pose``, n_eff, update_s, corrected, uncertainty, ``lost``: the car's
[LostDetector][mcl.filter.lost.LostDetector] flag).

Reset options (the others go to the race): ``init`` (``"pose"`` or ``"global"``), ``init_spread``
(standard deviations x m, y m, theta rad, or one number), ``init_pose`` (an (N, 3) array of
centres, one per car, instead of the true start poses, each in a free cell of the map),
``filter_seed`` (a non-negative integer: the cars' filters are seeded from it as from the reset's
``seed``, so the same race is localized with another draw of their random numbers). They
are checked before the race is reset ([filter_start][mcl.wrappers.checks.filter_start]).

The filters run one after another on the calling thread (each vectorised over its particles).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from pettingzoo.utils.wrappers import BaseParallelWrapper

from mcl.filter.lost import LostDetector
from mcl.filter.particle_filter import ParticleFilter
from mcl.wrappers.checks import check_wrapped, filter_start
from mcl.wrappers.localization import (
    LocalizationConfig,
    correct_with_scan,
    filter_rng,
    localization_report,
    pose_estimate_space,
    shared_models,
    start_filter,
)
from racecar_sim.settings.validation import short
from racecar_sim.vector_env import car_seeds

__all__ = ["LocalizedRaceEnv"]


class LocalizedRaceEnv(BaseParallelWrapper):
    """A particle filter per agent of a race (see the module docstring).

    Args:
        env: a [`racecar_sim.RaceEnv`][racecar_sim.RaceEnv] (or a wrapper of one that keeps its observations).
        config: [`LocalizationConfig`][mcl.wrappers.localization.LocalizationConfig] or a mapping of its fields (the
            adaptive filter is not supported here).
        agents: the agents to localize (default: every one; an empty list localizes none); the
            others' observations and infos pass through unchanged.
        clock: seconds, the timer of ``update_s``; a fixed clock makes infos reproducible.
    """

    def __init__(
        self,
        env: Any,
        config: LocalizationConfig | Mapping[str, Any] | None = None,
        *,
        agents: list[str] | None = None,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        check_wrapped("LocalizedRaceEnv", env, "race", "a racecar_sim.RaceEnv")
        super().__init__(env)
        if agents is not None and (
            not isinstance(agents, list | tuple) or not all(isinstance(a, str) for a in agents)
        ):
            raise ValueError(
                f"LocalizedRaceEnv agents must be a list of agent names (str), got {short(agents)}"
            )
        localized = list(env.possible_agents) if agents is None else list(agents)
        unknown = set(localized) - set(env.possible_agents)
        if unknown or len(set(localized)) < len(localized):
            raise ValueError(
                f"LocalizedRaceEnv agents {short(localized)} must be distinct agents of the race, "
                f"{short(list(env.possible_agents), 80)}"
            )
        self.localized: tuple[str, ...] = tuple(localized)
        """The agents with a filter."""
        inner = env.unwrapped
        cars = getattr(inner, "cars", None)
        if not cars or not hasattr(cars[0], "lidar") or not hasattr(inner, "map"):
            raise TypeError(
                f"LocalizedRaceEnv needs a racecar_sim.RaceEnv; got {type(inner).__name__}"
            )
        self.map = inner.map
        self.dt = float(inner.dt)
        lidar = cars[0].lidar
        self._lidar_max_range = float(lidar.params.max_range)
        self.config: LocalizationConfig
        self.config, self.sensor_model, self.motion_model = shared_models(
            config, self.map, lidar, "LocalizedRaceEnv"
        )
        self._clock = clock
        self._started = False  # whether a reset went through
        self.filters: dict[str, ParticleFilter] = {}
        self.lost_detectors: dict[str, LostDetector] = {}
        """The lost flag of each localized agent's filter."""
        self._rngs: dict[str, np.random.Generator] = {}
        self._spaces = {
            agent: spaces.Dict(
                {**env.observation_space(agent).spaces, "pose_estimate": pose_estimate_space()}
            )
            if agent in self.localized
            else env.observation_space(agent)
            for agent in env.possible_agents
        }

    def observation_space(self, agent: str) -> spaces.Space:
        """The race's observation space of ``agent``, plus ``pose_estimate`` when localized."""
        return self._spaces[agent]

    def reset(
        self, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, dict[str, Any]], dict[str, dict[str, Any]]]:
        """Reset the race and start every car's filter (module docstring for the options)."""
        agents = list(self.env.possible_agents)
        start, options = filter_start(
            "LocalizedRaceEnv", options, self.config.init, self.map, rows=len(agents)
        )
        self._started = False  # until this reset goes through
        obs, infos = self.env.reset(seed=seed, options=options or None)
        seeds = car_seeds(seed if start.filter_seed is None else start.filter_seed, len(agents))
        out_obs, out_infos = dict(obs), dict(infos)
        for i, agent in enumerate(agents):
            if agent not in obs or agent not in self.localized:
                continue
            if seeds[i] is not None or agent not in self._rngs:
                self._rngs[agent] = filter_rng(seeds[i])
            truth = np.asarray(infos[agent]["pose"], dtype=np.float64)
            t0 = self._clock()
            pf = start_filter(
                self.map, self.config, self.sensor_model, self.motion_model, self._rngs[agent],
                start.init, truth if start.centres is None else start.centres[i], start.spread,
            )  # fmt: skip
            self.filters[agent] = pf
            detector = self.lost_detectors[agent] = LostDetector(self.config.lost)
            n_eff = correct_with_scan(pf, obs[agent]["scan"], self._lidar_max_range, detector)
            out_obs[agent], out_infos[agent] = self._report(
                agent, obs[agent], infos[agent], n_eff, self._clock() - t0, True
            )
        self._started = True
        return out_obs, out_infos

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """Step the race, then predict and correct every car that observed."""
        if not self._started:
            raise ResetNeeded("LocalizedRaceEnv.step: call reset() before step()")
        obs, rewards, terminations, truncations, infos = self.env.step(actions)
        out_obs, out_infos = dict(obs), dict(infos)
        for agent, o in obs.items():
            pf = self.filters.get(agent)
            if pf is None:
                continue
            t0 = self._clock()
            pf.predict(np.asarray(o["odom"], dtype=np.float64), self.dt)
            detector = self.lost_detectors[agent]
            detector.advance(self.dt, o["odom"])
            fresh = bool(infos[agent].get("new_scan", True))
            n_eff = (
                correct_with_scan(pf, o["scan"], self._lidar_max_range, detector)
                if fresh
                else pf.effective_sample_size
            )
            out_obs[agent], out_infos[agent] = self._report(
                agent, o, infos[agent], n_eff, self._clock() - t0, fresh
            )
        return out_obs, rewards, terminations, truncations, out_infos

    def _report(
        self,
        agent: str,
        obs: dict[str, Any],
        info: dict[str, Any],
        n_eff: float,
        update_s: float,
        fresh: bool,
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        pf = self.filters[agent]
        estimate = pf.estimate()
        truth = np.asarray(info["pose"], dtype=np.float64)
        lost = self.lost_detectors[agent].lost
        loc = localization_report(pf, estimate, truth, n_eff, update_s, fresh, lost)
        return {**obs, "pose_estimate": estimate.copy()}, {**info, "localization": loc}
