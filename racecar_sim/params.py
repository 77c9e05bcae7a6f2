"""Parameters of the car, the lidar and the odometry: frozen dataclasses in SI units.

Every parameter class can be built from a mapping or a YAML file with :func:`from_mapping` /
:func:`from_yaml`; unknown keys raise a ``ValueError`` naming them.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import yaml

__all__ = [
    "CarParams",
    "LidarParams",
    "OdometryNoise",
    "from_mapping",
    "from_yaml",
    "nested",
]

T = TypeVar("T")


def from_mapping(cls: type[T], mapping: dict[str, Any] | None) -> T:
    """Build dataclass ``cls`` from a mapping, defaults for missing keys.

    Raises:
        ValueError: a key is not a field of ``cls``, or a value is rejected by its validation.
    """
    mapping = dict(mapping or {})
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(mapping) - names)
    if unknown:
        raise ValueError(f"unknown {cls.__name__} parameter(s) {unknown}; known: {sorted(names)}")
    return cls(**mapping)


def nested(value: Any, cls: type[T], owner: str) -> T:
    """A nested parameter dataclass from an instance of ``cls`` or a mapping of its fields.

    ``owner`` names the field in errors (e.g. ``"ParticleFilterParams.kld"``).

    Raises:
        ValueError: the mapping has an unknown key or a rejected value, or ``value`` is neither.
    """
    if isinstance(value, cls):
        return value
    if isinstance(value, dict) or hasattr(value, "keys"):
        try:
            return from_mapping(cls, dict(value))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{owner}: {exc}") from exc
    raise ValueError(f"{owner} must be a {cls.__name__} or a mapping, got {value!r}")


def from_yaml(cls: type[T], path: str | os.PathLike[str], section: str | None = None) -> T:
    """Build dataclass ``cls`` from a YAML file (optionally from one top-level ``section``)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"parameter file {path} not found")
    data = yaml.safe_load(path.read_text()) or {}
    if not isinstance(data, dict):
        raise ValueError(f"parameter file {path}: expected a mapping")
    if section is not None:
        data = data.get(section, {}) or {}
    try:
        return from_mapping(cls, data)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"parameter file {path}: {exc}") from exc


def _check(cls_name: str, **checks: tuple[float, bool]) -> None:
    for name, (value, ok) in checks.items():
        if not isinstance(value, int | float) or not math.isfinite(value) or not ok:
            raise ValueError(f"{cls_name}.{name} = {value!r} is out of range")


@dataclass(frozen=True)
class CarParams:
    """A 1/10-scale F1TENTH / MIT RSS racecar (kinematic bicycle about the rear axle).

    Attributes:
        wheelbase: metres between the axles.
        max_steer: radians, limit of the front wheel angle (both directions).
        max_steer_rate: radians per second the steering servo can turn.
        max_speed: metres per second forwards.
        max_reverse_speed: metres per second backwards (a positive number).
        max_accel: metres per second squared when speeding up.
        max_decel: metres per second squared when braking.
        length: metres, bumper to bumper.
        width: metres.
        rear_overhang: metres from the rear axle back to the rear bumper.
        mass: kilograms.
    """

    wheelbase: float = 0.33
    max_steer: float = 0.42
    max_steer_rate: float = 3.2
    max_speed: float = 7.0
    max_reverse_speed: float = 2.0
    max_accel: float = 7.5
    max_decel: float = 9.5
    length: float = 0.55
    width: float = 0.30
    rear_overhang: float = 0.11
    mass: float = 3.5

    def __post_init__(self) -> None:
        _check(
            "CarParams",
            wheelbase=(self.wheelbase, self.wheelbase > 0),
            max_steer=(self.max_steer, 0 < self.max_steer < math.pi / 2),
            max_steer_rate=(self.max_steer_rate, self.max_steer_rate > 0),
            max_speed=(self.max_speed, self.max_speed > 0),
            max_reverse_speed=(self.max_reverse_speed, self.max_reverse_speed >= 0),
            max_accel=(self.max_accel, self.max_accel > 0),
            max_decel=(self.max_decel, self.max_decel > 0),
            length=(self.length, self.length > 0),
            width=(self.width, self.width > 0),
            rear_overhang=(self.rear_overhang, 0 <= self.rear_overhang < self.length),
            mass=(self.mass, self.mass > 0),
        )


