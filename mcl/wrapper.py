"""LocalizationWrapper: Monte Carlo Localization in the loop of a ``RacecarSim-v0`` env.

Each episode the wrapper starts a particle filter (around the true start pose, or spread over the
whole map), then on every step moves the particles by the step's odometry and, when the step
carries a fresh scan (``info["new_scan"]``), weighs and resamples them by that scan. The estimate
goes into the observation so an agent can drive on it, the error against the truth into ``info``
and, optionally, into a CSV log (:mod:`mcl.error_log`).

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
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mcl.adaptive import AdaptiveParams, AdaptiveParticleFilter
from mcl.angles import wrap_angle
from mcl.error_log import ErrorLogWriter
from mcl.motion_model import MotionModel, MotionModelParams
from mcl.particle_filter import ParticleFilter, ParticleFilterParams
from mcl.sensor_model import SensorModel, SensorModelParams
from racecar_sim.config import from_mapping, nested
from racecar_sim.maps import OccupancyMap, resolve_map

__all__ = [
    "INIT_MODES",
    "FilterFactory",
    "LocalizationConfig",
    "LocalizationWrapper",
    "as_localization_config",
    "correct_with_scan",
    "filter_rng",
    "localization_report",
    "pose_error",
    "pose_estimate_space",
    "sensor_model_for_lidar",
]

INIT_MODES: tuple[str, ...] = ("pose", "global")
"""How the filter starts: around the true start pose, or uniform over the map's free space."""

_FILTER_STREAM = 1  # spawn index of the filter's stream in the reset seed's SeedSequence
_RESET_OPTIONS = ("init", "init_spread", "init_pose")

FilterFactory = Callable[..., ParticleFilter]
"""Builds the filter: called as ``factory(occupancy_map, motion_model=..., sensor_model=...,
params=..., rng=...)`` (the signature of :class:`~mcl.particle_filter.ParticleFilter`); a variant
such as augmented MCL passes its own class."""


@dataclass(frozen=True)
class LocalizationConfig:
    """Settings of :class:`LocalizationWrapper` (loadable with ``racecar_sim.config.from_mapping``).

    Attributes:
        init: ``"pose"`` (Gaussian around the true start pose, standard deviations
            ``filter.init_spread``) or ``"global"`` (uniform over free space); a reset option
            ``{"init": ...}`` overrides it for one episode.
        motion: odometry noise of the motion model (scheme and coefficients per update).
        sensor: beam sensor model; its ``mount_offset`` is replaced by the env lidar's, and the
            beam angles are the env lidar's.
        filter: particle count, resampling and initial spread of the particle filter.
        render_particles: most particles drawn by :meth:`LocalizationWrapper.render` (an even
            stride through them, no randomness).
        adaptive: when given, the filter is a :class:`~mcl.adaptive.AdaptiveParticleFilter`
            with these settings (searching, then tracking), unless a ``filter_factory`` is given.
    """

    init: str = "pose"
    motion: MotionModelParams = field(default_factory=MotionModelParams)
    sensor: SensorModelParams = field(default_factory=SensorModelParams)
    filter: ParticleFilterParams = field(
        default_factory=lambda: ParticleFilterParams(init_spread=(0.25, 0.25, 0.1))
    )
    render_particles: int = 2000
    adaptive: AdaptiveParams | None = None

    def __post_init__(self) -> None:
        if self.init not in INIT_MODES:
            raise ValueError(
                f"LocalizationConfig.init = {self.init!r}; choose one of {list(INIT_MODES)}"
            )
        object.__setattr__(
            self, "motion", nested(self.motion, MotionModelParams, "LocalizationConfig.motion")
        )
        object.__setattr__(
            self, "sensor", nested(self.sensor, SensorModelParams, "LocalizationConfig.sensor")
        )
        object.__setattr__(
            self, "filter", nested(self.filter, ParticleFilterParams, "LocalizationConfig.filter")
        )
        if self.adaptive is not None:
            object.__setattr__(
                self,
                "adaptive",
                nested(self.adaptive, AdaptiveParams, "LocalizationConfig.adaptive"),
            )
        n = self.render_particles
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(
                f"LocalizationConfig.render_particles = {n!r} must be a non-negative integer"
            )

    def with_particles(self, n_particles: int) -> LocalizationConfig:
        """The same settings with another particle count."""
        return replace(self, filter=replace(self.filter, n_particles=n_particles))

    def with_motion(self, scheme: str, coefficients: Any) -> LocalizationConfig:
        """The same settings with another motion noise scheme and coefficients (per update)."""
        return replace(self, motion=MotionModelParams(scheme=scheme, coefficients=coefficients))


def as_localization_config(
    config: LocalizationConfig | Mapping[str, Any] | None,
) -> LocalizationConfig:
    """``config`` as a :class:`LocalizationConfig`: the defaults for None, a mapping of its
    fields loaded and checked (``racecar_sim.config.from_mapping``).

    Raises:
        TypeError: anything else.
    """
    if config is None:
        return LocalizationConfig()
    if isinstance(config, Mapping):
        return from_mapping(LocalizationConfig, dict(config))
    if not isinstance(config, LocalizationConfig):
        raise TypeError(f"config must be a LocalizationConfig or a mapping, got {config!r}")
    return config


