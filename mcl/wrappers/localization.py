"""The localization settings and the pieces both wrappers share (the single env's
[`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] and the vector env's
[`LocalizedVectorEnv`][mcl.wrappers.vector.LocalizedVectorEnv]): the config, the filter's generator and sensor
model, a correction by one scan, the pose-estimate space, the error against the truth and the
run report.

Frames and units: world frame of the map; poses [x, y, theta] of the rear axle in metres and
radians (theta in [-pi, pi)); times in seconds.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import yaml
from gymnasium import spaces

from mcl.filter.adaptive import AdaptiveParams
from mcl.filter.angles import wrap_angle
from mcl.filter.bounds import MAX_CASTS, check_filter
from mcl.filter.lost import LostDetector
from mcl.filter.lost_params import LostParams
from mcl.filter.motion_model import MotionModel, MotionModelParams
from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.maps import OccupancyMap
from racecar_sim.settings.config import from_mapping, nested
from racecar_sim.settings.validation import short

__all__ = [
    "INIT_MODES",
    "RESET_OPTIONS",
    "TRACKING_INIT_SPREAD",
    "FilterFactory",
    "LocalizationConfig",
    "as_localization_config",
    "correct_with_scan",
    "dotted_settings",
    "filter_rng",
    "localization_report",
    "pose_error",
    "pose_estimate_space",
    "sensor_model_for_lidar",
    "shared_models",
    "start_filter",
]

INIT_MODES: tuple[str, ...] = ("pose", "global")
"""How the filter starts: around the true start pose, or uniform over the map's free space."""

_FILTER_STREAM = 1  # spawn index of the filter's stream in the reset seed's SeedSequence
RESET_OPTIONS = ("init", "init_spread", "init_pose", "filter_seed")
"""The reset options the wrappers read."""

FilterFactory = Callable[..., ParticleFilter]
"""Builds the filter: called as ``factory(occupancy_map, motion_model=..., sensor_model=...,
params=..., rng=...)`` (the signature of [`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter]); a variant
such as augmented MCL passes its own class."""


TRACKING_INIT_SPREAD: tuple[float, float, float] = (0.25, 0.25, 0.1)
"""The default start cloud's standard deviations around the start pose (x m, y m, theta rad)."""


@dataclass(frozen=True)
class LocalizationConfig:
    """Settings of [`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] (loadable with ``racecar_sim.settings.config.from_mapping``).

    Attributes:
        init: ``"pose"`` (Gaussian around the true start pose, standard deviations
            ``filter.init_spread``) or ``"global"`` (uniform over free space); a reset option
            ``{"init": ...}`` overrides it for one episode.
        motion: odometry noise of the motion model (scheme and coefficients per update).
        sensor: beam sensor model; its ``mount_offset`` is replaced by the env lidar's, and the
            beam angles are the env lidar's.
        filter: particle count, resampling and initial spread of the particle filter.
        render_particles: most particles drawn by [`render()`][mcl.wrappers.single.LocalizationWrapper.render] (an even
            stride through them, no randomness).
        adaptive: when given, the filter is a [`AdaptiveParticleFilter`][mcl.filter.adaptive.AdaptiveParticleFilter]
            with these settings (searching, then tracking), unless a ``filter_factory`` is given.
        lost: the ``lost`` flag's thresholds and the recovery it triggers
            ([LostParams][mcl.filter.lost_params.LostParams]).
    """

    init: str = "pose"
    motion: MotionModelParams = field(default_factory=MotionModelParams)
    sensor: SensorModelParams = field(default_factory=SensorModelParams)
    filter: ParticleFilterParams = field(
        default_factory=lambda: ParticleFilterParams(init_spread=TRACKING_INIT_SPREAD)
    )
    render_particles: int = 2000
    adaptive: AdaptiveParams | None = None
    lost: LostParams = field(default_factory=LostParams)

    def __post_init__(self) -> None:
        if self.init not in INIT_MODES:
            raise ValueError(
                f"LocalizationConfig.init = {short(self.init)}; choose one of {list(INIT_MODES)}"
            )
        object.__setattr__(
            self, "motion", nested(self.motion, MotionModelParams, "LocalizationConfig.motion")
        )
        object.__setattr__(
            self, "sensor", nested(self.sensor, SensorModelParams, "LocalizationConfig.sensor")
        )
        filter_params = self.filter
        if not isinstance(filter_params, ParticleFilterParams) and hasattr(filter_params, "keys"):
            # a mapping of some fields: the others are this config's defaults, not the class's
            filter_params = {"init_spread": TRACKING_INIT_SPREAD, **dict(filter_params)}
        object.__setattr__(
            self, "filter", nested(filter_params, ParticleFilterParams, "LocalizationConfig.filter")
        )
        object.__setattr__(self, "lost", nested(self.lost, LostParams, "LocalizationConfig.lost"))
        if self.adaptive is not None:
            object.__setattr__(
                self,
                "adaptive",
                nested(self.adaptive, AdaptiveParams, "LocalizationConfig.adaptive"),
            )
        check_filter("LocalizationConfig", "render_particles", self.render_particles,
                     "render_particles")  # fmt: skip
        most = max(self.filter.n_particles, self.filter.global_particles or 0)
        casts = most * self.sensor.num_beams_per_particle
        if casts > MAX_CASTS:
            raise ValueError(
                f"LocalizationConfig: {most} particles x {self.sensor.num_beams_per_particle} "
                f"beams per particle = {casts:,} casts an update, more than {MAX_CASTS:,}; use "
                "fewer particles or beams"
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
    """``config`` as a `LocalizationConfig`: the defaults for None, a mapping of its
    fields loaded and checked (``racecar_sim.settings.config.from_mapping``).

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


def dotted_settings(items: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` items (dotted keys, YAML values: ``sensor.sigma_hit=2.0``,
    ``filter.odometry_scale.learn=false``) as the nested mapping `as_localization_config` loads.

    Raises:
        ValueError: an item that is not ``KEY=VALUE``, a value that is not YAML, or a key set both
            as a value and as a group; the message names the item.
    """
    settings: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"{item!r} is not KEY=VALUE (e.g. sensor.sigma_hit=2.0)")
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:
            raise ValueError(f"{item!r}: the value is not a YAML value") from None
        *path, last = key.strip().split(".")
        node = settings
        for part in path:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ValueError(f"{item!r}: {part} is set twice")
        node[last] = value
    return settings


