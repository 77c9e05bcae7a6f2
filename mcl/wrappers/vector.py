"""LocalizedVectorEnv: one particle filter per car of a ``RacecarSim-v0`` vector env.

``LocalizedVectorEnv(gymnasium.make_vec("RacecarSim-v0", num_envs=N,
vectorization_mode="vector_entry_point", ...), config)`` runs, for every car, what
[`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] runs for one: predict with the car's odometry each step,
weigh and resample with its scan when it is fresh, and put the estimate into the observation, so an
agent trained on N cars acts on localized poses. The filters share one sensor model (its tables
are built once for the map and lidar) and one motion model; each car has its own particles and
its own random generator, derived from the car's reset seed exactly as the single wrapper derives
its own ([`filter_rng()`][mcl.wrappers.localization.filter_rng]). So car ``i`` localizes exactly as
``LocalizationWrapper(gymnasium.make("RacecarSim-v0", ...), config)`` reset with seed ``s + i``
(tested against Gymnasium's ``SyncVectorEnv`` over such wrappers, autoresets included).

Frames and units as the single wrapper: world frame, [x, y, theta] in metres and radians.

Observation: the vector env's dict plus ``pose_estimate`` (N, 3). Info: the vector env's plus
``localization``, a dict of (N, ...) arrays (each with its ``_key`` mask, as Gymnasium's vector
infos): ``estimate``, ``position_error``, ``heading_error``, ``n_eff``, ``update_s`` (seconds of
that car's filter update), ``corrected``, ``n_particles``, ``lost`` (bool: the car's lost flag,
[LostDetector][mcl.filter.lost.LostDetector]) and, with ``uncertainty=True``, the single wrapper's
uncertainty keys.

The cars' filters run one after another on the calling thread; each update is vectorised over its
particles (and its ray casts use numba's threads), so a step costs about N single updates.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorWrapper
from gymnasium.vector.utils import batch_space

from mcl.filter.lost import LostDetector
from mcl.filter.particle_filter import ParticleFilter
from mcl.wrappers.checks import check_wrapped, filter_start
from mcl.wrappers.localization import (
    LocalizationConfig,
    correct_with_scan,
    filter_rng,
    pose_error,
    pose_estimate_space,
    shared_models,
    start_filter,
)
from racecar_sim.settings.validation import short
from racecar_sim.vector_env import car_seeds

__all__ = ["LocalizedVectorEnv"]

_UNCERTAINTY_KEYS = ("position_sd", "heading_sd", "n_clusters", "top_weight", "ambiguous")


class LocalizedVectorEnv(VectorWrapper):
    """A particle filter per car of a ``RacecarSim-v0`` vector env (see the module docstring).

    Args:
        env: the vector env (``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``,
            i.e. [`racecar_sim.vector_env.RacecarVectorEnv`][racecar_sim.vector_env.RacecarVectorEnv]), in next-step autoreset mode.
        config: [`LocalizationConfig`][mcl.wrappers.localization.LocalizationConfig] or a mapping of its fields (the adaptive
            filter is not supported here).
        uncertainty: also report each car's uncertainty (covariance summary, clusters,
            ``ambiguous``); costs about a millisecond per car and step at 1500 particles.
        clock: seconds, the timer of ``update_s``.

    Reset options: as the single wrapper's (``init``, ``init_spread``, ``init_pose`` as one
    (3,) pose for every car or an (N, 3) array; ``filter_seed`` seeds car ``i``'s filter as
    ``seed`` would), plus the vector env's ``reset_mask``.
    """

    def __init__(
        self,
        env: gym.vector.VectorEnv,
        config: LocalizationConfig | Mapping[str, Any] | None = None,
        *,
        uncertainty: bool = False,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        check_wrapped("LocalizedVectorEnv", env, "vector", "a RacecarSim-v0 vector env")
        super().__init__(env)
        inner = env.unwrapped
        cars = getattr(inner, "envs", None)
        if not cars or not hasattr(cars[0], "lidar") or not hasattr(inner, "map"):
            raise TypeError(
                "LocalizedVectorEnv needs a RacecarSim-v0 vector env (gymnasium.make_vec(..., "
                f"vectorization_mode='vector_entry_point')); got {type(inner).__name__}"
            )
        if inner.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP) != AutoresetMode.NEXT_STEP:
            raise ValueError("LocalizedVectorEnv needs the vector env's next-step autoreset mode")
        self.map = inner.map
        self.dt = float(inner.dt)
        lidar = cars[0].lidar
        self._lidar_max_range = float(lidar.params.max_range)
        self.config: LocalizationConfig
        self.config, self.sensor_model, self.motion_model = shared_models(
            config, self.map, lidar, "LocalizedVectorEnv"
        )
        self.uncertainty = bool(uncertainty)
        self._clock = clock
        n = self.num_envs
        self.filters: list[ParticleFilter | None] = [None] * n
        self.lost_detectors = [LostDetector(self.config.lost) for _ in range(n)]
        """The lost flag of each car's filter."""
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._ended = np.zeros(n, dtype=np.bool_)
        single = spaces.Dict(
            {
                **env.single_observation_space.spaces,
                "pose_estimate": pose_estimate_space(),
            }
        )
        self.single_observation_space = single
        self.observation_space = batch_space(single, n)

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset the cars (all, or ``options["reset_mask"]``) and start their filters."""
        n = self.num_envs
        start, options = filter_start(
            "LocalizedVectorEnv", options, self.config.init, self.map, rows=n, one_for_all=True
        )
        centres = None if start.centres is None else np.broadcast_to(start.centres, (n, 3))
        seeds = car_seeds(seed if start.filter_seed is None else start.filter_seed, n)
        obs, infos = self.env.reset(seed=seed, options=options or None)  # it checks reset_mask
        mask = options.get("reset_mask")
        mask = np.ones(n, dtype=np.bool_) if mask is None else np.asarray(mask, dtype=np.bool_)
        truth = np.asarray(infos["pose"], dtype=np.float64)
        report = self._empty_report()
        estimates = self._estimates()
        for i in np.flatnonzero(mask):
            if seeds[i] is not None or self._rngs[i] is None:  # filter_seed or the reset's
                self._rngs[i] = filter_rng(seeds[i])
            centre = truth[i] if centres is None else centres[i]
            self._start(i, start.init, centre, start.spread)
            t0 = self._clock()
            n_eff = self._correct(i, obs["scan"][i])
            estimates[i] = self._pf(i).estimate()
            self._record(report, i, estimates[i], truth[i], n_eff, self._clock() - t0, True)
        self._ended[mask] = False
        return self._observe(obs, estimates), {**infos, "localization": self._finish(report, mask)}

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every car, then predict with its odometry and correct with its fresh scan."""
        unset = [i for i, pf in enumerate(self.filters) if pf is None]
        if len(unset) == self.num_envs:
            raise ResetNeeded("LocalizedVectorEnv.step: call reset() before step()")
        if unset:
            raise ResetNeeded(
                f"LocalizedVectorEnv.step: car(s) {short(unset)} were never reset (reset_mask left "
                "them out); reset them before step()"
            )
        obs, rewards, terminated, truncated, infos = self.env.step(actions)
        truth = np.asarray(infos["pose"], dtype=np.float64)
        fresh = np.asarray(infos.get("new_scan", np.ones(self.num_envs, dtype=np.bool_)))
        odom = np.asarray(obs["odom"], dtype=np.float64)
        report = self._empty_report()
        estimates = np.empty((self.num_envs, 3))  # every row is set below
        for i in range(self.num_envs):
            t0 = self._clock()
            if self._ended[i]:  # next-step autoreset: this is the car's first observation
                self._start(i, self.config.init, truth[i], None)  # as the single wrapper's reset
                n_eff, corrected = self._correct(i, obs["scan"][i]), True
            else:
                pf = self._pf(i)
                pf.predict(odom[i], self.dt)
                self.lost_detectors[i].advance(self.dt, odom[i])
                corrected = bool(fresh[i])
                n_eff = self._correct(i, obs["scan"][i]) if corrected else pf.effective_sample_size
            estimates[i] = self._pf(i).estimate()
            self._record(report, i, estimates[i], truth[i], n_eff, self._clock() - t0, corrected)
        self._ended = np.asarray(terminated) | np.asarray(truncated)
        everyone = np.ones(self.num_envs, dtype=np.bool_)
        infos = {**infos, "localization": self._finish(report, everyone)}
        return self._observe(obs, estimates), rewards, terminated, truncated, infos

    # ------------------------------------------------------------------ internals
    def _pf(self, i: int) -> ParticleFilter:
        pf = self.filters[i]
        assert pf is not None
        return pf

    def _start(self, i: int, init: str, centre: np.ndarray, spread: Any) -> None:
        """A new filter for car ``i`` (as the single wrapper's reset), on the car's generator."""
        rng = self._rngs[i]
        assert rng is not None
        self.filters[i] = start_filter(
            self.map, self.config, self.sensor_model, self.motion_model, rng, init, centre, spread
        )
        self.lost_detectors[i].restart()

    def _correct(self, i: int, scan: np.ndarray) -> float:
        return correct_with_scan(self._pf(i), scan, self._lidar_max_range, self.lost_detectors[i])

    def _estimates(self) -> np.ndarray:
        """The current estimates (N, 3); rows of cars without a filter are NaN."""
        out = np.full((self.num_envs, 3), np.nan)
        for i, pf in enumerate(self.filters):
            if pf is not None:
                out[i] = pf.estimate()
        return out

    def _empty_report(self) -> dict[str, np.ndarray]:
        n = self.num_envs
        report = {
            "estimate": np.full((n, 3), np.nan),
            "position_error": np.full(n, np.nan),
            "heading_error": np.full(n, np.nan),
            "n_eff": np.zeros(n),
            "update_s": np.zeros(n),
            "corrected": np.zeros(n, dtype=np.bool_),
            "n_particles": np.zeros(n, dtype=np.int64),
            "lost": np.zeros(n, dtype=np.bool_),
        }
        if self.uncertainty:
            report.update(
                covariance=np.full((n, 3, 3), np.nan),
                position_sd=np.full(n, np.nan),
                heading_sd=np.full(n, np.nan),
                n_clusters=np.zeros(n, dtype=np.int64),
                top_weight=np.zeros(n),
                ambiguous=np.zeros(n, dtype=np.bool_),
            )
        return report

    def _record(
        self,
        report: dict[str, np.ndarray],
        i: int,
        estimate: np.ndarray,
        truth: np.ndarray,
        n_eff: float,
        update_s: float,
        corrected: bool,
    ) -> None:
        pf = self._pf(i)
        report["estimate"][i] = estimate
        report["position_error"][i], report["heading_error"][i] = pose_error(estimate, truth)
        report["n_eff"][i] = n_eff
        report["update_s"][i] = update_s
        report["corrected"][i] = corrected
        report["n_particles"][i] = pf.n_particles
        report["lost"][i] = self.lost_detectors[i].lost
        if self.uncertainty:
            unc = pf.uncertainty()
            report["covariance"][i] = unc.covariance
            for key in _UNCERTAINTY_KEYS:
                report[key][i] = getattr(unc, key)

    @staticmethod
    def _finish(report: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, np.ndarray]:
        """The report with Gymnasium's ``_key`` masks (True where the car reported)."""
        return {**report, **{f"_{k}": mask.copy() for k in report}}

    @staticmethod
    def _observe(obs: dict[str, np.ndarray], estimates: np.ndarray) -> dict[str, np.ndarray]:
        return {**obs, "pose_estimate": estimates.copy()}
