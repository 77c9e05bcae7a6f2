"""The scan fit: the fraction of a scan's beams that the filter's map explains from one pose.

A count of beams, not a likelihood, so it does not depend on the sensor model's tempering or its
``sigma_hit``: a beam agrees when its measured range lies within a tolerance of the range cast in
the *filter's* map from the pose's lidar (beams at or beyond the filter's range, or the lidar's
when it sees less, agree with a cast that finds no wall within it). One cast of a few evenly
spaced beams from one pose: tens of microseconds per scan. Beams that return short of the cast (something the map lacks stands in
front) may be left out: they neither confirm nor refute the pose. Used by the ``lost`` flag
([`mcl.filter.lost`][mcl.filter.lost]) and by the learned odometry scale
([`mcl.filter.odometry_scale`][mcl.filter.odometry_scale]), which learns only between poses the
scan confirms.

Frames and units: world frame; metres, radians; the fit is a fraction in [0, 1] (NaN when no beam
counts).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mcl.filter.scan_continuity import scan_bearings
from racecar_sim.maps import OccupancyMap

__all__ = ["ScanFit", "scan_agreement"]


def scan_agreement(
    expected: np.ndarray,
    measured: np.ndarray,
    tolerance: float,
    max_range: float,
    skip_short: bool = False,
) -> float:
    """Fraction of beams whose measured range (metres) lies within ``tolerance`` of the expected
    one, both clipped to ``max_range`` (so a no-return agrees with a cast that finds no wall);
    NaN when no beam counts.

    Args:
        expected: (K,) ranges cast in the filter's map (metres).
        measured: (K,) measured ranges (metres; NaN/inf beams are left out).
        tolerance: metres.
        max_range: metres, the filter's range.
        skip_short: leave out the beams that return more than ``tolerance`` short of the cast
            (something the map lacks stands in front: they neither confirm nor refute the pose).
    """
    z = np.asarray(measured, dtype=np.float64)
    ok = np.isfinite(z)
    if not ok.any():
        return math.nan
    diff = np.minimum(z[ok], max_range) - np.minimum(
        np.asarray(expected, dtype=np.float64)[ok], max_range
    )
    agree = np.abs(diff) <= tolerance
    counted = agree.size - (int(np.count_nonzero(diff < -tolerance)) if skip_short else 0)
    return float(np.count_nonzero(agree) / counted) if counted > 0 else math.nan


class ScanFit:
    """The scan fit at a pose (module docstring), with the beams it compares kept between calls.

    Args:
        beams: beams of the scan compared (evenly spaced).
        tolerance: metres; a beam agrees when its measured range is this close to the cast.
        skip_short: leave out the beams that return more than ``tolerance`` short of the cast.
    """

    def __init__(self, beams: int, tolerance: float, skip_short: bool) -> None:
        self.beams = int(beams)
        self.tolerance = float(tolerance)
        self.skip_short = bool(skip_short)
        self._key: tuple[int, int] = (-1, -1)  # (scan length, sensor model) the beams are for
        self._index = np.zeros(0, dtype=np.int64)
        self._angles = np.zeros(0)

    def at(
        self,
        sensor_model: Any,
        grid: OccupancyMap,
        pose: np.ndarray,
        scan: np.ndarray,
        lidar_range: float | None = None,
    ) -> float:
        """The fit of ``scan`` (metres, the sensor model's beams) at the world pose ``pose``
        [x m, y m, theta rad], cast in ``grid`` (the filter's map) with ``sensor_model``'s caster
        (the distance to the nearest wall at the beam end points for the likelihood field, which
        has no caster); NaN when no beam counts. ``lidar_range``: metres the lidar sees, when
        shorter than the sensor model's range: ranges and casts are clipped to it, so a no-return
        agrees with a cast that finds no wall within the lidar's reach (None: the model's range)."""
        z = np.asarray(scan, dtype=np.float64).reshape(-1)
        n = z.size
        if self._key != (n, id(sensor_model)):
            self._index = np.unique(
                np.floor(np.linspace(0, n - 1, min(self.beams, n)) + 0.5).astype(np.int64)
            )
            self._angles = scan_bearings(sensor_model, n)[self._index]
            self._key = (n, id(sensor_model))
        z, angles = z[self._index], self._angles
        lidar = sensor_model.lidar_poses(np.asarray(pose, dtype=np.float64)[None, :])[0]
        max_range = float(sensor_model.max_range)
        if lidar_range is not None:
            max_range = min(max_range, float(lidar_range))
        tol = self.tolerance
        if sensor_model.caster is not None:
            expected = sensor_model.caster.cast(lidar, angles)[0]
            return scan_agreement(expected, z, tol, max_range, self.skip_short)
        # likelihood field: a beam agrees when its end point lies within the tolerance of a wall
        # on the filter's map (no-returns agree only with open space)
        ok = np.isfinite(z)
        if not ok.any():
            return math.nan
        z, angles = z[ok], angles[ok]
        far = z >= max_range - tol
        ends = lidar[:2] + z[:, None] * np.column_stack(
            [np.cos(lidar[2] + angles), np.sin(lidar[2] + angles)]
        )
        near_wall = grid.distance_at(ends) <= tol
        return float(np.mean(np.where(far, True, near_wall)))
