"""The simulated gyro's settings (`ImuParams`, ``RacecarEnv(imu=...)``; the gyro itself is
described in [`racecar_sim.sensors.vesc`][racecar_sim.sensors.vesc]).

Below both [`racecar_sim.settings.config`][racecar_sim.settings.config] (whose ``EnvConfig.imu`` holds it) and
[`racecar_sim.sensors.vesc`][racecar_sim.sensors.vesc].
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from racecar_sim.settings.bounds import check
from racecar_sim.settings.validation import short

__all__ = ["ImuParams"]


@dataclass(frozen=True)
class ImuParams:
    """A yaw-rate gyro: reported = true yaw rate + bias + N(0, sigma²), one draw per env step.

    Attributes:
        sigma: rad/s, standard deviation of the white noise per step.
        bias: rad/s, constant offset.
    """

    sigma: float = 0.01
    bias: float = 0.0

    def __post_init__(self) -> None:
        check("ImuParams", "sigma", self.sigma, "imu.sigma")  # bounds: racecar_sim.settings.bounds
        check("ImuParams", "bias", self.bias, "imu.bias")

    @classmethod
    def from_setting(cls, value: Any) -> ImuParams | None:
        """None, ``True`` (the defaults), an `ImuParams` or a mapping of its fields."""
        if value is None or value is False:
            return None
        if value is True:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, Mapping) and not set(value) - {"sigma", "bias"}:
            return cls(**dict(value))
        raise ValueError(f"imu must be true, false, or a mapping {{sigma, bias}}, got {short(value)}")