def filter_rng(seed: int | None) -> np.random.Generator:
    """The filter's Generator for an env reset with ``seed`` (fresh entropy when None).

    A child of ``SeedSequence(seed)``, the sequence Gymnasium seeds ``env.np_random`` with, so the
    two streams are independent.
    """
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(_FILTER_STREAM + 1)[-1])


def correct_with_scan(pf: ParticleFilter, scan: np.ndarray, lidar_max_range: float) -> float:
    """Weigh ``pf`` by ``scan`` (metres) and resample when needed; the effective sample size
    before resampling (or the current one when the filter waits for more motion).

    Beams at the lidar's max range (no return) are passed on at the sensor model's max range,
    so that they meet its max-range component whatever the map's resolution.
    """
    z = np.asarray(scan, dtype=np.float64)
    z = np.where(z >= lidar_max_range, pf.sensor_model.max_range, z)
    skipped = pf.n_skipped
    pf.correct(z)  # inject (augmented MCL), weigh, resample (KLD count) when needed
    if pf.n_skipped != skipped:  # the filter waits for more motion (update_min_distance)
        return pf.effective_sample_size
    return pf.last_effective_sample_size


def pose_estimate_space() -> spaces.Box:
    """The ``pose_estimate`` observation: [x m, y m, theta rad in [-pi, pi)], world frame."""
    return spaces.Box(
        low=np.array([-np.inf, -np.inf, -math.pi]),
        high=np.array([np.inf, np.inf, math.pi]),
        dtype=np.float64,
    )


def sensor_model_for_lidar(
    occupancy_map: OccupancyMap, params: SensorModelParams, lidar: Any
) -> SensorModel:
    """The sensor model of ``params`` for an env's lidar: its beam angles and mount offset."""
    return SensorModel(
        occupancy_map,
        replace(params, mount_offset=float(lidar.params.mount_offset)),
        beam_angles=np.asarray(lidar.angles, dtype=np.float64),
    )


