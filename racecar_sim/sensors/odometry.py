"""Simulated wheel odometry: the car-frame twist with proportional and additive Gaussian noise.

The noise draws come from a `numpy.random.Generator` passed to the call, so the same seed gives
the same measurements. The VESC's own odometry (its lead, bias and integration) is
[`racecar_sim.sensors.vesc`][racecar_sim.sensors.vesc].
"""

from __future__ import annotations

import math

import numpy as np

from racecar_sim.settings.config import OdometryNoise

__all__ = ["Odometry"]

_DEFAULT_ODOMETRY = OdometryNoise()


class Odometry:
    """Wheel odometry: the car-frame twist with proportional and additive Gaussian noise.

    Args:
        noise: standard deviations per component, see `OdometryNoise`.
    """

    def __init__(self, noise: OdometryNoise = _DEFAULT_ODOMETRY) -> None:
        if not isinstance(noise, OdometryNoise):
            raise TypeError(f"noise must be an OdometryNoise, got {type(noise).__name__}")
        self.noise = noise
        self._prop = np.asarray(noise.proportional, dtype=np.float64)
        self._add = np.asarray(noise.additive, dtype=np.float64)
        self._prop_f = [float(v) for v in noise.proportional]
        self._add_f = [float(v) for v in noise.additive]

    @property
    def proportional(self) -> np.ndarray:
        """(3,) float64 proportional standard deviations of [vx, vy, omega] (unitless)."""
        return self._prop

    @property
    def additive(self) -> np.ndarray:
        """(3,) float64 additive standard deviations of [vx, vy, omega] (m/s, m/s, rad/s)."""
        return self._add

    def measure(self, twist: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noisy (3,) float32 [vx, vy, omega] (m/s, m/s, rad/s, car frame) from the true ``twist``.

        Each component is ``true * (1 + N(0, proportional²)) + N(0, additive²)``; draws six standard
        normals.

        Raises:
            ValueError: ``twist`` is not three finite numbers.
        """
        t = np.asarray(twist, dtype=np.float64)
        if t.shape != (3,):
            raise ValueError(f"twist must be three finite numbers [vx, vy, omega], got {twist!r}")
        vx, vy, om = t.tolist()
        if not (math.isfinite(vx) and math.isfinite(vy) and math.isfinite(om)):
            raise ValueError(f"twist must be three finite numbers [vx, vy, omega], got {twist!r}")
        return self.noisy(vx, vy, om, rng)

    def noisy(self, vx: float, vy: float, om: float, rng: np.random.Generator) -> np.ndarray:
        """`measure()` of a twist already known to be finite floats (m/s, m/s, rad/s)."""
        # Six standard normals, the first three proportional, the last three additive (the same
        # draws and the same double operations as the array expression, in plain floats).
        z = rng.standard_normal(6).tolist()
        p, a = self._prop_f, self._add_f
        return np.array(
            [
                vx * (1.0 + p[0] * z[0]) + a[0] * z[3],
                vy * (1.0 + p[1] * z[1]) + a[1] * z[4],
                om * (1.0 + p[2] * z[2]) + a[2] * z[5],
            ],
            dtype=np.float32,
        )
