"""Wheels that turn while the car stands: the filter's check that the odometry moves a car its scans
say has not moved.

Wheel odometry reports what the wheels do. A car pinned against a wall or a chair with the motor
still pushing, a car lifted onto a stand, wheels spinning on a slick floor: the odometry says the
car drives on, and a filter that follows its odometry drives its estimate away from the car,
through walls, while every scan says the car is where it was (in the honest world of
`docs/localization_changing_world.md`, cluttered seed 9 pins itself at 53 s and the estimate
followed the spinning wheels 4 m away in 7 s).

[Standstill][mcl.filter.standstill.Standstill] keeps a reference scan and the odometry's motion
since. Once the odometry has moved the car ``min_distance`` metres or turned it ``min_turn``
radians from there, it compares the newest scan with the reference twice, with the two scans'
[continuity][mcl.filter.scan_continuity.both_ways] (no map involved): as the odometry says the
car moved, and as if it had not moved at all. When the car standing still explains the scans
(``still_above`` of the points seen again) better by ``margin`` than the odometry's motion in
``in_a_row`` comparisons in a row, the car stands: the filter then predicts with no motion (its motion noise still applies) until a later
comparison says the car moves. In a corridor whose walls look the same all along, both explain the
side walls and the far ones decide: the odometry's motion wins whenever the car did move.

Frames and units: car frame and lidar frame (as in [mcl.filter.scan_continuity][]); metres,
radians, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcl.filter.scan_continuity import both_ways, compose, invert, odometry_motion
from racecar_sim.settings.validation import short

__all__ = ["Standstill", "StandstillParams"]


@dataclass(frozen=True)
class StandstillParams:
    """Settings of the standstill check (module docstring).

    Attributes:
        enabled: check, and predict with no motion while the car stands (False: always follow the
            odometry).
        min_distance: metres the odometry must have moved the car since the reference scan before
            the two are compared.
        min_turn: radians the odometry must have turned the car, the same way.
        still_above: the continuity with no motion must be at least this for the car to stand.
        margin: ... and exceed the continuity with the odometry's motion by this much.
        in_a_row: comparisons in a row that must find the car standing before the filter stops
            following the odometry (the first that finds it moving ends the standstill).
        beams: points of each scan compared.
        tolerance: metres within which a point counts as seen again.
        tolerance_per_m: extra metres of tolerance per metre of range.
    """

    enabled: bool = True
    min_distance: float = 0.2
    min_turn: float = 0.2
    still_above: float = 0.75
    margin: float = 0.3
    in_a_row: int = 2
    beams: int = 100
    tolerance: float = 0.05
    tolerance_per_m: float = 0.01

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ValueError(f"StandstillParams.enabled = {short(self.enabled)} must be a bool")
        for name in ("beams", "in_a_row"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(
                    f"StandstillParams.{name} = {short(value)} must be a positive integer"
                )
        if isinstance(self.beams, bool) or not isinstance(self.beams, int) or self.beams < 10:
            raise ValueError(
                f"StandstillParams.beams = {short(self.beams)} must be an integer >= 10"
            )
        for name in ("min_distance", "min_turn", "still_above", "margin", "tolerance",
                     "tolerance_per_m"):  # fmt: skip
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not (math.isfinite(value) and value >= 0)
            ):
                raise ValueError(f"StandstillParams.{name} = {short(value)} must be a number >= 0")
            object.__setattr__(self, name, float(value))
        if self.min_distance <= 0 or self.min_turn <= 0:
            raise ValueError("StandstillParams: min_distance and min_turn must be > 0")
        if self.still_above > 1 or self.margin > 1:
            raise ValueError("StandstillParams: still_above and margin are fractions in [0, 1]")


class Standstill:
    """Whether one car stands while its wheels turn (module docstring); one per filter.

    Args:
        params: [StandstillParams][mcl.filter.standstill.StandstillParams].

    Attributes:
        standing: the last comparison found the car standing (the filter predicts no motion).
        n_standing: comparisons that found it standing since the start.
    """

    def __init__(self, params: StandstillParams | None = None) -> None:
        self.params = params if params is not None else StandstillParams()
        self.standing = False
        self.n_standing = 0
        self._in_a_row = 0
        self._motion = np.zeros(3)  # the car's motion by the odometry since the reference scan
        self._reference: tuple[np.ndarray, np.ndarray] | None = None

    def restart(self) -> None:
        """Forget the reference scan and the motion since (a new belief)."""
        self.standing = False
        self._in_a_row = 0
        self._motion = np.zeros(3)
        self._reference = None

    def advance(self, twist: np.ndarray, dt: float) -> None:
        """The odometry says the car drove the car-frame ``twist`` [vx m/s, vy m/s, omega rad/s]
        for ``dt`` seconds."""
        if self.params.enabled:
            self._motion = compose(self._motion, odometry_motion(twist, dt))

    def due(self) -> bool:
        """Whether the next scan is taken (the first one, or the odometry has moved the car far
        enough since the reference): the caller need not work out the scan's bearings otherwise."""
        if not self.params.enabled:
            return False
        m = self._motion
        return self._reference is None or (
            math.hypot(m[0], m[1]) >= self.params.min_distance or abs(m[2]) >= self.params.min_turn
        )

    def observe(
        self, scan: np.ndarray, angles: np.ndarray, mount: np.ndarray, max_range: float
    ) -> bool:
        """Compare ``scan`` (metres, at bearings ``angles`` in radians, ascending, evenly spaced)
        with the reference once the odometry has moved far enough; returns `standing`.

        Args:
            scan: the ranges.
            angles: their bearings in the lidar frame.
            mount: the lidar's pose in the car frame [x m, y m, theta rad].
            max_range: metres; ranges at or beyond it are no return.
        """
        p = self.params
        if not self.due():
            return self.standing
        z = np.asarray(scan, dtype=np.float64).reshape(-1)
        if self._reference is None:
            self._reference = (z.copy(), np.asarray(angles, dtype=np.float64).copy())
            return self.standing
        m = self._motion
        before, before_angles = self._reference
        mount = np.asarray(mount, dtype=np.float64)
        moved = compose(compose(invert(mount), m), mount)
        args = (p.beams, float(max_range), p.tolerance, p.tolerance_per_m)
        as_odometry = both_ways(before, before_angles, z, angles, moved, *args)
        as_standing = both_ways(before, before_angles, z, angles, np.zeros(3), *args)
        looks_standing = as_standing >= p.still_above and as_standing - as_odometry >= p.margin
        self._in_a_row = self._in_a_row + 1 if looks_standing else 0  # NaN compares False
        self.standing = self._in_a_row >= p.in_a_row
        self.n_standing += self.standing
        self._reference = (z.copy(), np.asarray(angles, dtype=np.float64).copy())
        self._motion = np.zeros(3)
        return self.standing
