"""Odometry speed scale learned online: the filter's answer to wheels that under- or over-report.

Wheel odometry has a speed scale error (the MIT racecar's VESC reports about 5 % less than the car
drives: ``docs/honest_noise.md``). Where the scan pins the car along its path the filter corrects
it; in a long corridor, and worse where the map is out of date, nothing does, and the estimate falls
behind the car at the scale error times the speed (0.1 m/s at 2 m/s: a metre in ten seconds).

[OdometryScale][mcl.filter.odometry_scale.OdometryScale] learns the scale one of two ways
(``source``):

- ``"scans"`` (the default): from **consecutive scans matched to each other**, no map involved
  ([ScanScale][mcl.filter.scan_scale.ScanScale]): every ``scans.spacing`` metres of travel the
  newest scan is matched to the one before it over the odometry's forward travel times a scale,
  and the scale is the matched travel over the odometry's, summed over the pairs. The world
  agrees with itself wherever it stands still, whatever the map says; on the 80 honest drives of
  ``docs/localization_changing_world.md`` it lost 9, 9 and 8 drives in three draws of the
  filter's random numbers where the bridges below lost 13, 14 and 13.
- ``"map"``: **between poses the scan confirms** against the map, the bridges below.

A pose is confirmed when the scan fit at the filter's
estimate ([`mcl.filter.scan_fit`][mcl.filter.scan_fit], the fraction of beams the filter's map
explains, averaged over the last ``fit_scans`` corrected scans) is at least ``fit_gate`` and the
cloud's position spread is at most ``max_spread``. From one confirmed pose to the next at least
``window`` metres of odometry travel later (a *bridge*), it integrates the raw odometry's
displacement along the estimate's heading (the heading is taken from the estimate at every
corrected scan, so turns do not mix heading and speed errors) and compares it with the estimate's
displacement: the bridge's ratio is their dot product over the odometry's squared length. The
scale is the mean of the bridges' ratios weighted by their lengths, with ``initial`` counted as
``prior_metres`` of bridges; it is clipped to [``low``, ``high``]. The first ``settle_bridges``
bridges after a start (the cloud still settling on the car) are not used, nor bridges whose
odometry displacement is under ``min_straightness`` of the path driven, nor, once ``max_bridge``
metres have passed without a confirmed pose, the bridge in progress (the next confirmed pose
starts a new one).

Why bridges between confirmed poses, when the map is the source: where the map is out of date,
the scan drags the estimate back along a corridor; a learner that compared every window saw the
estimate move 0.85-0.95 of the odometry there and followed the drag, which let the estimate fall
further behind. The drag's poses fit the old map poorly (0.48-0.79 of the beams in the honest
world's cluttered seed 9) and are not confirmed; a bridge over them ends where the scan confirms
the car again, after the estimate has caught up. The weighted mean does not let one short bridge
move the scale far. Where the scan says nothing along the path the estimate follows the scaled
odometry, the ratios equal the scale, and the scale stays. But where the old map fits poorly at
the car's own place, few poses are confirmed and the scale is learned late or not at all: that is
why the scans are the default.

A car whose odometry has been calibrated (``racecar-sim calibrate-noise`` measures the wheels'
speed bias from the car's own recordings: the MIT racecar's VESC reads 5.3 % slow, a scale of
1 / (1 - 0.053) = 1.056) can start from that scale (``initial``) and hold it (``learn=False``).
The whole calibration (scale and offset of each of vx, vy, omega) goes in
``filter.odometry_bias``.

Units: metres, radians, seconds; the scale is dimensionless (1 = trust the wheels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mcl.filter.bounds import check_filter
from mcl.filter.scan_scale import ScanScale, ScanScaleParams
from racecar_sim.settings.params import nested
from racecar_sim.settings.validation import short

__all__ = ["SOURCES", "OdometryScale", "OdometryScaleParams"]

SOURCES = ("map", "scans")
"""Where the scale is learned from: ``"map"``, bridges between poses the scan confirms against
the map (module docstring); ``"scans"``, consecutive scans matched to each other, no map involved
([ScanScale][mcl.filter.scan_scale.ScanScale])."""


@dataclass(frozen=True)
class OdometryScaleParams:
    """Settings of the learned odometry speed scale (module docstring).

    Attributes:
        enabled: apply the scale (False: the odometry is used as reported).
        initial: the scale at the start (dimensionless; 1 = trust the wheels, 1.056 = wheels that
            read 5.3 % slow), e.g. from a calibration of the car's odometry.
        learn: learn the scale online from the estimate (False: hold ``initial``).
        window: metres of odometry travel a bridge spans at least (this and the settings
            down to ``min_straightness``: ``source="map"`` only).
        max_bridge: metres of odometry travel after which a bridge with no confirmed pose at its
            end is dropped.
        prior_metres: metres of bridges that ``initial`` counts as in the weighted mean.
        settle_bridges: bridges not used after a start (the cloud settling on the car).
        fit_gate: a pose is confirmed when the mean scan fit (fraction of beams) at the
            estimate over the last ``fit_scans`` corrected scans is at least this.
        fit_scans: corrected scans the fit is averaged over.
        fit_beams: beams of the scan the fit compares (evenly spaced).
        fit_tolerance: metres; a beam agrees when its range is this close to the cast.
        low: smallest scale (the wheels over-report by at most 1 / low - 1).
        high: largest scale.
        max_spread: metres; a pose is confirmed only when the cloud's position standard
            deviation (square root of the covariance's xy trace) is at most this.
        min_straightness: a bridge is used only when its odometry displacement (along the
            estimate's heading) is at least this fraction of the path driven.
        source: ``"scans"`` (consecutive scans matched to each other,
            [ScanScale][mcl.filter.scan_scale.ScanScale]; the bridges' settings unused) or
            ``"map"`` (bridges between poses the scan confirms, module docstring).
        scans: [ScanScaleParams][mcl.filter.scan_scale.ScanScaleParams] of ``"scans"``.
    """

    enabled: bool = True
    initial: float = 1.0
    learn: bool = True
    window: float = 2.0
    max_bridge: float = 40.0
    prior_metres: float = 5.0
    settle_bridges: int = 1
    fit_gate: float = 0.85
    fit_scans: int = 3
    fit_beams: int = 100
    fit_tolerance: float = 0.2
    low: float = 0.8
    high: float = 1.25
    max_spread: float = 0.3
    min_straightness: float = 0.5
    source: str = "scans"
    scans: ScanScaleParams = field(default_factory=ScanScaleParams)

    def __post_init__(self) -> None:
        if self.source not in SOURCES:
            raise ValueError(
                f"OdometryScaleParams.source = {short(self.source)}; choose one of {list(SOURCES)}"
            )
        object.__setattr__(
            self, "scans", nested(self.scans, ScanScaleParams, "OdometryScaleParams.scans")
        )
        for name in ("enabled", "learn"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"OdometryScaleParams.{name} = {short(getattr(self, name))} must be a bool"
                )
        for name in ("settle_bridges", "fit_scans", "fit_beams"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ValueError(
                    f"OdometryScaleParams.{name} = {short(value)} must be a whole number"
                )
        for name in (
            "initial", "window", "max_bridge", "prior_metres", "fit_gate", "fit_tolerance",
            "low", "high", "max_spread", "min_straightness",
        ):  # fmt: skip
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
        if self.max_bridge < self.window:
            raise ValueError(
                f"OdometryScaleParams.max_bridge = {self.max_bridge!r} must be at least window "
                f"= {self.window!r}"
            )
        if self.prior_metres <= 0:
            raise ValueError(
                f"OdometryScaleParams.prior_metres = {self.prior_metres!r} must be > 0"
            )
        if self.settle_bridges < 0:
            raise ValueError(
                f"OdometryScaleParams.settle_bridges = {self.settle_bridges!r} must be >= 0"
            )
        if self.fit_scans < 1 or self.fit_beams < 1:
            raise ValueError(
                f"OdometryScaleParams: fit_scans = {self.fit_scans!r} and fit_beams = "
                f"{self.fit_beams!r} must be >= 1"
            )
        if not 0.0 <= self.fit_gate <= 1.0:
            raise ValueError(f"OdometryScaleParams.fit_gate = {self.fit_gate!r} must be in [0, 1]")
        if self.fit_tolerance <= 0:
            raise ValueError(
                f"OdometryScaleParams.fit_tolerance = {self.fit_tolerance!r} must be > 0"
            )
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

    The filter calls [observe][mcl.filter.odometry_scale.OdometryScale.observe] with every step's
    odometry, [observe_scan][mcl.filter.odometry_scale.OdometryScale.observe_scan] with every scan
    (``source="scans"``) and [confirm][mcl.filter.odometry_scale.OdometryScale.confirm] after every
    corrected scan (``source="map"``).

    Args:
        params: the settings.

    Attributes:
        scale: the scale in use (dimensionless).
        bridges_used: bridges (``"map"``) or pairs of scans (``"scans"``) that moved the scale.
    """

    def __init__(self, params: OdometryScaleParams) -> None:
        self.params = params
        self.scale = params.initial
        self.bridges_used = 0
        self._weighted = params.prior_metres * params.initial  # sum of ratio x length, metres
        self._metres = params.prior_metres  # sum of lengths, metres
        self._fits: list[float] = []  # the last corrected scans' fits
        self._anchor: np.ndarray | None = None  # estimate [x, y] where the bridge started
        self._odometry = np.zeros(2)  # raw odometry displacement since the anchor, world frame
        self._heading = 0.0  # radians, world: the estimate's at the last scan, then odometry's
        self._path = 0.0  # metres of raw odometry travel since the anchor
        self._settling = params.settle_bridges
        self._scans = ScanScale(params.scans, params.initial) if params.source == "scans" else None

    @property
    def learning(self) -> bool:
        """Whether the scale is learned from bridges between confirmed poses (enabled,
        ``learn`` and ``source="map"``)."""
        return self.params.enabled and self.params.learn and self._scans is None

    @property
    def wants_scans(self) -> bool:
        """Whether the scale is learned from the scans matched to each other (enabled, ``learn``
        and ``source="scans"``): [observe_scan][mcl.filter.odometry_scale.OdometryScale.observe_scan]
        wants every scan."""
        return self.params.enabled and self.params.learn and self._scans is not None

    def restart(self) -> None:
        """Forget the bridge in progress and the recent fits (a new episode, a global start, a
        jump); the scale and what it learned are kept, and the next ``settle_bridges`` bridges
        are not used."""
        self.drop_bridge()
        self._settling = self.params.settle_bridges
        if self._scans is not None:
            self._scans.restart()

    def drop_bridge(self) -> None:
        """Forget the bridge in progress and the recent fits (the estimate was moved by other
        than the odometry, e.g. the motion the standstill check took back); what was learned is
        kept and the next bridge counts."""
        self._anchor = None
        self._fits.clear()
        self._odometry[:] = 0.0
        self._path = 0.0

    @property
    def evidence(self) -> tuple[float, float]:
        """What the scale was learned from: (sum of the bridges' ratios times their lengths,
        sum of their lengths), both in metres, the initial scale's ``prior_metres`` included."""
        return self._weighted, self._metres

    @property
    def scan_scale(self) -> ScanScale | None:
        """The scans' learner of ``source="scans"`` (None with ``"map"``)."""
        return self._scans

    def take(self, other: OdometryScale) -> None:
        """Start from what ``other`` learned (its scale and evidence), e.g. a search filter beside
        the filter."""
        self.scale = other.scale
        self._weighted, self._metres = other.evidence
        if self._scans is not None and other.scan_scale is not None:
            self._scans.take(other.scan_scale)

    def scaled(self, twist: np.ndarray) -> np.ndarray:
        """``twist`` [vx m/s, vy m/s, omega rad/s] with its forward speed times the scale."""
        if not self.params.enabled or self.scale == 1.0:
            return twist
        out = np.array(twist, dtype=np.float64)
        out[0] *= self.scale
        return out

    def observe(self, twist: np.ndarray, dt: float) -> None:
        """Account for one step of raw odometry ``twist`` [vx m/s, vy m/s, omega rad/s] (car
        frame) held ``dt`` seconds."""
        if self._scans is not None and self.wants_scans:
            self._scans.observe(twist, dt)
        if self._anchor is None or not self.learning:
            return
        vx, vy, omega = float(twist[0]), float(twist[1]), float(twist[2])
        theta = self._heading + 0.5 * omega * dt
        c, s = math.cos(theta), math.sin(theta)
        self._odometry[0] += (vx * c - vy * s) * dt
        self._odometry[1] += (vx * s + vy * c) * dt
        self._heading += omega * dt
        self._path += math.hypot(vx, vy) * dt

    def observe_scan(
        self, ranges: np.ndarray, angles: np.ndarray, mount: np.ndarray, max_range: float
    ) -> None:
        """``source="scans"``: a new scan (``ranges`` metres at ``angles`` radians, lidar frame;
        the lidar's ``mount`` pose in the car frame), matched to the one ``scans.spacing`` metres
        before it ([ScanScale][mcl.filter.scan_scale.ScanScale]); the scale follows the matches,
        clipped to [``low``, ``high``]."""
        if self._scans is not None and self.wants_scans:
            if self._scans.observe_scan(ranges, angles, mount, max_range):
                p = self.params
                self.scale = min(p.high, max(p.low, self._scans.scale))
                self.bridges_used = self._scans.pairs_used

    def confirm(self, estimate: np.ndarray, spread: float, fit: float) -> None:
        """After a corrected scan: the filter's ``estimate`` (world [x m, y m, theta rad]), its
        position spread (metres) and the scan fit there (a fraction of beams,
        [ScanFit][mcl.filter.scan_fit.ScanFit] with ``fit_beams`` and ``fit_tolerance``; NaN when
        no beam counted); ends a bridge at a confirmed pose."""
        if not self.learning:
            return
        p = self.params
        self._fits.append(float(fit))
        del self._fits[: -p.fit_scans]
        fits = [f for f in self._fits if math.isfinite(f)]
        confirmed = bool(fits) and sum(fits) / len(fits) >= p.fit_gate and spread <= p.max_spread
        here = np.asarray(estimate, dtype=np.float64)
        if self._anchor is not None and self._path >= p.window and confirmed:
            self._learn(here)
            self._start_bridge(here)
        elif self._anchor is not None and self._path >= p.max_bridge:
            self._anchor = None
        elif self._anchor is None and confirmed:
            self._start_bridge(here)
        self._heading = float(here[2])

    def _start_bridge(self, estimate: np.ndarray) -> None:
        self._anchor = estimate[:2].copy()
        self._odometry[:] = 0.0
        self._path = 0.0

    def _learn(self, estimate: np.ndarray) -> None:
        assert self._anchor is not None
        p = self.params
        length = math.hypot(self._odometry[0], self._odometry[1])
        if self._settling > 0:
            self._settling -= 1
            return
        if length <= 0 or length < p.min_straightness * self._path:
            return
        moved = estimate[:2] - self._anchor
        ratio = float(moved @ self._odometry) / (length * length)
        self._weighted += ratio * length
        self._metres += length
        self.scale = min(p.high, max(p.low, self._weighted / self._metres))
        self.bridges_used += 1