def pose_error(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """(position error m, heading error rad = estimate minus truth wrapped to [-pi, pi))."""
    return (
        float(math.hypot(estimate[0] - truth[0], estimate[1] - truth[1])),
        float(wrap_angle(estimate[2] - truth[2])),
    )


def localization_report(
    pf: ParticleFilter,
    estimate: np.ndarray,
    truth: np.ndarray,
    n_eff: float,
    update_s: float,
    fresh: bool,
) -> dict[str, Any]:
    """``info["localization"]`` of one car (keys in :class:`LocalizationWrapper`'s docstring)."""
    unc = pf.uncertainty()
    position_error, heading_error = pose_error(estimate, truth)
    return {
        "estimate": estimate,
        "position_error": position_error,
        "heading_error": heading_error,
        "n_eff": float(n_eff),
        "update_s": float(update_s),
        "corrected": fresh,
        "n_particles": pf.n_particles,
        "covariance": unc.covariance,
        "position_sd": unc.position_sd,
        "heading_sd": unc.heading_sd,
        "n_clusters": unc.n_clusters,
        "top_weight": unc.top_weight,
        "ambiguous": unc.ambiguous,
    }


class LocalizationWrapper(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Runs a particle filter on a ``RacecarSim-v0`` env's odometry and scans (module docstring).

    Args:
        env: a ``RacecarSim-v0`` env (``gymnasium.make`` or :class:`racecar_sim.env.RacecarEnv`,
            with any wrappers that keep its observations).
        config: :class:`LocalizationConfig` or a mapping of its fields.
        log_path: when given, a CSV error log (:mod:`mcl.error_log`) is written there, one row per
            step, flushed as it goes; episodes follow one another in the same file, ``step``
            restarting at 1.
        filter_factory: builds the filter (default :class:`ParticleFilter`).
        sensor_model: a ready sensor model to share between wrappers on the same map and lidar
            (it must use the env's beam angles and mount offset); built from ``config`` when None.
        clock: seconds, the timer of ``update_s``. Wall time differs from run to run; a fixed
            clock (``lambda: 0.0``) makes the infos reproducible bit for bit (``check_env``).
        filter_map: the map the *filter* holds (bundled name, YAML path or OccupancyMap) when it
            differs from the world the env simulates (e.g. the world edited since the map was
            drawn); None = the env's map. Both must share the world frame; size and resolution
            may differ.

    Observation: the env's dict plus ``pose_estimate``, ``Box(-inf, inf, (3,), float64)``, the
    estimate [x, y, theta] (world, metres, radians in [-pi, pi)).

    Info: the env's plus ``localization``: ``estimate`` (3,), ``position_error`` (m),
    ``heading_error`` (rad, estimate minus truth wrapped to [-pi, pi)), ``n_eff`` (effective
    sample size after this step's weight update, before resampling), ``update_s`` (s of wall time
    of this step's filter update), ``corrected`` (whether the step carried a fresh scan), and how
    far to trust the estimate (:meth:`mcl.particle_filter.ParticleFilter.uncertainty`):
    ``n_particles``, ``covariance`` (3, 3) (metres, radians), ``position_sd`` (m, largest axis),
    ``heading_sd`` (rad), ``n_clusters`` (clusters of the cloud with a noticeable weight),
    ``top_weight`` (weight of the heaviest cluster) and ``ambiguous`` (True when the cloud does not
    pin down one pose: two heavy clusters or a large spread, e.g. in a featureless corridor).

    Reset options (the others go to the env): ``init`` (``"pose"`` or ``"global"``, this episode),
    ``init_spread`` (standard deviations x m, y m, theta rad around the start, or one number),
    ``init_pose`` (centre of the initial guess instead of the true start pose).
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
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, config=config, log_path=log_path, filter_factory=filter_factory, clock=clock,
            filter_map=filter_map,
        )  # fmt: skip
        gym.Wrapper.__init__(self, env)
        inner = env.unwrapped
        for attr in ("map", "lidar", "dt", "renderer"):
            if not hasattr(inner, attr):
                raise TypeError(
                    f"LocalizationWrapper needs a RacecarSim-v0 env; {type(inner).__name__} has "
                    f"no {attr!r}"
                )
        if not isinstance(env.observation_space, spaces.Dict) or not {"scan", "odom"} <= set(
            env.observation_space.spaces
        ):
            raise TypeError("LocalizationWrapper needs observations with 'scan' and 'odom'")
        config = as_localization_config(config)
        self.config: LocalizationConfig = config
        self.world_map = inner.map
        """The map the env simulates (the world)."""
        self.map = inner.map if filter_map is None else resolve_map(filter_map)
        """The map the filter holds."""
        self.dt = float(inner.dt)
        lidar = inner.lidar
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
        self._rng: np.random.Generator | None = None

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
        options = dict(options or {})
        mine = {k: options.pop(k) for k in _RESET_OPTIONS if k in options}
        init = mine.get("init", self.config.init)
        if init not in INIT_MODES:
            raise ValueError(f"reset option init = {init!r}; choose one of {list(INIT_MODES)}")
        obs, info = self.env.reset(seed=seed, options=options or None)
        if seed is not None or self._rng is None:
            self._rng = filter_rng(seed)
        self.filter = self._filter_factory(
            self.map,
            motion_model=self.motion_model,
            sensor_model=self.sensor_model,
            params=self.config.filter,
            rng=self._rng,
        )
        truth = np.asarray(info["pose"], dtype=np.float64)
        t0 = self._clock()
        if init == "global":
            self.filter.initialize_global()
        else:
            centre = mine.get("init_pose", truth)
            self.filter.initialize(np.asarray(centre, dtype=np.float64), mine.get("init_spread"))
        n_eff = self._correct(obs["scan"])  # the reset observation carries a fresh scan
        estimate = self.filter.estimate()
        self._step = 0
        loc = self._localization(estimate, truth, n_eff, self._clock() - t0, True)
        return self._observe(obs, estimate), {**info, "localization": loc}

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """Step the env, then predict with its odometry and correct with a fresh scan."""
        if self.filter is None:
            raise RuntimeError("call reset() before step()")
        obs, reward, terminated, truncated, info = self.env.step(action)
        pf = self.filter
        t0 = self._clock()
        pf.predict(np.asarray(obs["odom"], dtype=np.float64), self.dt)
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
            )
        obs = self._observe(obs, estimate)
        return obs, reward, terminated, truncated, {**info, "localization": loc}

    def render(self) -> np.ndarray | None:
        """The env's frame with the particles (green dots) and the estimate (orange arrow)."""
        img = self.env.render()
        if img is None or self.filter is None:
            return img
        renderer = self.env.unwrapped.renderer
        particles = self.filter.particles
        stride = max(1, math.ceil(len(particles) / max(self.config.render_particles, 1)))
        if self.config.render_particles > 0:
            renderer.draw_particles(img, particles[::stride])
        renderer.draw_pose(img, self.filter.estimate())
        return img

    def close(self) -> None:
        """Close the error log and the env."""
        if self.log is not None:
            self.log.close()
        super().close()

    # ------------------------------------------------------------------ internals
    def _correct(self, scan: np.ndarray) -> float:
        """Weigh by ``scan`` and resample when needed (:func:`correct_with_scan`)."""
        assert self.filter is not None
        return correct_with_scan(self.filter, scan, self._lidar_max_range)

    def _localization(
        self, estimate: np.ndarray, truth: np.ndarray, n_eff: float, update_s: float, fresh: bool
    ) -> dict[str, Any]:
        assert self.filter is not None
        loc = localization_report(self.filter, estimate, truth, n_eff, update_s, fresh)
        self.last_localization = loc
        return loc

    @staticmethod
    def _observe(obs: dict[str, Any], estimate: np.ndarray) -> dict[str, Any]:
        return {**obs, "pose_estimate": np.asarray(estimate, dtype=np.float64).copy()}
