"""mcl: Monte Carlo Localization (particle filter) for racecar_sim.

What a user needs is here: the wrappers that run the filter inside the envs, the filters and
their settings. The filter's parts live in ``mcl.filter`` (models, kernels, resampling, KLD, the
``lost`` flag), the wrappers in ``mcl.wrappers``, the lab around them in ``mcl.io``,
``mcl.experiments``, ``mcl.calibration``, ``mcl.agents``, ``mcl.bench`` and ``mcl.cli`` (the
``racecar-sim`` command). Depends on ``racecar_sim``; ``racecar_sim`` never imports ``mcl``.
"""

from mcl.filter.adaptive import AdaptiveParticleFilter
from mcl.filter.augmented import AugmentedParams
from mcl.filter.kld import KLDParams
from mcl.filter.lost_params import LostParams
from mcl.filter.motion_model import MotionModel, MotionModelParams
from mcl.filter.params import DEFAULT_PARTICLES, ParticleFilterParams
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from mcl.filter.uncertainty import ClusterParams, Uncertainty
from mcl.wrappers.localization import LocalizationConfig
from mcl.wrappers.single import LocalizationWrapper
from mcl.wrappers.vector import LocalizedVectorEnv
from racecar_sim import __version__
from racecar_sim.old_paths import MCL_MOVED, install

install(MCL_MOVED)  # ``mcl.wrapper`` and the other 0.2 paths still import, with a warning

__all__ = [
    "DEFAULT_PARTICLES",
    "AdaptiveParticleFilter",
    "AugmentedParams",
    "ClusterParams",
    "DriveRecorder",
    "KLDParams",
    "LocalizationConfig",
    "LocalizationWrapper",
    "LocalizedRaceEnv",
    "LocalizedVectorEnv",
    "LostParams",
    "MotionModel",
    "MotionModelParams",
    "ParticleFilter",
    "ParticleFilterParams",
    "SensorModel",
    "SensorModelParams",
    "Uncertainty",
    "__version__",
    "read_bag",
    "replay",
]


_ON_FIRST_USE = {
    "LocalizedRaceEnv": "mcl.wrappers.race",  # PettingZoo, the race extra
    "DriveRecorder": "mcl.io.bag_writer",  # rosbags and mcap
    "read_bag": "mcl.io.bag_reader",
    "replay": "mcl.experiments.replay",
}


def __getattr__(name: str):
    """The race wrapper, recording, reading and replaying bags are imported on first use
    (``from mcl import read_bag`` loads the bag readers, ``import mcl`` does not)."""
    if name in _ON_FIRST_USE:
        import importlib

        return getattr(importlib.import_module(_ON_FIRST_USE[name]), name)
    raise AttributeError(f"module 'mcl' has no attribute {name!r}")