def filter_rng(seed: int | None) -> np.random.Generator:
    """The filter's Generator for an env reset with ``seed`` (fresh entropy when None).

    A child of ``SeedSequence(seed)``, the sequence Gymnasium seeds ``env.np_random`` with, so the
    two streams are independent.
    """
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(_FILTER_STREAM + 1)[-1])


def correct_with_scan(
    pf: ParticleFilter,
    scan: np.ndarray,
    lidar_max_range: float,
    detector: LostDetector | None = None,
) -> float:
    """Weigh ``pf`` by ``scan`` (metres) and resample when needed; the effective sample size
    before resampling (or the current one when the filter waits for more motion).

    Beams at the lidar's max range (no return) are passed on at the sensor model's max range,
    so that they meet its max-range component whatever the map's resolution. With a
    ``detector``, the scan's fit at the new estimate updates the lost flag, which may ask the
    filter for recovery ([LostDetector.observe][mcl.filter.lost.LostDetector.observe]).
    """
    z = np.asarray(scan, dtype=np.float64)
    z = np.where(z >= lidar_max_range, pf.sensor_model.max_range, z)
    skipped = pf.n_skipped
    pf.correct(z)  # inject (augmented MCL), weigh, resample (KLD count) when needed
    if detector is not None:
        detector.observe(pf, z, lidar_max_range)
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


def shared_models(
    config: LocalizationConfig | Mapping[str, Any] | None,
    occupancy_map: OccupancyMap,
    lidar: Any,
    owner: str,
) -> tuple[LocalizationConfig, SensorModel, MotionModel]:
    """The checked config, and the one sensor model and motion model that many cars' filters
    share (the wrappers of the vector env and of the race).

    Raises:
        ValueError: the config asks for the adaptive filter (``owner`` names the wrapper).
    """
    config = as_localization_config(config)
    if config.adaptive is not None:
        raise ValueError(f"{owner} does not run the adaptive filter; set adaptive=None")
    sensor = sensor_model_for_lidar(occupancy_map, config.sensor, lidar)
    return config, sensor, MotionModel(config.motion)


def start_filter(
    occupancy_map: OccupancyMap,
    config: LocalizationConfig,
    sensor_model: SensorModel,
    motion_model: MotionModel,
    rng: np.random.Generator,
    init: str,
    centre: np.ndarray,
    spread: Any,
) -> ParticleFilter:
    """A new filter on ``rng``: uniform over free space (``init="global"``) or Gaussian around
    ``centre`` (world [x, y, theta]) with ``spread`` (None: ``config.filter.init_spread``)."""
    pf = ParticleFilter(
        occupancy_map,
        motion_model=motion_model,
        sensor_model=sensor_model,
        params=config.filter,
        rng=rng,
    )
    if init == "global":
        pf.initialize_global()
    else:
        pf.initialize(np.asarray(centre, dtype=np.float64), spread)
    return pf


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
    lost: bool = False,
) -> dict[str, Any]:
    """``info["localization"]`` of one car (keys in [`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper]'s
    docstring); ``lost`` is the car's [LostDetector][mcl.filter.lost.LostDetector] flag."""
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
        "lost": bool(lost),
    }