@dataclass(frozen=True)
class LidarParams:
    """A planar scanning lidar (defaults: the MIT RSS racecar's Hokuyo as used in the lab).

    Beams are spread evenly over ``fov`` centred on the car's heading, first beam at ``-fov / 2``
    (right), last at ``+fov / 2`` (left), both ends included.

    Noise follows the four parts of the beam model (Probabilistic Robotics, 6.3), each beam drawing
    one of: a random return (probability ``p_rand``, uniform in [0, max_range]), a max-range drop-out
    (``p_max``, reported as ``max_range``), a short return from an unmapped obstacle (``p_short``, an
    exponential distance with rate ``short_lambda`` truncated to the true range), otherwise the true
    range plus Gaussian noise of ``sigma`` metres. Ranges are clipped to [0, max_range].

    Attributes:
        n_beams: number of beams per scan.
        fov: radians covered by the scan.
        max_range: metres; also the value of a drop-out.
        mount_offset: metres ahead of the rear axle along the car's x axis.
        rate: scans per second; between scans the last scan is repeated.
        sigma: metres, standard deviation of the Gaussian range noise.
        p_short: probability of a short return per beam.
        short_lambda: 1/metres, rate of the exponential short-return distance.
        p_max: probability of a max-range drop-out per beam.
        p_rand: probability of a uniformly random return per beam.
    """

    n_beams: int = 1080
    fov: float = 4.71
    max_range: float = 10.0
    mount_offset: float = 0.275
    rate: float = 40.0
    sigma: float = 0.01
    p_short: float = 0.01
    short_lambda: float = 1.0
    p_max: float = 0.005
    p_rand: float = 0.005

    def __post_init__(self) -> None:
        if not isinstance(self.n_beams, int) or isinstance(self.n_beams, bool) or self.n_beams < 1:
            raise ValueError(f"LidarParams.n_beams = {self.n_beams!r} must be a positive integer")
        _check(
            "LidarParams",
            fov=(self.fov, 0 < self.fov <= 2 * math.pi),
            max_range=(self.max_range, self.max_range > 0),
            mount_offset=(self.mount_offset, True),
            rate=(self.rate, self.rate > 0),
            sigma=(self.sigma, self.sigma >= 0),
            p_short=(self.p_short, 0 <= self.p_short <= 1),
            short_lambda=(self.short_lambda, self.short_lambda > 0),
            p_max=(self.p_max, 0 <= self.p_max <= 1),
            p_rand=(self.p_rand, 0 <= self.p_rand <= 1),
        )
        if self.p_short + self.p_max + self.p_rand > 1:
            raise ValueError("LidarParams: p_short + p_max + p_rand must not exceed 1")

    @property
    def angles(self):  # -> np.ndarray, imported lazily to keep this module light
        """(n_beams,) beam angles in the car frame, radians."""
        import numpy as np

        if self.n_beams == 1:
            return np.zeros(1)
        return np.linspace(-self.fov / 2, self.fov / 2, self.n_beams)


@dataclass(frozen=True)
class OdometryNoise:
    """Noise of the wheel odometry's car-frame twist (vx, vy, omega), like a VESC's /odom.

    Each reported component is ``true * (1 + N(0, proportional**2)) + N(0, additive**2)``.

    Attributes:
        proportional: (vx, vy, omega) standard deviations as a fraction of the true value.
        additive: (vx, vy, omega) standard deviations in m/s, m/s, rad/s.
    """

    proportional: tuple[float, float, float] = (0.02, 0.0, 0.05)
    additive: tuple[float, float, float] = (0.005, 0.0, 0.005)

    def __post_init__(self) -> None:
        for name in ("proportional", "additive"):
            value = tuple(float(v) for v in getattr(self, name))
            if len(value) != 3 or not all(math.isfinite(v) and v >= 0 for v in value):
                raise ValueError(
                    f"OdometryNoise.{name} must be three non-negative numbers, got {value!r}"
                )
            object.__setattr__(self, name, value)
