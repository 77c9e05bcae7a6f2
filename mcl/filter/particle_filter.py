"""Monte Carlo Localization: a particle filter over world poses [x, y, theta] on an occupancy map.

One update is ``predict(twist, dt)`` (motion model) then ``correct(scan)`` (sensor model ->
weights -> resampling when the effective sample size is low), then ``estimate()``. ``correct`` is the
composition of public steps so that variants (augmented MCL, KLD-sampling) can replace one of them:

    log_lik = pf.sensor_model.log_evaluate(pf.particles, scan)   # (N,) log-likelihoods
    pf.update_weights(log_lik)                                    # Bayes rule in log space
    if pf.needs_resampling():
        pf.resample()                                             # or pf.set_particles(...)

Global localization and recovery (global starts, KLD-sampling, augmented MCL, the lost flag's
bursts) are [`mcl.filter.recovery`][mcl.filter.recovery]; ``uncertainty()`` gives the covariance,
the clusters of the cloud and an ambiguity flag ([`mcl.filter.uncertainty`][mcl.filter.uncertainty]).

Frames and units: particles are world-frame rear-axle poses (metres, radians, theta in [-pi, pi));
the twist is car-frame [vx, vy, omega] (m/s, m/s, rad/s) of the rear axle; dt in seconds; scans in
metres.

Degenerate weights: when every particle's weight is zero or not finite after a correction (e.g. the
scan matches nothing, or the filter is lost), the filter does not produce NaN. It counts the event in
``n_degenerate`` and, by ``ParticleFilterParams.on_degenerate``, keeps the particles with uniform
weights (``"keep"``) or re-spreads as many uniformly over free space (``"global"``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from mcl.filter.angles import wrap_angle
from mcl.filter.augmented import LikelihoodAverages
from mcl.filter.motion_model import MotionModel, twist_to_odometry
from mcl.filter.odometry_scale import OdometryScale
from mcl.filter.params import ParticleFilterParams, spread_sd
from mcl.filter.place_keeping import PlaceKeeping, resample_keeping_places
from mcl.filter.recovery import GlobalRecovery
from mcl.filter.resampling import resample_particles
from mcl.filter.scan_checks import ScanChecks
from mcl.filter.scan_fit import ScanFit
from mcl.filter.scan_turn import TurnCheck
from mcl.filter.sensor_model import SensorModel
from mcl.filter.standstill import Standstill
from mcl.filter.step_kernels import bayes_step
from racecar_sim.maps import OccupancyMap

__all__ = ["ParticleFilter", "ParticleFilterParams"]


class ParticleFilter(ScanChecks, GlobalRecovery):
    """Monte Carlo Localization on an occupancy map (see the module docstring).

    Args:
        occupancy_map: the map (world frame).
        n_particles: overrides ``params.n_particles`` when given.
        motion_model: defaults to [`MotionModel`][mcl.filter.motion_model.MotionModel] with default parameters.
        sensor_model: defaults to [`SensorModel`][mcl.filter.sensor_model.SensorModel] on ``occupancy_map``.
        params: `ParticleFilterParams`.
        rng: the filter's only source of randomness (a Generator, or a seed for one).

    The filter starts empty: call `initialize()` or `initialize_global()` first.

    Attributes:
        n_updates: corrections applied.
        n_resamples: resampling steps.
        n_degenerate: corrections after which every weight was zero or not finite (see the
            module docstring).
        last_log_mean_likelihood: log of the weighted mean likelihood of the last scan,
            ``log sum_i w_i p(z | x_i)`` with the weights before the correction (for augmented MCL).
        last_effective_sample_size: Kish's effective sample size right after the last weight
            update, before any resampling (NaN before the first).
        averages: the [`LikelihoodAverages`][mcl.filter.augmented.LikelihoodAverages] of augmented MCL.
        pending_random: random particles drawn by the last resampling that join the particles at
            the next correction (augmented MCL).
        n_injected: random particles injected by augmented MCL so far; last_injected: by the last
            correction. n_skipped: scans `correct()` skipped (``update_min_distance``).
        recovery_share: the least share of each resampling's draws that are uniform poses, as
            the lost flag's recovery asked (`request_recovery()`; 0 when not lost).
        place_keeping: None (plain resampling), or how each resampling keeps particles in every
            place with weight ([`mcl.filter.place_keeping`][mcl.filter.place_keeping]).
        scan_exponent: the power each scan's likelihood is raised to (1: Bayes' rule; the
            lost flag's search filter sets both).
    """

    def __init__(
        self,
        occupancy_map: OccupancyMap,
        n_particles: int | None = None,
        motion_model: MotionModel | None = None,
        sensor_model: SensorModel | None = None,
        params: ParticleFilterParams | None = None,
        rng: np.random.Generator | int | None = None,
    ) -> None:
        params = params if params is not None else ParticleFilterParams()
        if n_particles is not None:
            params = replace(params, n_particles=n_particles)
        self.params = params
        self.map = occupancy_map
        self.motion_model = motion_model if motion_model is not None else MotionModel()
        self.sensor_model = sensor_model if sensor_model is not None else SensorModel(occupancy_map)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self._particles: np.ndarray | None = None
        self._log_weights: np.ndarray | None = None
        self._weights: np.ndarray | None = None
        self._mean_memo: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._ess_memo: tuple[np.ndarray | None, float] = (None, math.nan)  # weights, their ESS
        self._uniform = (np.empty(0), np.empty(0))  # the weights, log-weights of the last draw
        self.n_updates = 0
        self.n_resamples = 0
        self.n_degenerate = 0
        self.last_log_mean_likelihood = math.nan
        self.last_effective_sample_size = math.nan
        self.averages = LikelihoodAverages(params.augmented)
        self.n_injected = 0
        self.last_injected = 0
        self.pending_random = 0
        self.pending_local = np.empty((0, 3))  # poses of a local burst that join at the next correction
        self.n_skipped = 0
        self.recovery_share = 0.0
        self._shrink_to: int | None = None  # the count to resample back to after a burst
        self._before_burst: tuple[np.ndarray, np.ndarray, int] | None = None  # for undo_burst
        self._moved = [math.inf, math.inf]  # metres, radians of odometry since the last used scan
        self._global_count: int | None = None
        self.odometry_scale = OdometryScale(scale := params.odometry_scale)
        self._scale_fit = ScanFit(scale.fit_beams, scale.fit_tolerance, skip_short=True)
        self.standstill = Standstill(params.standstill)
        self.turn_check = TurnCheck(params.turn_check)
        self.searching = False  # whether the last correction scored with the wide search hit
        self.place_keeping: PlaceKeeping | None = None
        self.scan_exponent = 1.0

    # ------------------------------------------------------------------ state
    def set_particles(self, particles: np.ndarray, weights: np.ndarray | None = None) -> None:
        """Replace the particles (M, 3) world frame and their weights (uniform when None).

        Theta is wrapped to [-pi, pi); the weights are normalised.

        Raises:
            ValueError: wrong shapes, non-finite poses, or weights that are negative, not finite or
                all zero.
        """
        p = np.array(particles, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
            raise ValueError(f"particles must have shape (M, 3) with M >= 1, got {p.shape}")
        if not np.isfinite(p).all():
            raise ValueError("particles must be finite")
        p[:, 2] = wrap_angle(p[:, 2])
        if weights is None:
            lw = np.full(p.shape[0], -math.log(p.shape[0]))
        else:
            w = np.asarray(weights, dtype=np.float64)
            if w.shape != (p.shape[0],):
                raise ValueError(f"weights must have shape ({p.shape[0]},), got {w.shape}")
            if not (np.isfinite(w).all() and (w >= 0).all() and w.sum() > 0):
                raise ValueError("weights must be finite, non-negative and not all zero")
            with np.errstate(divide="ignore"):
                lw = np.log(w / w.sum())
        self._particles = p
        self._set_log_weights(lw)

    def _set_log_weights(self, log_weights: np.ndarray) -> None:
        """Store log-weights normalised so that the weights sum to 1 (max must be finite)."""
        top = log_weights.max()
        w = np.exp(log_weights - top)
        total = w.sum()
        self._weights = w / total
        self._log_weights = log_weights - (top + math.log(total))

    # ------------------------------------------------------------------ initialisation
    def initialize(
        self,
        pose: np.ndarray,
        spread: float | tuple[float, float, float] | np.ndarray | None = None,
    ) -> None:
        """Particles drawn from a Gaussian around ``pose`` [x, y, theta] (world, metres, radians).

        Args:
            pose: the centre.
            spread: standard deviations (x m, y m, theta rad), one number for all three, or None for
                ``params.init_spread``.
        """
        centre = np.asarray(pose, dtype=np.float64)
        if centre.shape != (3,) or not np.isfinite(centre).all():
            raise ValueError(f"pose must be three finite numbers [x, y, theta], got {pose!r}")
        sd = np.asarray(spread_sd(self.params.init_spread if spread is None else spread, "spread"))
        self.set_particles(self.poses_around(centre, sd, self.params.n_particles))
        self.start_new_belief()

    def start_new_belief(self) -> None:
        """Forget the likelihood history, the recovery state, the moved distance and the
        odometry scale's window (the next scan is always used): what `initialize()` and
        `initialize_global()` do after placing the particles; subclasses extend it."""
        self.averages.reset()
        self.pending_random = 0
        self.pending_local = np.empty((0, 3))
        self.recovery_share, self._shrink_to, self._before_burst = 0.0, None, None
        self._moved = [math.inf, math.inf]
        self.odometry_scale.restart()
        self.standstill.restart()
        self.turn_check.restart()
        self.searching = False

    # ------------------------------------------------------------------ update steps
    def predict(self, twist: np.ndarray, dt: float) -> None:
        """Move the particles by a car-frame twist [vx, vy, omega] held for ``dt`` seconds (the
        calibrated ``odometry_bias`` undone, its forward speed times the learned
        [odometry_scale][mcl.filter.odometry_scale.OdometryScale]);
        by less, or none, while the [standstill][mcl.filter.standstill.Standstill] check says the car
        slips or stands (standing, with ``hold_still``, not even by the motion noise)."""
        self._require()
        twist = np.asarray(twist, dtype=np.float64)
        if twist.shape != (3,) or not all(map(math.isfinite, twist.tolist())):
            raise ValueError(f"twist must be three finite numbers [vx, vy, omega], got {twist!r}")
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"dt must be a non-negative number of seconds, got {dt!r}")
        if not self.params.odometry_bias.is_zero:  # the car's calibrated odometry error
            twist = self.params.odometry_bias.unbiased(twist)
        scale = self.odometry_scale
        self.standstill.advance(scale.scaled(twist), dt)  # as the filter would move
        if self.standstill.slipping:
            twist = self.standstill.scaled(twist)
        scale.observe(twist, dt)  # accounts the raw twist; the scale changes only with a scan
        moved = scale.scaled(twist)
        self.turn_check.advance(moved, dt)
        still = self.standstill.params
        if still.hold_still and self.standstill.standing and (still.hold_searching or not self.searching):
            return  # a car that stands: nothing moved, no motion to be unsure of
        self.move(twist_to_odometry(moved.tolist(), dt))

    def move(self, odometry: np.ndarray) -> None:
        """Move the particles by a car-frame displacement [dx, dy, dtheta] (metres, radians)."""
        particles, _ = self._require()
        model = self.motion_model.while_searching() if self.searching else self.motion_model
        self._particles = model.evaluate(particles, odometry, self.rng)
        dx, dy, dtheta = np.asarray(odometry, dtype=np.float64).tolist()
        self._moved[0] += math.hypot(dx, dy)
        self._moved[1] += abs(dtheta)

    def update_weights(self, log_likelihood: np.ndarray) -> None:
        """Multiply the weights by ``exp(scan_exponent x log_likelihood)`` (N,) and normalise (Bayes
        rule; `scan_exponent` is 1 unless a search tempers its scans).

        NaN and +inf log-likelihoods count as impossible (-inf). When no particle keeps a positive
        weight the filter recovers as ``params.on_degenerate`` says and counts the event.
        """
        particles, _ = self._require()
        ll = np.asarray(log_likelihood, dtype=np.float64)
        if ll.shape != (particles.shape[0],):
            raise ValueError(
                f"log_likelihood must have shape ({particles.shape[0]},), got {ll.shape}"
            )
        self.n_updates += 1
        assert self._log_weights is not None
        if self.scan_exponent != 1.0:
            ll = ll * self.scan_exponent
        lw, w, top, total, sum_w2 = bayes_step(self._log_weights, ll)  # one numba call
        if not math.isfinite(top):
            self.n_degenerate += 1
            self.last_log_mean_likelihood = -math.inf
            if self.params.on_degenerate == "global":
                self.initialize_global(particles.shape[0])  # same count (KLD may grow it)
            else:
                self.set_particles(particles)
            self.last_effective_sample_size = self.effective_sample_size
            return
        self.last_log_mean_likelihood = float(top + math.log(total))
        self._log_weights = lw
        self._weights = w
        self.last_effective_sample_size = float(1.0 / sum_w2)
        self._ess_memo = (w, self.last_effective_sample_size)

    def needs_resampling(self) -> bool:
        """Whether the effective sample size is at most ``resample_threshold`` x N, or augmented
        MCL wants to inject random particles (its injection probability is above 0)."""
        if self.averages.injection_probability > 0.0 or self.recovery_share > 0.0:
            return True
        return self.effective_sample_size <= self.params.resample_threshold * self.n_particles

    def resample(self, n: int | None = None) -> np.ndarray:
        """Draw ``n`` particles by ``params.resampling``; the weights become uniform (with
        `place_keeping`: every place keeps particles, weighted by importance).

        The default count is the current one, or with ``params.kld.enabled`` the count
        KLD-sampling asks for (`kld_count()`). With augmented MCL on, each of the ``n`` draws
        is a random free-space pose with the injection probability p instead: those are kept
        aside in `pending_random` and join the particles at the start of the next
        `correct()`, so that its scan weighs them before any estimate sees them.

        Returns the chosen indexes of the old particles (the drawn, non-random ones).
        """
        particles, weights = self._require()
        p_random = max(self.averages.injection_probability, self.recovery_share)
        if n is None and self.params.kld.enabled:
            n, n_random = self.kld_count(p_random)
        else:
            n = particles.shape[0] if n is None else n
            n_random = int(self.rng.binomial(n, p_random)) if p_random > 0.0 else 0
        n_random = min(n_random, n - 1)  # keep at least one particle of the belief
        n, how = n - n_random, self.params.resampling  # drawn: valid and wrapped, set directly
        if self.place_keeping is not None:  # log-weights: a place's tiny weight must not be 0
            lw = self._log_weights if self._log_weights is not None else np.log(weights)
            idx, lw = resample_keeping_places(particles, lw, self.rng, n, self.place_keeping)
            self._particles = np.ascontiguousarray(particles[idx])
            self._set_log_weights(lw)
        else:
            idx, self._particles = resample_particles(how, particles, weights, self.rng, n)
            if self._uniform[0].shape[0] != n:  # never written in place: shared across draws
                self._uniform = (np.full(n, 1.0 / n), np.full(n, -math.log(n)))
            self._weights, self._log_weights = self._uniform
        self.pending_random = n_random
        self.n_resamples += 1
        return idx

    def should_correct(self) -> bool:
        """Whether the car moved ``update_min_distance`` or turned ``update_min_angle`` since the
        last used scan (always True when both are 0)."""
        p = self.params
        if p.update_min_distance <= 0.0 and p.update_min_angle <= 0.0:
            return True
        moved, turned = self._moved
        return (p.update_min_distance > 0.0 and moved >= p.update_min_distance) or (
            p.update_min_angle > 0.0 and turned >= p.update_min_angle
        )

    def correct(self, scan: np.ndarray) -> bool:
        """Weigh the particles by a scan (metres) and resample if needed; returns whether it did.

        The steps: the per-scan checks that need no map
        ([ScanChecks][mcl.filter.scan_checks.ScanChecks]: a standing car, a missed turn, the
        scale's scans); skip the scan unless `should_correct()`; add the random particles of
        augmented MCL drawn at the last resampling; `update_weights()` with the sensor model's
        log-likelihoods; fold the scan's per-beam likelihood into `averages`;
        `resample()` when `needs_resampling()`.

        See [`SensorModel`][mcl.filter.sensor_model.SensorModel] for the scan's treatment (NaN/inf beams
        dropped, wrong length or negative ranges rejected with ``ValueError``).
        """
        self._require()
        self._check_scans(scan)
        if not self._takes_scan():
            self.n_skipped += 1
            return False
        n_beams = self.sensor_model.observe(scan)[1].size  # checks the scan before any change
        self._moved, self.last_injected = [0.0, 0.0], 0
        shrink_to, self._shrink_to = self._shrink_to, None
        self._before_burst = None if shrink_to is None else (*self._require(), shrink_to)
        self._join_pending_random()
        # averages (augmented MCL) follow the model's own; weights: search hit or beam bound
        own, weighing, squash = self._scan_log_likelihoods(scan)
        if weighing is own:
            self.update_weights(own)
        else:
            _, _, top, total, _ = bayes_step(self._log_weights, own)
            self.update_weights(weighing)
            if math.isfinite(self.last_log_mean_likelihood):
                self.last_log_mean_likelihood = (
                    float(top + math.log(total)) if total > 0 else -math.inf
                )
        if shrink_to is not None:  # a recovery burst: back to the cloud's count (or KLD's)
            self.resample(None if self.params.kld.enabled else shrink_to)
            self._confirm_scale(scan)
            return True
        self.averages.update(self.last_log_mean_likelihood, int(n_beams), squash)
        resampled = self.needs_resampling()
        if resampled:
            self.resample()
        self._confirm_scale(scan)
        return resampled

    def _takes_scan(self) -> bool:
        """Whether `correct()` weighs the scan it was given (else it counts it skipped):
        `should_correct()`."""
        return self.should_correct()

    def _scan_log_likelihoods(self, scan: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(own, weighing, squash) for `correct()`: the (N,) log-likelihoods the averages
        follow and those the cloud is weighed by
        ([SensorModel.weigh][mcl.filter.sensor_model.SensorModel.weigh], the search hit while
        `is_searching()`), and the squash exponent they were computed with."""
        self.searching = self.is_searching()
        own, weighing = self.sensor_model.weigh(self.particles, scan, self.searching)
        return own, weighing, float(self.sensor_model.params.squash_exponent)

    def update(self, twist: np.ndarray, dt: float, scan: np.ndarray | None) -> np.ndarray:
        """``predict``, then ``correct`` when a scan is given, then return ``estimate()``."""
        self.predict(twist, dt)
        if scan is not None:
            self.correct(scan)
        return self.estimate()
