"""The particle filter's settings (`ParticleFilterParams`): counts, resampling, recovery, KLD.

Validated once when built; nested settings (``augmented``, ``kld``, ``clusters``) may be given as
mappings (e.g. from YAML).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mcl.filter.augmented import AugmentedParams
from mcl.filter.bounds import FILTER_BOUNDS, check_filter
from mcl.filter.kld import KLDParams
from mcl.filter.odometry_scale import OdometryScaleParams
from mcl.filter.resampling import RESAMPLERS
from mcl.filter.scan_turn import TurnCheckParams
from mcl.filter.standstill import StandstillParams
from mcl.filter.uncertainty import ClusterParams
from racecar_sim.sensors.scan_effects import OdometryBias
from racecar_sim.settings.config import nested
from racecar_sim.settings.validation import short

__all__ = ["DEFAULT_PARTICLES", "ParticleFilterParams", "spread_sd"]

DEFAULT_PARTICLES = 1500
"""Particles of a tracking filter when nobody says otherwise: the filter, the wrapper, every run and
command (1 500 x 100 beams updates in ~2.5 ms on one thread: see the README's Performance)."""

_THRESHOLD_WORDS = {"always": 1.0, "never": 0.0}
_ON_DEGENERATE = ("keep", "global")


@dataclass(frozen=True)
class ParticleFilterParams:
    """Parameters of the particle filter.

    Attributes:
        n_particles: number of particles.
        resampling: ``"systematic"`` (low variance), ``"multinomial"`` (the MIT RSS lab) or
            ``"stratified"``.
        resample_threshold: resample when the effective sample size is at most this fraction of
            the particle count. ``"always"`` (= 1.0) resamples after every correction like the lab;
            ``"never"`` (= 0.0) never does.
        on_degenerate: what to do when every weight is zero or not finite: ``"keep"`` the particles
            with uniform weights, or re-spread them over free space (``"global"``).
        init_spread: default standard deviations (metres, metres, radians) of `initialize()`.
        global_clearance: metres; `initialize_global()` and augmented MCL draw positions at
            least this far from any occupied cell (0 allows every free cell).
        global_particles: particles of `initialize_global()`; None sizes the count from the
            map's free area (see ``global_density``).
        global_density: particles per square metre of free floor for a global start.
        global_max_particles: cap on the count sized from the free area.
        update_min_distance: metres the odometry must have moved (or ``update_min_angle``
            radians turned) since the last used scan before `correct()` uses another one;
            0 for both uses every scan. As ROS amcl's ``update_min_d`` / ``update_min_a``:
            scans taken at 40 Hz from almost the same pose are far from independent, and
            weighing them all makes the filter overconfident before the car has seen what
            tells similar places apart.
        update_min_angle: radians, see ``update_min_distance``.
        augmented: [`AugmentedParams`][mcl.filter.augmented.AugmentedParams] (alphas 0: off).
        kld: [`KLDParams`][mcl.filter.kld.KLDParams] (``enabled=False``: fixed count).
        clusters: [`ClusterParams`][mcl.filter.uncertainty.ClusterParams] of `uncertainty()`.
        odometry_bias: [OdometryBias][racecar_sim.sensors.scan_effects.OdometryBias]: the car's
            odometry error as calibrated (it reads true x (1 + scale) + offset per [vx, vy,
            omega]; ``racecar-sim calibrate-noise`` measures it from the car's recordings: the MIT
            racecar's VESC reads vx 5.3 % low and 0.029 m/s under, omega 10.1 % high); the filter's
            predict undoes it before anything else (``racecar-sim replay`` moves its filter by a
            bag's odometry as recorded). Zero (the default): the odometry is taken as read.
        odometry_scale: [OdometryScaleParams][mcl.filter.odometry_scale.OdometryScaleParams]: the forward
            speed scale learned online from where the scan pins the car (on by default).
        standstill: [StandstillParams][mcl.filter.standstill.StandstillParams]: predict no
            motion while the scans say the car stands and the odometry says it drives (wheels
            turning against a wall; on by default).
        turn_check: [TurnCheckParams][mcl.filter.scan_turn.TurnCheckParams]: turn the cloud
            when the scans and the odometry agree that the car turned and the estimate did not
            (on by default).
    """

    n_particles: int = DEFAULT_PARTICLES
    resampling: str = "systematic"
    resample_threshold: float | str = 0.5
    on_degenerate: str = "keep"
    init_spread: tuple[float, float, float] = (0.5, 0.5, 0.3)
    global_clearance: float = 0.0
    global_particles: int | None = None
    global_density: float = 20.0
    global_max_particles: int = 20000
    update_min_distance: float = 0.0
    update_min_angle: float = 0.0
    augmented: AugmentedParams = field(default_factory=AugmentedParams)
    kld: KLDParams = field(default_factory=KLDParams)
    odometry_bias: OdometryBias = field(default_factory=OdometryBias)
    odometry_scale: OdometryScaleParams = field(default_factory=OdometryScaleParams)
    clusters: ClusterParams = field(default_factory=ClusterParams)
    standstill: StandstillParams = field(default_factory=StandstillParams)
    turn_check: TurnCheckParams = field(default_factory=TurnCheckParams)

    def __post_init__(self) -> None:
        owner = "ParticleFilterParams"  # bounds and their reasons: mcl.filter.bounds
        check_filter(owner, "n_particles", self.n_particles, "filter.n_particles")
        if self.global_particles is not None:
            check_filter(
                owner, "global_particles", self.global_particles, "filter.global_particles"
            )
        for name in ("global_max_particles", "global_density", "global_clearance",
                     "update_min_distance", "update_min_angle"):  # fmt: skip
            check_filter(owner, name, getattr(self, name), f"filter.{name}")
        if self.resampling not in RESAMPLERS:
            raise ValueError(
                f"ParticleFilterParams.resampling = {short(self.resampling)}; "
                f"choose one of {sorted(RESAMPLERS)}"
            )
        thr = self.resample_threshold
        if isinstance(thr, str):
            thr = _THRESHOLD_WORDS.get(thr, thr)
        if isinstance(thr, bool) or not isinstance(thr, int | float) or not 0.0 <= thr <= 1.0:
            raise ValueError(
                f"ParticleFilterParams.resample_threshold = {short(self.resample_threshold)} must be a "
                "fraction in [0, 1], 'always' or 'never'"
            )
        object.__setattr__(self, "resample_threshold", float(thr))
        if self.on_degenerate not in _ON_DEGENERATE:
            raise ValueError(
                f"ParticleFilterParams.on_degenerate = {short(self.on_degenerate)}; "
                f"choose one of {list(_ON_DEGENERATE)}"
            )
        object.__setattr__(self, "init_spread", spread_sd(self.init_spread, "init_spread"))
        for v in self.init_spread:
            check_filter(owner, "init_spread", v, "filter.init_spread")
        c = self.global_clearance
        if (
            isinstance(c, bool)
            or not isinstance(c, int | float)
            or not (math.isfinite(c) and c >= 0)
        ):
            raise ValueError(
                f"ParticleFilterParams.global_clearance = {short(c)} must be >= 0 metres"
            )
        g = self.global_particles
        if g is not None and (isinstance(g, bool) or not isinstance(g, int) or g < 1):
            raise ValueError(
                f"ParticleFilterParams.global_particles = {short(g)} must be None or a positive integer"
            )
        for name in ("global_density", "update_min_distance", "update_min_angle"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 <= v < math.inf:
                raise ValueError(f"ParticleFilterParams.{name} = {short(v)} must be a number >= 0")
        gmax = self.global_max_particles
        if isinstance(gmax, bool) or not isinstance(gmax, int) or gmax < 1:
            raise ValueError(
                f"ParticleFilterParams.global_max_particles = {short(gmax)} must be a positive integer"
            )
        for name, cls in (
            ("augmented", AugmentedParams),
            ("kld", KLDParams),
            ("clusters", ClusterParams),
            ("odometry_bias", OdometryBias),
            ("odometry_scale", OdometryScaleParams),
            ("standstill", StandstillParams),
            ("turn_check", TurnCheckParams),
        ):
            object.__setattr__(
                self, name, nested(getattr(self, name), cls, f"ParticleFilterParams.{name}")
            )
        if not all(s > -0.9 for s in self.odometry_bias.scale):
            raise ValueError(
                f"ParticleFilterParams.odometry_bias.scale = {self.odometry_bias.scale} must be > "
                "-0.9 in each component (odometry that reads under a tenth of the motion)"
            )


def spread_sd(
    value: float | tuple[float, ...] | np.ndarray, name: str
) -> tuple[float, float, float]:
    """One number (all three) or three standard deviations (x m, y m, theta rad), non-negative
    and at most ``filter.init_spread``'s bound (10 km: wider than any map)."""
    most = FILTER_BOUNDS["filter.init_spread"].high
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.size == 1:
        arr = np.repeat(arr, 3)
    if arr.size != 3 or not (np.isfinite(arr).all() and (arr >= 0).all() and (arr <= most).all()):
        raise ValueError(
            f"{name} must be one or three numbers in [0, {most:g}] (m, m, rad), got {short(value)}"
        )
    return (float(arr[0]), float(arr[1]), float(arr[2]))
