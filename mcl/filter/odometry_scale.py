"""Odometry speed scale learned online: the filter's answer to wheels that under- or over-report.

Wheel odometry has a speed scale error (the MIT racecar's VESC reports about 5 % less than the car
drives: ``docs/honest_noise.md``). Where the scan pins the car along its path the filter corrects
it; in a long corridor, and worse where the map is out of date, nothing does, and the estimate falls
behind the car at the scale error times the speed (0.1 m/s at 2 m/s: a metre in ten seconds).

[OdometryScale][mcl.filter.odometry_scale.OdometryScale] compares, over windows of ``window`` metres of
odometry travel, how far the filter's estimate moved (world frame, expressed in the car frame at the
window's start) with how far the raw odometry says the car moved, and moves its scale a fraction
``gain`` of the way to the observed ratio, from the first window on (a first window that counted in
full, taken where the estimate lagged, set the scale to its floor and kept it there: clean seed 14
of the honest world's 20, 6.96 m mean error). The filter multiplies the forward speed by the scale before
its motion model. Where the scan says nothing along the path the estimate follows the scaled
odometry, the observed ratio equals the scale, and the scale stays what it learned where the scan did
say something: it is a fixed point, not a drift. Windows taken while the cloud is spread (the
estimate not trusted) or while the car turned more than it drove straight are not used.

A car whose odometry has been calibrated (``racecar-sim calibrate-noise`` measures the wheels'
speed bias from the car's own recordings: the MIT racecar's VESC reads 5.3 % slow, a scale of
1 / (1 - 0.053) = 1.056) can start from that scale (``initial``) and hold it (``learn=False``):
where the old map drags the estimate back along a corridor, the windows see it move less than
the car and the learned scale follows the drag (``docs/localization_changing_world.md``). The
whole calibration (scale and offset of each of vx, vy, omega) goes in ``filter.odometry_bias``.

Units: metres, radians, seconds; the scale is dimensionless (1 = trust the wheels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcl.filter.bounds import check_filter
from racecar_sim.settings.validation import short

__all__ = ["OdometryScale", "OdometryScaleParams"]


@dataclass(frozen=True)
class OdometryScaleParams:
    """Settings of the learned odometry speed scale.

    Attributes:
        enabled: apply the scale (False: the odometry is used as reported).
        initial: the scale at the start (dimensionless; 1 = trust the wheels, 1.056 = wheels that
            read 5.3 % slow), e.g. from a calibration of the car's odometry.
        learn: learn the scale online from the estimate (False: hold ``initial``).
        window: metres of odometry travel per comparison.
        gain: fraction of the way from the scale to a window's observed ratio taken per window.
        low: smallest scale (the wheels over-report by at most 1 / low - 1).
        high: largest scale.
        max_spread: metres; a window is used only when the cloud's position standard deviation
            (square root of the covariance's xy trace) is below this at both its ends.
        min_straightness: a window is used only when the straight-line odometry displacement is at
            least this fraction of the path length (turns mix heading and speed errors).
    """

    enabled: bool = True
    initial: float = 1.0
    learn: bool = True
    window: float = 2.0
    gain: float = 0.2
    low: float = 0.8
    high: float = 1.25
    max_spread: float = 0.3
    min_straightness: float = 0.9

    def __post_init__(self) -> None:
        for name in ("enabled", "learn"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"OdometryScaleParams.{name} = {short(getattr(self, name))} must be a bool"
                )
        for name in ("initial", "window", "gain", "low", "high", "max_spread", "min_straightness"):
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not math.isfinite(value)
            ):
                raise ValueError(
                    f"OdometryScaleParams.{name} = {short(value)} must be a finite number"
                )
            object.__setattr__(self, name, float(value))
        check_filter("OdometryScaleParams", "window", self.window, "odometry_scale.window")
        if not 0.0 < self.gain <= 1.0:
            raise ValueError(f"OdometryScaleParams.gain = {self.gain!r} must be in (0, 1]")
        if not 0.0 < self.low <= 1.0 <= self.high <= 10.0:
            raise ValueError(
                f"OdometryScaleParams: low = {self.low!r} and high = {self.high!r} must satisfy "
                "0 < low <= 1 <= high <= 10"
            )
        if not self.low <= self.initial <= self.high:
            raise ValueError(
                f"OdometryScaleParams.initial = {self.initial!r} must lie in [low, high] = "
                f"[{self.low!r}, {self.high!r}]"
            )
        if self.max_spread <= 0:
            raise ValueError(f"OdometryScaleParams.max_spread = {self.max_spread!r} must be > 0")
        if not 0.0 <= self.min_straightness <= 1.0:
            raise ValueError(
                f"OdometryScaleParams.min_straightness = {self.min_straightness!r} must be in [0, 1]"
            )


class OdometryScale:
    """The learned forward-speed scale of one filter (module docstring).

    Args:
        params: the settings.
    """

    def __init__(self, params: OdometryScaleParams) -> None:
        self.params = params
        self.scale = params.initial
        self.windows_used = 0
        self._anchor: np.ndarray | None = None  # estimate [x, y, theta] at the window's start
        self._odo = np.zeros(3)  # raw dead reckoning since the anchor, anchor frame
        self._path = 0.0  # metres of raw odometry travel since the anchor

    def restart(self) -> None:
        """Forget the window in progress (a new episode, a global start); the scale is kept."""
        self._anchor = None
        self._odo[:] = 0.0
        self._path = 0.0

    def scaled(self, twist: np.ndarray) -> np.ndarray:
        """``twist`` [vx m/s, vy m/s, omega rad/s] with its forward speed times the scale."""
        if not self.params.enabled or self.scale == 1.0:
            return twist
        out = np.array(twist, dtype=np.float64)
        out[0] *= self.scale
        return out

    def needs_estimate(self) -> bool:
        """Whether the next [observe][mcl.filter.odometry_scale.OdometryScale.observe] needs the
        filter's estimate and spread (at a window's start or end only)."""
        p = self.params
        return p.enabled and p.learn and (self._anchor is None or self._path >= p.window)

    def observe(
        self,
        twist: np.ndarray,
        dt: float,
        estimate: np.ndarray | None = None,
        spread: float = math.inf,
    ) -> None:
        """Account for one step of raw odometry ``twist`` held ``dt`` seconds, given (when
        [needs_estimate][mcl.filter.odometry_scale.OdometryScale.needs_estimate]) the filter's estimate
        (world [x m, y m, theta rad]) and position spread (metres) *before* the step."""
        p = self.params
        if not (p.enabled and p.learn):
            return
        if self.needs_estimate():
            if estimate is None:
                raise ValueError("OdometryScale.observe needs the estimate at a window's ends")
            if self._anchor is not None and spread <= p.max_spread:
                self._learn(np.asarray(estimate, dtype=np.float64))
            self._anchor = np.array(estimate, dtype=np.float64) if spread <= p.max_spread else None
            self._odo[:] = 0.0
            self._path = 0.0
        vx, vy, omega = float(twist[0]), float(twist[1]), float(twist[2])
        theta = self._odo[2] + 0.5 * omega * dt
        c, s = math.cos(theta), math.sin(theta)
        self._odo[0] += (vx * c - vy * s) * dt
        self._odo[1] += (vx * s + vy * c) * dt
        self._odo[2] += omega * dt
        self._path += math.hypot(vx, vy) * dt

    def _learn(self, estimate: np.ndarray) -> None:
        assert self._anchor is not None
        p = self.params
        chord = math.hypot(self._odo[0], self._odo[1])
        if self._path <= 0 or chord < p.min_straightness * self._path:
            return
        ax, ay, at = self._anchor
        dx, dy = estimate[0] - ax, estimate[1] - ay
        c, s = math.cos(at), math.sin(at)
        moved = np.array([c * dx + s * dy, -s * dx + c * dy])  # the estimate's move, anchor frame
        ratio = float(moved @ self._odo[:2]) / (chord * chord)
        self.scale = min(p.high, max(p.low, self.scale + p.gain * (ratio - self.scale)))
        self.windows_used += 1
