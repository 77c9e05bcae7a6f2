"""mcl: Monte Carlo Localization (particle filter) for racecar_sim.

The main classes are here; helpers live in their modules (``mcl.resampling``, ``mcl.angles``,
``mcl.motion_model``, ...). The experiment harness is ``mcl.experiments``, the console command
``mcl.cli``, the benchmarks ``mcl.bench``. Depends on ``racecar_sim``; ``racecar_sim`` never
imports ``mcl``.
"""

from mcl.augmented import AugmentedParams
from mcl.filter_params import DEFAULT_PARTICLES, ParticleFilterParams
from mcl.kld import KLDParams
from mcl.localization import LocalizationConfig
from mcl.motion_model import MotionModel, MotionModelParams
from mcl.particle_filter import ParticleFilter
from mcl.sensor_model import SensorModel, SensorModelParams
from mcl.uncertainty import ClusterParams, Uncertainty
from mcl.vector_wrapper import LocalizedVectorEnv
from mcl.wrapper import LocalizationWrapper
from racecar_sim import __version__

__all__ = [
    "DEFAULT_PARTICLES",
    "AugmentedParams",
    "ClusterParams",
    "KLDParams",
    "LocalizationConfig",
    "LocalizationWrapper",
    "LocalizedVectorEnv",
    "MotionModel",
    "MotionModelParams",
    "ParticleFilter",
    "ParticleFilterParams",
    "SensorModel",
    "SensorModelParams",
    "Uncertainty",
    "__version__",
]
