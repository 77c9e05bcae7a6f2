"""One filter for an unknown start: search the map, then track tightly, switching by itself.

A global start needs a filter that is slow to make up its mind: a soft (strongly tempered) beam
model, scans spaced out in distance travelled, wide motion noise so that hypotheses near the car
can climb to it, and many particles kept alive. Tracking needs the opposite: the lab's squash,
every scan, the odometry's own noise and 1-2 k particles. `AdaptiveParticleFilter` is a
[`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter] that does both, in one of two modes decided before
each scan from the cloud itself:

- **searching** (after a global start, or when the cloud spreads out again): squash
  ``search_squash``, a scan every ``search_min_distance`` metres / ``search_min_angle`` radians
  of motion *or* every ``search_max_skipped + 1``-th scan when the car stands still (a car that
  waits at its start still gets localized), motion noise x ``search_noise``, KLD-sampling
  between ``search_min_particles`` and the KLD maximum;
- **tracking** once the position standard deviation is below ``converged_position_sd`` and the
  heading's below ``converged_heading_sd``: the sensor model's own squash, every scan, the motion
  model's noise, KLD between ``track_min_particles`` and ``track_max_particles``. Back to
  searching when the cloud spreads beyond ``lost_position_sd`` / ``lost_heading_sd`` (augmented
  MCL's random particles that win weight do that after a kidnapping).

Measured on the two real Stata basement recordings (README, "Real data"): the plain recovery
filter (squash 0.05 throughout, a scan per 0.1 m) ends 0.4 m off the best-fitting pose and loses
bag 1 in some seeds; this one finds both within 3 s and then trails the lab's tracking filter by
millimetres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from mcl.filter.motion_model import MotionModel
from mcl.filter.particle_filter import ParticleFilter
from racecar_sim.settings.validation import short

__all__ = ["AdaptiveParams", "AdaptiveParticleFilter"]


@dataclass(frozen=True)
class AdaptiveParams:
    """Settings of the two modes (module docstring). Metres, radians; squashes are exponents.

    Attributes:
        search_squash: tempering exponent of the beam model while searching.
        search_min_distance, search_min_angle: motion between two scans used while searching.
        search_max_skipped: while searching, use a scan after this many skipped ones even if the
            car has not moved (0 uses every scan).
        search_noise: factor on the motion model's noise coefficients while searching.
        search_min_particles: KLD-sampling's lower bound while searching.
        track_min_particles: KLD-sampling's lower bound while tracking.
        track_max_particles: KLD-sampling's upper bound while tracking (at least
            ``track_min_particles``; the filter's own bound if lower). Augmented MCL's random
            particles, injected when the scans fit worse than they used to (a real building's
            clutter does that for seconds at a time), each count a KLD bin of their own: without
            this bound a tracking cloud on the real bags grew to 10 000-11 500 particles, most of
            them random, and the replay took 2-3 times as long.
        converged_position_sd, converged_heading_sd: below both, the filter tracks.
        lost_position_sd, lost_heading_sd: above either, a tracking filter searches again.
    """

    search_squash: float = 0.05
    search_min_distance: float = 0.1
    search_min_angle: float = 0.2
    search_max_skipped: int = 2
    search_noise: float = 3.0
    search_min_particles: int = 5000
    track_min_particles: int = 1000
    track_max_particles: int = 3000
    converged_position_sd: float = 0.3
    converged_heading_sd: float = math.radians(10.0)
    lost_position_sd: float = 1.0
    lost_heading_sd: float = math.radians(30.0)

    def __post_init__(self) -> None:
        for name in (
            "search_squash",
            "search_noise",
            "converged_position_sd",
            "converged_heading_sd",
            "lost_position_sd",
            "lost_heading_sd",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < math.inf:
                raise ValueError(f"AdaptiveParams.{name} = {short(v)} must be a positive number")
        for name in ("search_min_distance", "search_min_angle"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 <= v < math.inf:
                raise ValueError(f"AdaptiveParams.{name} = {short(v)} must be a number >= 0")
        for name, low in (
            ("search_max_skipped", 0),
            ("search_min_particles", 1),
            ("track_min_particles", 1),
            ("track_max_particles", 1),
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ValueError(f"AdaptiveParams.{name} = {short(v)} must be an integer >= {low}")
        if self.track_max_particles < self.track_min_particles:
            raise ValueError("AdaptiveParams.track_max_particles must be >= track_min_particles")
        if self.lost_position_sd < self.converged_position_sd:
            raise ValueError("AdaptiveParams.lost_position_sd must be >= converged_position_sd")
        if self.lost_heading_sd < self.converged_heading_sd:
            raise ValueError("AdaptiveParams.lost_heading_sd must be >= converged_heading_sd")


class AdaptiveParticleFilter(ParticleFilter):
    """A particle filter that searches, then tracks (module docstring).

    Takes the arguments of [`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter] plus ``adaptive``
    (`AdaptiveParams`). Its `correct()` is the plain filter's with the current mode's squash and
    scan spacing (the scan also goes to the standstill check and the learned odometry scale, and a
    recovery burst is weighed and shrunk back, as there). The given ``params`` describe the
    tracking filter's resampling, KLD-sampling (its ``max_particles`` bounds the search too) and
    augmented MCL; the sensor model's ``squash_exponent`` is the tracking squash.

    Attributes:
        tracking: True once the cloud has converged (see the module docstring).
        n_mode_switches: how often the mode changed.
    """

    def __init__(self, *args, adaptive: AdaptiveParams | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.adaptive = adaptive if adaptive is not None else AdaptiveParams()
        a, p = self.adaptive, self.params
        kld_max = p.kld.max_particles
        self._track_params = replace(
            p,
            update_min_distance=0.0,
            update_min_angle=0.0,
            kld=replace(
                p.kld,
                min_particles=a.track_min_particles,
                max_particles=max(
                    min(a.track_max_particles, kld_max or a.track_max_particles),
                    a.track_min_particles,
                ),
            ),
        )
        self._search_params = replace(
            p,
            update_min_distance=a.search_min_distance,
            update_min_angle=a.search_min_angle,
            kld=replace(
                p.kld,
                min_particles=a.search_min_particles,
                max_particles=None if kld_max is None else max(kld_max, a.search_min_particles),
            ),
        )
        self._track_motion = self.motion_model
        mp = self.motion_model.params
        self._search_motion = MotionModel(
            replace(
                mp,
                coefficients=tuple(c * a.search_noise for c in mp.coefficients),
                alphas=tuple(v * a.search_noise**2 for v in mp.alphas),  # variances: k² each
            )
        )
        self.tracking = False
        self.n_mode_switches = 0
        self._skipped_in_row = 0
        self._set_mode(False)

    # ------------------------------------------------------------------ modes
    def _set_mode(self, tracking: bool) -> None:
        if tracking != self.tracking:
            self.n_mode_switches += 1
        self.tracking = tracking
        self.params = self._track_params if tracking else self._search_params
        self.motion_model = self._track_motion if tracking else self._search_motion

    @property
    def squash(self) -> float:
        """The tempering exponent the next scan is weighed with."""
        if self.tracking:
            return float(self.sensor_model.params.squash_exponent)
        return self.adaptive.search_squash

    def spread(self) -> tuple[float, float]:
        """(position sd m: sqrt of the largest x-y eigenvalue, heading sd rad) of the cloud."""
        cov = self.covariance()
        top = float(np.linalg.eigvalsh(cov[:2, :2])[-1])
        return math.sqrt(max(top, 0.0)), math.sqrt(max(float(cov[2, 2]), 0.0))

    def _update_mode(self) -> None:
        a = self.adaptive
        pos_sd, head_sd = self.spread()
        if self.tracking:
            if pos_sd > a.lost_position_sd or head_sd > a.lost_heading_sd:
                self._set_mode(False)
        elif pos_sd < a.converged_position_sd and head_sd < a.converged_heading_sd:
            self._set_mode(True)

    def start_new_belief(self) -> None:
        """The filter's new belief, and this filter searches again (a new start is unknown)."""
        super().start_new_belief()
        self._skipped_in_row = 0
        if hasattr(self, "_search_params"):
            self._set_mode(False)

    # ------------------------------------------------------------------ update
    def _takes_scan(self) -> bool:
        """Decide the mode from the cloud, then whether this scan is used: every scan while
        tracking; while searching one per ``search_min_distance`` / ``search_min_angle`` of
        motion, or after ``search_max_skipped`` skipped ones (module docstring)."""
        if self.n_updates > 0:
            self._update_mode()
        use = self.should_correct() or (
            not self.tracking and self._skipped_in_row >= self.adaptive.search_max_skipped
        )
        self._skipped_in_row = 0 if use else self._skipped_in_row + 1
        return use

    def _scan_log_likelihoods(self, scan: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """The scan's log-likelihoods at the current mode's squash (`squash`), the wide search
        hit while the cloud searches; the same array weighs the cloud and feeds the averages."""
        squash = self.squash
        factor = squash / float(self.sensor_model.params.squash_exponent)
        log_likelihood = (
            self.sensor_model.log_evaluate(self.particles, scan, self.is_searching()) * factor
        )
        return log_likelihood, log_likelihood, squash
