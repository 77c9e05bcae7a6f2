"""The car's sensors: the lidar ([`racecar_sim.sensors.lidar`][racecar_sim.sensors.lidar]), the
VESC's wheel odometry, the gyro, their noise settings and measured noise profiles, and the scan
effects of a real scanner. Truth in, noisy measurement out; imports the maps, the ray caster and the
settings, never the car's physics or an env."""

_MOVED_NAMES = {
    "Lidar": "racecar_sim.sensors.lidar",
    "ScanKernelInputs": "racecar_sim.sensors.lidar",
    "check_pose": "racecar_sim.sensors.lidar",
    "Odometry": "racecar_sim.sensors.odometry",
}


def __getattr__(name: str):
    """``from racecar_sim.sensors import Lidar`` (the 0.2 module) still works, with a warning."""
    if name in _MOVED_NAMES:
        import importlib
        import warnings

        new = _MOVED_NAMES[name]
        warnings.warn(
            f"racecar_sim.sensors.{name} moved to {new}.{name}; the old path works until racecar-sim 0.4",
            FutureWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module(new), name)
    raise AttributeError(f"module 'racecar_sim.sensors' has no attribute {name!r}")
