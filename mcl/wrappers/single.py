"""LocalizationWrapper: Monte Carlo Localization in the loop of a ``RacecarSim-v0`` env.

Each episode the wrapper starts a particle filter (around the true start pose, or spread over the
whole map), then on every step moves the particles by the step's odometry and, when the step
carries a fresh scan (``info["new_scan"]``), weighs and resamples them by that scan. The estimate
goes into the observation so an agent can drive on it, the error against the truth into ``info``
and, optionally, into a CSV log (`mcl.wrappers.error_log`).

Frames and units: world frame of the map; poses [x, y, theta] of the rear axle in metres and
radians (theta in [-pi, pi)); times in seconds.

Randomness: the filter never draws from ``env.np_random`` (that would change the simulated sensor
noise whenever the filter changes). It has its own ``numpy.random.Generator``, derived from the
reset seed by ``numpy.random.SeedSequence(seed).spawn``: the same seed gives the same true
trajectory and the same sensor noise whatever the filter's settings, and the same filter draws.
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from mcl.filter.adaptive import AdaptiveParticleFilter
from mcl.filter.lost import LostDetector
from mcl.filter.motion_model import MotionModel
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.sensor_model import SensorModel
from mcl.wrappers.checks import check_filter_map, check_wrapped, filter_start
from mcl.wrappers.error_log import ErrorLogWriter
from mcl.wrappers.hooks import StepHook, StepHooks, step_record
from mcl.wrappers.localization import (
    FilterFactory,
    LocalizationConfig,
    as_localization_config,
    correct_with_scan,
    filter_rng,
    localization_report,
    pose_estimate_space,
    sensor_model_for_lidar,
)
from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.render import MapRenderer

__all__ = ["LocalizationWrapper", "car_of"]


def car_of(inner: Any) -> Any:
    """The localized car of an unwrapped env: the env itself for ``RacecarSim-v0`` (it has
    ``map``, ``lidar`` and ``dt``), car 0 of the race for ``RacecarRace-v0`` (``inner.race``).

    Raises:
        TypeError: the env is neither.
    """
    if all(hasattr(inner, a) for a in ("map", "lidar", "dt")):
        return inner
    race = getattr(inner, "race", None)
    cars = getattr(race, "cars", None)
    if cars and all(hasattr(cars[0], a) for a in ("map", "lidar", "dt")):
        return cars[0]
    raise TypeError(
        f"LocalizationWrapper needs a RacecarSim-v0 or RacecarRace-v0 env; {type(inner).__name__} "
        "has no map, lidar and dt (nor a race whose car 0 has them)"
    )


class LocalizationWrapper(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Runs a particle filter on a ``RacecarSim-v0`` env's odometry and scans (module docstring).

    Args:
        env: a ``RacecarSim-v0`` env (``gymnasium.make`` or [`racecar_sim.env.RacecarEnv`][racecar_sim.env.RacecarEnv],
            with any wrappers that keep its observations), or ``RacecarRace-v0`` (the filter
            localizes car 0 among the opponents; `car_of()`).
        config: `LocalizationConfig` or a mapping of its fields.
        log_path: when given, a CSV error log (`mcl.wrappers.error_log`) is written there, one row per
            step, flushed as it goes; episodes follow one another in the same file, ``step``
            restarting at 1.
        filter_factory: builds the filter (default `ParticleFilter`).
        sensor_model: a ready sensor model to share between wrappers on the same map and lidar
            (it must use the env's beam angles and mount offset); built from ``config`` when None.
        clock: seconds, the timer of ``update_s``. Wall time differs from run to run; a fixed
            clock (``lambda: 0.0``) makes the infos reproducible bit for bit (``check_env``).
        filter_map: the map the *filter* holds (bundled name, YAML path or OccupancyMap) when it
            differs from the world the env simulates (e.g. the world edited since the map was
            drawn); None = the env's map. Both must share the world frame; size and resolution
            may differ, but at least half of the world's free space must be free on it
            ([MIN_FILTER_MAP_COVER][mcl.wrappers.checks.MIN_FILTER_MAP_COVER]).
        on_step: a step hook or a list of them ([`mcl.wrappers.hooks`][mcl.wrappers.hooks]):
            each is called as ``hook(record)`` with the
            [`StepRecord`][mcl.wrappers.hooks.StepRecord] of the reset (step 0) and of every step,
            after the filter's update and the error log's row. More can be added with
            [`add_step_hook()`][mcl.wrappers.single.LocalizationWrapper.add_step_hook]. The bag
            recorder and the Foxglove live view attach this way
            ([`DriveRecorder`][mcl.io.bag_writer.DriveRecorder], streaming to a server from
            [`start_live()`][mcl.io.bag_writer.start_live] when given one); the wrapper neither
            closes nor owns its hooks.

    Observation: the env's dict plus ``pose_estimate``, ``Box(-inf, inf, (3,), float64)``, the
    estimate [x, y, theta] (world, metres, radians in [-pi, pi)).

    Info: the env's plus ``localization``: ``estimate`` (3,), ``position_error`` (m),
    ``heading_error`` (rad, estimate minus truth wrapped to [-pi, pi)), ``n_eff`` (effective
    sample size after this step's weight update, before resampling), ``update_s`` (s of wall time
    of this step's filter update), ``corrected`` (whether the step carried a fresh scan), and how
    far to trust the estimate ([`mcl.filter.particle_filter.ParticleFilter.uncertainty()`][mcl.filter.particle_filter.ParticleFilter.uncertainty]):
    ``n_particles``, ``covariance`` (3, 3) (metres, radians), ``position_sd`` (m, largest axis),
    ``heading_sd`` (rad), ``n_clusters`` (clusters of the cloud with a noticeable weight),
    ``top_weight`` (weight of the heaviest cluster) and ``ambiguous`` (True when the cloud does not
    pin down one pose: two heavy clusters or a large spread, e.g. in a featureless corridor),
    and ``lost`` (True when the estimate should not be trusted: the scan no longer fits the map
    from it, or the cloud is spread; [LostDetector][mcl.filter.lost.LostDetector], settings
    ``config.lost``; while it is up the filter searches the map for the car).

    Reset options (the others go to the env): ``init`` (``"pose"`` or ``"global"``, this episode),
    ``init_spread`` (standard deviations x m, y m, theta rad around the start, or one number),
    ``init_pose`` (centre of the initial guess instead of the true start pose; it must lie in a
    free cell of the filter's map), ``filter_seed`` (a non-negative integer: the filter's random
    generator is seeded from it instead of from ``seed``, so the same drive is localized with
    another draw of the filter's motion noise and resampling). They are checked before the env is reset
    ([filter_start][mcl.wrappers.checks.filter_start]).
    """

    def __init__(
        self,
        env: gym.Env,
        config: LocalizationConfig | Mapping[str, Any] | None = None,
        *,
        log_path: str | os.PathLike[str] | None = None,
        filter_factory: FilterFactory | None = None,
        sensor_model: SensorModel | None = None,
        clock: Callable[[], float] = time.perf_counter,
        filter_map: str | os.PathLike[str] | OccupancyMap | None = None,
        on_step: StepHook | Sequence[StepHook] | None = None,
    ) -> None:
        # not on_step: Gymnasium deep-copies these, and a hook is a live object (an open bag)
        gym.utils.RecordConstructorArgs.__init__(
            self, config=config, log_path=log_path, filter_factory=filter_factory, clock=clock,
            filter_map=filter_map,
        )  # fmt: skip
        self._hooks = StepHooks(on_step)  # checked first: a hook that is no callable fails fast
        check_wrapped("LocalizationWrapper", env, "single",
                      "a RacecarSim-v0 or RacecarRace-v0 env (a gymnasium.Env)")  # fmt: skip
        gym.Wrapper.__init__(self, env)
        inner = env.unwrapped
        car = car_of(inner)
        if not isinstance(env.observation_space, spaces.Dict) or not {"scan", "odom"} <= set(
            env.observation_space.spaces
        ):
            raise TypeError("LocalizationWrapper needs observations with 'scan' and 'odom'")
        config = as_localization_config(config)
        self.config: LocalizationConfig = config
        self.world_map = car.map
        """The map the env simulates (the world)."""
        self.map = car.map if filter_map is None else resolve_map(filter_map)
        """The map the filter holds."""
        if filter_map is not None:
            check_filter_map("LocalizationWrapper", self.map, self.world_map)
        self.dt = float(car.dt)
        lidar = car.lidar
        self._lidar_max_range = float(lidar.params.max_range)
        angles = np.asarray(lidar.angles, dtype=np.float64)
        if sensor_model is None:
            sensor_model = sensor_model_for_lidar(self.map, config.sensor, lidar)
        elif sensor_model.beam_angles is None or not np.array_equal(
            sensor_model.beam_angles, angles
        ):
            raise ValueError("sensor_model must be built with the env lidar's beam angles")
        self.sensor_model = sensor_model
        self.motion_model = MotionModel(config.motion)
        if filter_factory is None:
            filter_factory = ParticleFilter
            if config.adaptive is not None:
                filter_factory = functools.partial(AdaptiveParticleFilter, adaptive=config.adaptive)
        self._filter_factory = filter_factory
        self._clock = clock
        self.filter: ParticleFilter | None = None
        self.lost_detector = LostDetector(config.lost)
        """The lost flag of the filter ([LostDetector][mcl.filter.lost.LostDetector])."""
        self._rng: np.random.Generator | None = None
        self._renderer: MapRenderer | None = None

        self.observation_space = spaces.Dict(
            {
                **env.observation_space.spaces,
                "pose_estimate": pose_estimate_space(),
            }
        )
        self.log: ErrorLogWriter | None = ErrorLogWriter(log_path) if log_path is not None else None
        self._step = 0
        self.last_localization: dict[str, Any] | None = None

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Reset the env, then start the filter (see the class docstring for the options)."""
        start, options = filter_start("LocalizationWrapper", options, self.config.init, self.map)
        self.filter = None  # until this reset goes through
        obs, info = self.env.reset(seed=seed, options=options or None)
        if start.filter_seed is not None:
            self._rng = filter_rng(start.filter_seed)
        elif seed is not None or self._rng is None:
            self._rng = filter_rng(seed)
        pf = self._filter_factory(
            self.map,
            motion_model=self.motion_model,
            sensor_model=self.sensor_model,
            params=self.config.filter,
            rng=self._rng,
        )
        truth = np.asarray(info["pose"], dtype=np.float64)
        t0 = self._clock()
        if start.init == "global":
            pf.initialize_global()
        else:
            pf.initialize(truth if start.centres is None else start.centres, start.spread)
        self.filter = pf
        self.lost_detector.restart()
        n_eff = self._correct(obs["scan"])  # the reset observation carries a fresh scan
        estimate = self.filter.estimate()
        self._step = 0
        loc = self._localization(estimate, truth, n_eff, self._clock() - t0, True)
        return self._hooked(self._observe(obs, estimate), {**info, "localization": loc})

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """Step the env, then predict with its odometry and correct with a fresh scan."""
        if self.filter is None:
            raise ResetNeeded("LocalizationWrapper.step: call reset() before step()")
        obs, reward, terminated, truncated, info = self.env.step(action)
        pf = self.filter
        t0 = self._clock()
        pf.predict(np.asarray(obs["odom"], dtype=np.float64), self.dt)
        self.lost_detector.advance(self.dt, obs["odom"])
        fresh = bool(info.get("new_scan", True))
        n_eff = self._correct(obs["scan"]) if fresh else pf.effective_sample_size
        estimate = pf.estimate()
        update_s = self._clock() - t0
        truth = np.asarray(info["pose"], dtype=np.float64)
        loc = self._localization(estimate, truth, n_eff, update_s, fresh)
        self._step += 1
        if self.log is not None:
            self.log.write(
                self._step,
                info.get("time", self._step * self.dt),
                truth,
                estimate,
                loc["position_error"],
                loc["heading_error"],
                n_eff,
                update_s,
                loc["lost"],
            )
        obs, info = self._hooked(self._observe(obs, estimate), {**info, "localization": loc})
        return obs, reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """The env's frame with the particles (green dots) and the estimate (orange arrow)."""
        img = self.env.render()
        if img is None or self.filter is None:
            return img
        renderer = getattr(self.env.unwrapped, "renderer", None)
        if renderer is None:  # a race: its frame is drawn on the same map
            if self._renderer is None:
                self._renderer = MapRenderer(self.world_map)
            renderer = self._renderer
        particles = self.filter.particles
        stride = max(1, math.ceil(len(particles) / max(self.config.render_particles, 1)))
        if self.config.render_particles > 0:
            renderer.draw_particles(img, particles[::stride])
        renderer.draw_pose(img, self.filter.estimate())
        return img

    def close(self) -> None:
        """Close the error log and the env (the step hooks are their owners' to close)."""
        if self.log is not None:
            self.log.close()
        super().close()

    # ------------------------------------------------------------------ step hooks
    def add_step_hook(self, hook: StepHook) -> None:
        """Call ``hook(record)`` with the [`StepRecord`][mcl.wrappers.hooks.StepRecord] of every
        reset and step from now on, after the hooks added before it.

        Raises:
            TypeError: ``hook`` is not callable.
        """
        self._hooks.add(hook)

    def remove_step_hook(self, hook: StepHook) -> None:
        """Stop calling a hook given as ``on_step`` or added with
        [`add_step_hook()`][mcl.wrappers.single.LocalizationWrapper.add_step_hook].

        Raises:
            ValueError: ``hook`` is not one of this wrapper's.
        """
        self._hooks.remove(hook)

    @property
    def step_hooks(self) -> tuple[StepHook, ...]:
        """The step hooks, in the order they are called."""
        return tuple(self._hooks)

    # ------------------------------------------------------------------ internals
    def _hooked(self, obs: dict[str, Any], info: dict[str, Any]) -> tuple[dict, dict]:
        """Call the step hooks with this step's record; ``obs`` and ``info`` unchanged."""
        if self._hooks:
            assert self.filter is not None
            time_s = info.get("time", self._step * self.dt)
            record = step_record(
                self._step, time_s, obs, info, self.filter.particles, self.filter.weights
            )
            self._hooks.call(record)
        return obs, info

    def _correct(self, scan: np.ndarray) -> float:
        """Weigh by ``scan`` and resample when needed (`correct_with_scan()`)."""
        assert self.filter is not None
        return correct_with_scan(self.filter, scan, self._lidar_max_range, self.lost_detector)

    def _localization(
        self, estimate: np.ndarray, truth: np.ndarray, n_eff: float, update_s: float, fresh: bool
    ) -> dict[str, Any]:
        assert self.filter is not None
        loc = localization_report(
            self.filter, estimate, truth, n_eff, update_s, fresh, self.lost_detector.lost
        )
        self.last_localization = loc
        return loc

    @staticmethod
    def _observe(obs: dict[str, Any], estimate: np.ndarray) -> dict[str, Any]:
        return {**obs, "pose_estimate": np.asarray(estimate, dtype=np.float64).copy()}

