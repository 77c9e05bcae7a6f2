"""The sensors' parameters: the lidar (`LidarParams`) and the wheel odometry's noise
(`OdometryNoise`), in SI units."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from racecar_sim.settings.bounds import check
from racecar_sim.settings.validation import short

__all__ = ["LidarParams", "OdometryNoise"]


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
        for f in dataclasses.fields(self):  # bounds and reasons: racecar_sim.settings.bounds
            key = "lidar_rate" if f.name == "rate" else f.name
            check("LidarParams", f.name, getattr(self, f.name), key)
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
            given = getattr(self, name)
            try:
                value = tuple(float(v) for v in given)
            except (TypeError, ValueError):
                value = ()
            if len(value) != 3:
                raise ValueError(f"OdometryNoise.{name} must be three numbers, got {short(given)}")
            for v in value:  # bounds and reasons: racecar_sim.settings.bounds
                check("OdometryNoise", name, v, f"odom_{name}")
            object.__setattr__(self, name, value)
