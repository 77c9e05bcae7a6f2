"""The simulated lidar: a planar scan of the true pose, cast exactly, with the beam noise of a real
scanner. Truth in, noisy measurement out (the wheel odometry is
[`racecar_sim.sensors.odometry`][racecar_sim.sensors.odometry]).

Both sensors draw their random numbers from a `numpy.random.Generator` passed to the call
(the lidar one 64-bit seed per scan, for a fast stream inside its kernel: `racecar_sim.raycast.rand`),
so the same seed gives the same measurements.

Lidar beam noise (the four-part beam model of [`LidarParams`][racecar_sim.settings.config.LidarParams]). One uniform
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
from typing import NamedTuple

import numpy as np

from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import RayCaster
from racecar_sim.raycast.rand import seed_from
from racecar_sim.raycast.scan import add_beam_noise, scan_geometry, scan_with_noise
from racecar_sim.settings.config import LidarParams

__all__ = ["Lidar", "ScanKernelInputs", "check_pose"]

_DEFAULT_LIDAR = LidarParams()


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


class ScanKernelInputs(NamedTuple):
    """What the scan kernels that cast many cars' scans in one call
    (`racecar_sim.raycast.scan`, `racecar_sim.race.lidar`) take for one lidar model:
    the same arrays [`Lidar.measure`][racecar_sim.sensors.lidar.Lidar.measure] casts with. Read-only: shared, not copied."""

    field: np.ndarray
    """The exact caster's grid of the map ([`RayCaster.field`][racecar_sim.raycast.caster.RayCaster.field])."""
    geometry: np.ndarray
    """The map's frame and the mount offset (`racecar_sim.raycast.scan.scan_geometry`)."""
    cos_a: np.ndarray
    """(n_beams,) cosines of the beam angles in the car frame."""
    sin_a: np.ndarray
    """(n_beams,) sines of the beam angles in the car frame."""
    noise: np.ndarray
    """The four-part beam noise: sigma, max_range, p_rand, p_max, p_short, short_lambda."""


class Lidar:
    """A planar scanning lidar mounted on the car, casting on an occupancy map.

    Args:
        occupancy_map: the map the beams are cast on (world frame).
        params: beam geometry, rate and noise.

    Attributes:
        params: the `LidarParams`.
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
        # measure() casts and adds noise in one kernel call (racecar_sim.raycast.scan).
        self._n = int(params.n_beams)
        self._geometry = scan_geometry(occupancy_map, params.max_range, params.mount_offset)
        self._noise = np.array(
            [params.sigma, params.max_range, params.p_rand, params.p_max, params.p_short,
             params.short_lambda]
        )  # fmt: skip
        self._cos_a = np.cos(self.angles)
        self._sin_a = np.sin(self.angles)
        self._ranges = np.empty(self._n)

    @property
    def kernel_inputs(self) -> ScanKernelInputs:
        """The arrays this lidar casts with, for kernels that cast many cars' scans at once."""
        return ScanKernelInputs(
            self._caster.field, self._geometry, self._cos_a, self._sin_a, self._noise
        )

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
        """(n_beams,) float32 noisy scan in metres from a car at rear-axle world ``pose`` (3,).

        The same as ``add_noise(true_ranges(pose), rng)`` (same draws, same floats), in one
        kernel call; `last_ranges` holds the exact ranges it cast.
        """
        arr = np.asarray(pose, dtype=np.float64)
        if arr.shape != (3,):
            check_pose(pose)
        out = np.empty(self._n, dtype=np.float32)
        status = scan_with_noise(
            self._caster.field, arr, self._geometry, self._cos_a, self._sin_a, seed_from(rng),
            self._noise, self._ranges, out,
        )  # fmt: skip
        if status == 1:
            check_pose(pose)  # raises, naming the pose
        if status != 0:  # pragma: no cover - an exact cast stays within [0, max_range]
            raise ValueError(f"ranges must be within [0, max_range={self.params.max_range}] metres")
        return out

    @property
    def last_ranges(self) -> np.ndarray:
        """(n_beams,) float64 exact ranges (metres) of the last `measure()` (a copy)."""
        return self._ranges.copy()

    def add_noise(self, ranges: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The beam noise alone: true ``ranges`` (metres, any shape) -> float32 noisy ranges.

        See the module docstring for the model. Draws one 64-bit seed from ``rng``; beam ``i``
        then takes one uniform and one standard normal from counters ``2i + 1`` and ``2i + 2`` of
        that seed's `racecar_sim.raycast.rand` stream (`uniforms_and_normals()`;
        the normal is used by Gaussian beams only). The uniform both picks the beam's part and,
        rescaled to [0, 1) within that part's interval, gives the random return's or the short
        return's distance, so no further draws are needed.

        Raises:
            ValueError: a range is NaN, negative or beyond ``max_range``.
        """
        r = np.ascontiguousarray(ranges, dtype=np.float64)
        out = np.empty(r.size, dtype=np.float32)
        if add_beam_noise(r.reshape(-1), seed_from(rng), self._noise, out) != 0:
            raise ValueError(
                f"ranges must be finite and within [0, max_range={self.params.max_range}] metres"
            )
        return out.reshape(r.shape)
