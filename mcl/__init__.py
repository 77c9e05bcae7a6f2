"""mcl: Monte Carlo Localization (particle filter) for racecar_sim.

Depends on ``racecar_sim.maps`` and ``racecar_sim.raycast``; ``racecar_sim`` never imports ``mcl``.
"""

from mcl.angles import circular_mean, wrap_angle
from mcl.augmented import AugmentedParams
from mcl.filter_params import DEFAULT_PARTICLES, ParticleFilterParams
from mcl.kld import KLDParams
from mcl.motion_model import (
    MotionModel,
    MotionModelParams,
    gaussian_to_uniform,
    twist_to_odometry,
    uniform_to_gaussian,
)
from mcl.particle_filter import ParticleFilter
from mcl.resampling import (
    RESAMPLERS,
    effective_sample_size,
    multinomial,
    resample,
    stratified,
    systematic,
)
from mcl.sensor_model import SensorModel, SensorModelParams, beam_table
from mcl.uncertainty import ClusterParams, Uncertainty
from mcl.wrapper import LocalizationConfig, LocalizationWrapper
from racecar_sim import __version__

__all__ = [
    "DEFAULT_PARTICLES",
    "RESAMPLERS",
    "AugmentedParams",
    "ClusterParams",
    "KLDParams",
    "LocalizationConfig",
    "LocalizationWrapper",
    "MotionModel",
    "MotionModelParams",
    "ParticleFilter",
    "ParticleFilterParams",
    "SensorModel",
    "SensorModelParams",
    "Uncertainty",
    "__version__",
    "beam_table",
    "circular_mean",
    "effective_sample_size",
    "gaussian_to_uniform",
    "multinomial",
    "resample",
    "stratified",
    "systematic",
    "twist_to_odometry",
    "uniform_to_gaussian",
    "wrap_angle",
]
