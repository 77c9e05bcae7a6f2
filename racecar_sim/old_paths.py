"""Old import paths, kept for one release: ``import racecar_sim.config`` still works, warns once
with a `FutureWarning` naming the new path, and returns the very module of the new path (so a
monkeypatch through either name reaches the same object).

Modules moved into folders by noun in 0.3: the car (``racecar_sim.car``), its sensors
(``racecar_sim.sensors``), the room (``racecar_sim.world``), the settings
(``racecar_sim.settings``); the filter (``mcl.filter``) and its wrappers (``mcl.wrappers``).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

__all__ = ["MCL_MOVED", "RACECAR_SIM_MOVED", "OldPathFinder", "install"]

RACECAR_SIM_MOVED: dict[str, str] = {
    "racecar_sim.bounds": "racecar_sim.settings.bounds",
    "racecar_sim.car_body": "racecar_sim.car.body",
    "racecar_sim.config": "racecar_sim.settings.config",
    "racecar_sim.free_batch": "racecar_sim.car.free_batch",
    "racecar_sim.free_steps": "racecar_sim.car.free_steps",
    "racecar_sim.imu": "racecar_sim.sensors.imu",
    "racecar_sim.noise_profiles": "racecar_sim.sensors.noise_profiles",
    "racecar_sim.obstacles": "racecar_sim.world.obstacles",
    "racecar_sim.params": "racecar_sim.settings.params",
    "racecar_sim.physics": "racecar_sim.car.physics",
    "racecar_sim.car.fleet": "racecar_sim.fleet",
    "racecar_sim.race.laps": "racecar_sim.world.laps",
    "racecar_sim.race.loops": "racecar_sim.world.centerline",
    "racecar_sim.race.track": "racecar_sim.world.track",
    "racecar_sim.rand": "racecar_sim.raycast.rand",
    "racecar_sim.scan_effects": "racecar_sim.sensors.scan_effects",
    "racecar_sim.scenes": "racecar_sim.world.scenes",
    "racecar_sim.sensor_params": "racecar_sim.sensors.params",
    "racecar_sim.start_poses": "racecar_sim.car.start_poses",
    "racecar_sim.validation": "racecar_sim.settings.validation",
    "racecar_sim.vehicle": "racecar_sim.car.models",
    "racecar_sim.vehicle.kinematic": "racecar_sim.car.models.kinematic",
    "racecar_sim.vehicle.manoeuvres": "racecar_sim.car.models.manoeuvres",
    "racecar_sim.vehicle.params": "racecar_sim.car.models.params",
    "racecar_sim.vehicle.single_track": "racecar_sim.car.models.single_track",
    "racecar_sim.vesc": "racecar_sim.sensors.vesc",
    "racecar_sim.wall_features": "racecar_sim.world.wall_features",
    "racecar_sim.walls": "racecar_sim.car.walls",
}
"""Old module path -> new module path, for ``racecar_sim``."""

MCL_MOVED: dict[str, str] = {
    "mcl.adaptive": "mcl.filter.adaptive",
    "mcl.alpha_motion": "mcl.filter.alpha_motion",
    "mcl.angles": "mcl.filter.angles",
    "mcl.augmented": "mcl.filter.augmented",
    "mcl.beam_skip": "mcl.filter.beam_skip",
    "mcl.error_log": "mcl.wrappers.error_log",
    "mcl.filter_bounds": "mcl.filter.bounds",
    "mcl.filter_params": "mcl.filter.params",
    "mcl.kld": "mcl.filter.kld",
    "mcl.likelihood_field": "mcl.filter.likelihood_field",
    "mcl.localization": "mcl.wrappers.localization",
    "mcl.lost": "mcl.filter.lost",
    "mcl.motion_model": "mcl.filter.motion_model",
    "mcl.odometry_scale": "mcl.filter.odometry_scale",
    "mcl.particle_filter": "mcl.filter.particle_filter",
    "mcl.race_wrapper": "mcl.wrappers.race",
    "mcl.resampling": "mcl.filter.resampling",
    "mcl.run_bounds": "mcl.experiments.run_bounds",
    "mcl.sensor_model": "mcl.filter.sensor_model",
    "mcl.sensor_params": "mcl.filter.sensor_params",
    "mcl.step_kernels": "mcl.filter.step_kernels",
    "mcl.uncertainty": "mcl.filter.uncertainty",
    "mcl.vector_wrapper": "mcl.wrappers.vector",
    "mcl.wrapper": "mcl.wrappers.single",
    "mcl.wrapper_checks": "mcl.wrappers.checks",
}
"""Old module path -> new module path, for ``mcl``."""


class OldPathFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """A finder on `sys.meta_path` that serves each old path as an alias of its new module.

    Args:
        moved: old dotted module path -> new dotted module path.
    """

    def __init__(self, moved: dict[str, str]) -> None:
        self.moved = dict(moved)

    def find_spec(self, fullname: str, path: object = None, target: object = None):
        """A spec for an old path this finder knows; None (the next finder) for any other name."""
        if fullname not in self.moved:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        """Python's default module object (replaced by the new module in `exec_module`)."""
        return None

    def exec_module(self, module: ModuleType) -> None:
        """Warn once, then put the new module in `sys.modules` under the old name."""
        new = self.moved[module.__name__]
        warnings.warn(
            f"{module.__name__} moved to {new}; the old path works until racecar-sim 0.4",
            FutureWarning,
            stacklevel=2,
        )
        sys.modules[module.__name__] = importlib.import_module(new)


def install(moved: dict[str, str]) -> None:
    """Put one `OldPathFinder` for ``moved`` on `sys.meta_path` (at most once per table)."""
    if not any(isinstance(f, OldPathFinder) and f.moved == moved for f in sys.meta_path):
        sys.meta_path.insert(0, OldPathFinder(moved))  # before the path finder: a module of an
        # old package path would otherwise load a second time from the new folder
