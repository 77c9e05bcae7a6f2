"""Simulated sensors: a planar lidar and wheel odometry. Truth in, noisy measurement out.

Both sensors draw every random number from a :class:`numpy.random.Generator` passed to the call, so
the same seed gives the same measurements.

Lidar beam noise (the four-part beam model of :class:`~racecar_sim.params.LidarParams`). One uniform
draw per beam chooses its part:

* ``u < p_rand``: a random return, uniform in [0, max_range];
* ``u < p_rand + p_max``: a max-range drop-out, reported as ``max_range``;
* ``u < p_rand + p_max + p_short``: a short return from an unmapped obstacle, distance drawn from an
  exponential with rate ``short_lambda`` truncated to [0, true range] (inverse CDF, exact);
* otherwise the true range plus Gaussian noise N(0, sigma²).

The result is clipped to [0, max_range]. A beam whose true range is ``max_range`` hit nothing, so
there is no surface to add Gaussian noise to and no obstacle range to shorten: such a beam stays at
``max_range`` unless its draw picks a random return, which replaces it. (The short-return part of
the beam model describes objects in front of a *mapped* surface; that is the decision taken here.)
"""

from __future__ import annotations

import math

import numpy as np

from racecar_sim.maps import OccupancyMap
from racecar_sim.params import LidarParams, OdometryNoise
from racecar_sim.raycast import RayCaster

__all__ = ["Lidar", "Odometry", "check_pose"]

_DEFAULT_LIDAR = LidarParams()
_DEFAULT_ODOMETRY = OdometryNoise()


def check_pose(pose: np.ndarray, name: str = "pose") -> np.ndarray:
    """``pose`` as a float64 (3,) array [x, y, theta] (metres, radians), or raise ValueError.

    Raises:
        ValueError: the shape is not (3,) or a value is NaN or infinite; the message names ``name``.
    """
    arr = np.asarray(pose, dtype=np.float64)
    if arr.shape != (3,):
        raise ValueError(f"{name} must be [x, y, theta] with shape (3,), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite [x, y, theta], got {arr.tolist()}")
    return arr


class Lidar:
    """A planar scanning lidar mounted on the car, casting on an occupancy map.

    Args:
        occupancy_map: the map the beams are cast on (world frame).
        params: beam geometry, rate and noise.

    Attributes:
        params: the :class:`LidarParams`.
        angles: (n_beams,) beam angles in the car frame, radians (= ``params.angles``).
        period: seconds between two scans (``1 / params.rate``).
    """

    def __init__(self, occupancy_map: OccupancyMap, params: LidarParams = _DEFAULT_LIDAR) -> None:
        if not isinstance(params, LidarParams):
            raise TypeError(f"params must be a LidarParams, got {type(params).__name__}")
        self.map = occupancy_map
        self.params = params
        self.angles: np.ndarray = np.asarray(params.angles, dtype=np.float64)
        self.angles.setflags(write=False)
        self.period: float = 1.0 / params.rate
        self._caster = RayCaster(occupancy_map, params.max_range, method="exact")
        # Cumulative thresholds of the uniform draw choosing a beam's noise part.
        self._t_rand = params.p_rand
        self._t_max = params.p_rand + params.p_max
        self._t_short = params.p_rand + params.p_max + params.p_short

    # ------------------------------------------------------------------ geometry
    def mount_pose(self, pose: np.ndarray) -> np.ndarray:
        """World pose (3,) of the lidar for the car's rear-axle world pose ``pose`` (3,).

        The lidar sits ``params.mount_offset`` metres ahead of the rear axle along the heading and
        looks along the heading.
        """
        pose = check_pose(pose)
        off = self.params.mount_offset
        x, y, th = pose
        return np.array([x + off * math.cos(th), y + off * math.sin(th), th])

    # ------------------------------------------------------------------ measurements
    def true_ranges(self, pose: np.ndarray) -> np.ndarray:
        """(n_beams,) float64 exact ranges in metres from the lidar on a car at ``pose`` (world)."""
        return self._caster.cast(self.mount_pose(pose), self.angles)[0]

    def measure(self, pose: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(n_beams,) float32 noisy scan in metres from a car at rear-axle world ``pose`` (3,)."""
        return self.add_noise(self.true_ranges(pose), rng)

    def add_noise(self, ranges: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The beam noise alone: true ``ranges`` (metres, any shape) -> float32 noisy ranges.

        See the module docstring for the model. Draws, in this order: one uniform per beam, one
        standard normal per beam, one uniform per random return, one uniform per short return.

        Raises:
            ValueError: a range is NaN, negative or beyond ``max_range``.
        """
        p = self.params
        r = np.asarray(ranges, dtype=np.float64)
        if not (np.isfinite(r).all() and (r >= 0).all() and (r <= p.max_range).all()):
            raise ValueError(
                f"ranges must be finite and within [0, max_range={p.max_range}] metres"
            )
        u = rng.random(r.shape)
        out = r + p.sigma * rng.standard_normal(r.shape)
        no_return = r >= p.max_range
        out[no_return] = p.max_range
        if self._t_short > 0.0:
            out[u < self._t_max] = p.max_range  # drop-outs (random returns overwrite below)
            rand = u < self._t_rand
            n_rand = int(np.count_nonzero(rand))
            if n_rand:
                out[rand] = p.max_range * rng.random(n_rand)
            short = (u >= self._t_max) & (u < self._t_short) & ~no_return
            n_short = int(np.count_nonzero(short))
            if n_short:
                out[short] = _truncated_exponential(r[short], p.short_lambda, rng.random(n_short))
        np.clip(out, 0.0, p.max_range, out=out)
        return out.astype(np.float32)


def _truncated_exponential(upper: np.ndarray, rate: float, v: np.ndarray) -> np.ndarray:
    """Inverse CDF of an exponential with ``rate`` (1/m) truncated to [0, upper] at uniforms ``v``.

    F(x) = (1 - exp(-rate x)) / (1 - exp(-rate upper)), so x = -log1p(-v (1 - exp(-rate upper))) /
    rate, which lies in [0, upper] for v in [0, 1).
    """
    mass = -np.expm1(-rate * upper)
    return np.minimum(-np.log1p(-v * mass) / rate, upper)


class Odometry:
    """Wheel odometry: the car-frame twist with proportional and additive Gaussian noise.

    Args:
        noise: standard deviations per component, see :class:`OdometryNoise`.
    """

    def __init__(self, noise: OdometryNoise = _DEFAULT_ODOMETRY) -> None:
        if not isinstance(noise, OdometryNoise):
            raise TypeError(f"noise must be an OdometryNoise, got {type(noise).__name__}")
        self.noise = noise
        self._prop = np.asarray(noise.proportional, dtype=np.float64)
        self._add = np.asarray(noise.additive, dtype=np.float64)

    def measure(self, twist: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noisy (3,) float32 [vx, vy, omega] (m/s, m/s, rad/s, car frame) from the true ``twist``.

        Each component is ``true * (1 + N(0, proportional²)) + N(0, additive²)``; draws six standard
        normals.

        Raises:
            ValueError: ``twist`` is not three finite numbers.
        """
        t = np.asarray(twist, dtype=np.float64)
        if t.shape != (3,) or not np.isfinite(t).all():
            raise ValueError(f"twist must be three finite numbers [vx, vy, omega], got {twist!r}")
        z = rng.standard_normal((2, 3))
        return (t * (1.0 + self._prop * z[0]) + self._add * z[1]).astype(np.float32)
