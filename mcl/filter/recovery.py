"""Global localization and recovery of the particle filter: uniform poses over free space at a
global start, when augmented MCL injects them, and when the lost flag asks for a burst; the count
of particles KLD-sampling keeps; and when the sensor model scores with its wide search hit.

[`GlobalRecovery`][mcl.filter.recovery.GlobalRecovery] is a base of
[`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter], which holds the particles and the
fields used here. Frames and units: world poses [x, y, theta] (metres, radians).

Global localization and recovery (KLD-sampling, augmented MCL and scan spacing are off by default,
so the plain filter's draws are unchanged):

- [`initialize_global()`][mcl.filter.recovery.GlobalRecovery.initialize_global] spreads [`global_particle_count()`][mcl.filter.recovery.GlobalRecovery.global_particle_count]
  particles over free space, by default ``global_density`` per square metre of free floor
  (at least ``n_particles``, at most ``global_max_particles``).
- KLD-sampling ([`mcl.filter.kld`][mcl.filter.kld], ``params.kld``) picks the particle count at every resampling, so the
  many particles of a global start shrink to a few hundred once the cloud has converged.
- Augmented MCL ([`mcl.filter.augmented`][mcl.filter.augmented], ``params.augmented``) follows the slow and fast averages of
  the scan likelihood; while ``p = max(0, 1 - w_fast / w_slow)`` is above 0 the filter resamples,
  and each draw of the resampling is a random free-space pose with probability p (Table 8.3). With
  KLD-sampling on, each random draw counts as a bin of its own, so a lost filter grows its set (as
  ROS amcl). The random poses join the particles at the start of the next correction instead of
  right away, so that a scan weighs them before any estimate sees them (a fraction p of uniformly
  weighted random poses would otherwise drag the mean pose across the map).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mcl.filter.kld import kld_count
from mcl.filter.odometry_scale import OdometryScale
from mcl.filter.params import ParticleFilterParams
from mcl.filter.standstill import Standstill
from racecar_sim.maps import OccupancyMap

__all__ = ["GlobalRecovery"]


class GlobalRecovery:
    """Global starts, injected and burst uniform poses, KLD's count and the search decision
    (fields set by [`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter])."""

    params: ParticleFilterParams
    map: OccupancyMap
    rng: np.random.Generator
    sensor_model: Any
    pending_random: int
    pending_local: np.ndarray
    last_injected: int
    n_injected: int
    recovery_share: float
    searching: bool
    _global_count: int | None
    _shrink_to: int | None
    _before_burst: tuple[np.ndarray, np.ndarray, int] | None
    odometry_scale: OdometryScale
    standstill: Standstill

    def moved_elsewhere(self) -> None:
        """The cloud was moved to another place other than by the odometry and the scans (a
        burst's outcome kept, the search's cloud taken, a jump): the odometry scale's bridge,
        the standstill check's recorded estimates and the turn check's window span the move,
        and are dropped."""
        self.odometry_scale.restart()
        self.standstill.cloud_replaced()
        self.turn_check.restart()

    def global_particle_count(self) -> int:
        """Particles of a global start: ``params.global_particles`` when given, else
        ``global_density`` x the map's free area (m²), at least ``n_particles``, at most
        ``global_max_particles`` (or ``n_particles`` when that is larger)."""
        p = self.params
        if p.global_particles is not None:
            return p.global_particles
        if self._global_count is None:
            by_area = math.ceil(p.global_density * self.map.free_area)
            self._global_count = max(p.n_particles, min(by_area, p.global_max_particles))
        return self._global_count

    @property
    def max_particles(self) -> int:
        """Most particles KLD-sampling may keep: ``kld.max_particles`` or the global count."""
        kld_max = self.params.kld.max_particles
        return kld_max if kld_max is not None else self.global_particle_count()

    def initialize_global(self, n_particles: int | None = None) -> None:
        """Particles uniform over the map's free space, headings uniform in [-pi, pi).

        Args:
            n_particles: how many; None for `global_particle_count()`.
        """
        n = self.global_particle_count() if n_particles is None else n_particles
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"n_particles must be a positive integer, got {n_particles!r}")
        self.set_particles(self.random_free_poses(int(n)))
        self.start_new_belief()

    def random_free_poses(self, n: int) -> np.ndarray:
        """(n, 3) world poses uniform over free space (``global_clearance``), from the filter's rng."""
        return self.map.sample_free_poses(self.rng, n, clearance=self.params.global_clearance)

    def kld_count(self, p_random: float = 0.0) -> tuple[int, int]:
        """(particles, of which random) that KLD-sampling asks for ([`mcl.filter.kld`][mcl.filter.kld]).

        Draws batches of the weighted particles (multinomial, independent), each draw replaced with
        probability ``p_random`` by a random pose that counts as a bin of its own, doubling the
        batch until Fox's rule stops or `max_particles` draws are made.
        """
        particles, weights = self._require()
        return kld_count(
            particles, weights, self.params.kld, self.max_particles, self.rng, p_random
        )

    def _join_pending_random(self) -> None:
        """Add the random particles kept aside by `resample()` and the poses of a local burst
        (`request_local_burst()`), each with the mean weight."""
        local = self.pending_local
        k = self.pending_random + local.shape[0]
        if k <= 0:
            return
        particles, weights = self._require()
        n = particles.shape[0]
        total = n + k
        new = np.concatenate([self.random_free_poses(self.pending_random), local])
        w = np.concatenate([weights * (n / total), np.full(k, 1.0 / total)])
        self.set_particles(np.concatenate([particles, new]), w)
        self.pending_random = 0
        self.pending_local = np.empty((0, 3))
        self.last_injected = k
        self.n_injected += k

    def is_searching(self) -> bool:
        """Whether the next correction scores with the sensor model's wide search hit: random
        particles just joined, or the cloud's position spread exceeds ``search_start_spread``
        metres (a tracking filter) or ``search_spread`` (a searching one: hysteresis)."""
        if self.last_injected > 0:
            return True
        covariance = self.covariance()
        spread = math.sqrt(max(0.0, covariance[0, 0] + covariance[1, 1]))
        params = self.sensor_model.params
        return spread > (params.search_spread if self.searching else params.search_start_spread)

    def request_recovery(self, share: float, burst: int = 0) -> None:
        """Recovery asked for by the lost flag ([LostDetector][mcl.filter.lost.LostDetector]).

        Args:
            share: from now on (until asked again) each resampling replaces at least this
                fraction of its draws by uniform free-space poses (as augmented MCL's injection),
                and every correction resamples; 0 stops it.
            burst: uniform free-space poses that join the cloud at the next correction, are
                weighed by its scan with the cloud, after which the cloud is resampled back to
                its present count (KLD-sampling's count when it is on).
        """
        self.recovery_share = float(share)
        if burst > 0:
            self._mark_burst()
            self.pending_random += int(burst)

    def request_local_burst(self, n: int, position_sd: float, heading_sd: float) -> None:
        """A burst of ``n`` poses around the current estimate (`poses_around()`: ``position_sd``
        metres on each axis, ``heading_sd`` radians) that join the cloud at the next correction
        and are weighed with it, after which the cloud is resampled back to its present count,
        as a burst of `request_recovery()`; `undo_burst()` takes it back."""
        if n <= 0:
            return
        poses = self.poses_around(self.estimate(), (position_sd, position_sd, heading_sd), n)
        self._mark_burst()
        self.pending_local = np.concatenate([self.pending_local, poses])

    def poses_around(self, centre: np.ndarray, sd: Any, n: int) -> np.ndarray:
        """(n, 3) world poses drawn from a Gaussian around ``centre`` [x m, y m, theta rad] with
        standard deviations ``sd`` (x m, y m, theta rad), from the filter's generator; headings
        not wrapped (`set_particles()` wraps them)."""
        return np.asarray(centre, dtype=np.float64) + self.rng.standard_normal((int(n), 3)) * sd

    def _mark_burst(self) -> None:
        """A burst joins at the next correction: remember the count that correction would
        have had, to resample back to."""
        if self._shrink_to is None:
            self._shrink_to = self.n_particles + self.pending_random

    @property
    def burst_prior(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(particles, weights) as they were before the last correction's recovery burst joined
        them, or None when that correction had no burst (read-only views)."""
        if self._before_burst is None:
            return None
        p, w = self._before_burst[0].view(), self._before_burst[1].view()
        p.flags.writeable = w.flags.writeable = False
        return p, w

    def undo_burst(self) -> None:
        """Go back to the cloud of `burst_prior` (moved and weighed as it was before the
        burst), resampled to the count the burst's correction resampled to."""
        if self._before_burst is None:
            raise RuntimeError("undo_burst: the last correction had no recovery burst")
        particles, weights, count = self._before_burst
        self._before_burst = None
        self.set_particles(particles, weights)
        self.resample(None if self.params.kld.enabled else count)
