"""Monte Carlo Localization: a particle filter over world poses [x, y, theta] on an occupancy map.

One update is ``predict(twist, dt)`` (motion model) then ``correct(scan)`` (sensor model ->
weights -> resampling when the effective sample size is low), then ``estimate()``. ``correct`` is the
composition of public steps so that variants (augmented MCL, KLD-sampling) can replace one of them:

    log_lik = pf.sensor_model.log_evaluate(pf.particles, scan)   # (N,) log-likelihoods
    pf.update_weights(log_lik)                                    # Bayes rule in log space
    if pf.needs_resampling():
        pf.resample()                                             # or pf.set_particles(...)

Frames and units: particles are world-frame rear-axle poses (metres, radians, theta in [-pi, pi));
the twist is car-frame [vx, vy, omega] (m/s, m/s, rad/s) of the rear axle; dt in seconds; scans in
metres.

Degenerate weights: when every particle's weight is zero or not finite after a correction (e.g. the
scan matches nothing, or the filter is lost), the filter does not produce NaN. It counts the event in
``n_degenerate`` and, by ``ParticleFilterParams.on_degenerate``, keeps the particles with uniform
weights (``"keep"``) or re-spreads them uniformly over free space (``"global"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from mcl.angles import circular_mean, wrap_angle
from mcl.motion_model import MotionModel, twist_to_odometry
from mcl.resampling import RESAMPLERS, resample
from mcl.sensor_model import SensorModel
from racecar_sim.maps import OccupancyMap

__all__ = ["ParticleFilter", "ParticleFilterParams"]

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
        init_spread: default standard deviations (metres, metres, radians) of :meth:`initialize`.
        global_clearance: metres; :meth:`initialize_global` draws positions at least this far from
            any occupied cell (0 allows every free cell).
    """

    n_particles: int = 4000
    resampling: str = "systematic"
    resample_threshold: float | str = 0.5
    on_degenerate: str = "keep"
    init_spread: tuple[float, float, float] = (0.5, 0.5, 0.3)
    global_clearance: float = 0.0

    def __post_init__(self) -> None:
        n = self.n_particles
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"ParticleFilterParams.n_particles = {n!r} must be a positive integer")
        if self.resampling not in RESAMPLERS:
            raise ValueError(
                f"ParticleFilterParams.resampling = {self.resampling!r}; "
                f"choose one of {sorted(RESAMPLERS)}"
            )
        thr = self.resample_threshold
        if isinstance(thr, str):
            thr = _THRESHOLD_WORDS.get(thr, thr)
        if isinstance(thr, bool) or not isinstance(thr, int | float) or not 0.0 <= thr <= 1.0:
            raise ValueError(
                f"ParticleFilterParams.resample_threshold = {self.resample_threshold!r} must be a "
                "fraction in [0, 1], 'always' or 'never'"
            )
        object.__setattr__(self, "resample_threshold", float(thr))
        if self.on_degenerate not in _ON_DEGENERATE:
            raise ValueError(
                f"ParticleFilterParams.on_degenerate = {self.on_degenerate!r}; "
                f"choose one of {list(_ON_DEGENERATE)}"
            )
        object.__setattr__(self, "init_spread", _spread(self.init_spread, "init_spread"))
        c = self.global_clearance
        if (
            isinstance(c, bool)
            or not isinstance(c, int | float)
            or not (math.isfinite(c) and c >= 0)
        ):
            raise ValueError(f"ParticleFilterParams.global_clearance = {c!r} must be >= 0 metres")


def _spread(value: float | tuple[float, ...] | np.ndarray, name: str) -> tuple[float, float, float]:
    """One number (all three) or three standard deviations (x m, y m, theta rad), non-negative."""
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.size == 1:
        arr = np.repeat(arr, 3)
    if arr.size != 3 or not (np.isfinite(arr).all() and (arr >= 0).all()):
        raise ValueError(f"{name} must be one or three non-negative numbers, got {value!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


class ParticleFilter:
    """Monte Carlo Localization on an occupancy map (see the module docstring).

    Args:
        occupancy_map: the map (world frame).
        n_particles: overrides ``params.n_particles`` when given.
        motion_model: defaults to :class:`~mcl.motion_model.MotionModel` with default parameters.
        sensor_model: defaults to :class:`~mcl.sensor_model.SensorModel` on ``occupancy_map``.
        params: :class:`ParticleFilterParams`.
        rng: the filter's only source of randomness (a Generator, or a seed for one).

    The filter starts empty: call :meth:`initialize` or :meth:`initialize_global` first.

    Attributes:
        n_updates: corrections applied. n_resamples: resampling steps. n_degenerate: corrections
        after which every weight was zero or not finite (see the module docstring).
        last_log_mean_likelihood: log of the weighted mean likelihood of the last scan,
        ``log sum_i w_i p(z | x_i)`` with the weights before the correction (for augmented MCL).
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
        self.n_updates = 0
        self.n_resamples = 0
        self.n_degenerate = 0
        self.last_log_mean_likelihood = math.nan

    # ------------------------------------------------------------------ state
    def _require(self) -> tuple[np.ndarray, np.ndarray]:
        if self._particles is None or self._weights is None:
            raise RuntimeError("the particle filter has no particles: call initialize() first")
        return self._particles, self._weights

    @property
    def particles(self) -> np.ndarray:
        """(N, 3) world poses [x, y, theta] (metres, radians), read-only view."""
        p = self._require()[0].view()
        p.flags.writeable = False
        return p

    @property
    def weights(self) -> np.ndarray:
        """(N,) normalised weights (sum 1), read-only view."""
        w = self._require()[1].view()
        w.flags.writeable = False
        return w

    @property
    def n_particles(self) -> int:
        """Current number of particles."""
        return int(self._require()[0].shape[0])

    @property
    def effective_sample_size(self) -> float:
        """Kish's 1 / sum(w^2), in [1, N]."""
        w = self._require()[1]
        return float(1.0 / np.dot(w, w))

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
        sd = np.asarray(_spread(self.params.init_spread if spread is None else spread, "spread"))
        n = self.params.n_particles
        self.set_particles(centre + self.rng.standard_normal((n, 3)) * sd)

    def initialize_global(self) -> None:
        """Particles uniform over the map's free space, headings uniform in [-pi, pi)."""
        self.set_particles(
            self.map.sample_free_poses(
                self.rng, self.params.n_particles, clearance=self.params.global_clearance
            )
        )

    # ------------------------------------------------------------------ update steps
    def predict(self, twist: np.ndarray, dt: float) -> None:
        """Move the particles by a car-frame twist [vx, vy, omega] held for ``dt`` seconds."""
        twist = np.asarray(twist, dtype=np.float64)
        if twist.shape != (3,) or not np.isfinite(twist).all():
            raise ValueError(f"twist must be three finite numbers [vx, vy, omega], got {twist!r}")
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"dt must be a non-negative number of seconds, got {dt!r}")
        self.move(twist_to_odometry(twist, dt))

    def move(self, odometry: np.ndarray) -> None:
        """Move the particles by a car-frame displacement [dx, dy, dtheta] (metres, radians)."""
        particles, _ = self._require()
        self._particles = self.motion_model.evaluate(particles, odometry, self.rng)

    def update_weights(self, log_likelihood: np.ndarray) -> None:
        """Multiply the weights by ``exp(log_likelihood)`` (N,) and normalise (Bayes rule).

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
        ll = np.where(np.isnan(ll) | (ll == math.inf), -math.inf, ll)
        assert self._log_weights is not None
        lw = self._log_weights + ll
        top = lw.max()
        if not math.isfinite(top):
            self.n_degenerate += 1
            self.last_log_mean_likelihood = -math.inf
            if self.params.on_degenerate == "global":
                self.initialize_global()
            else:
                self.set_particles(particles)
            return
        self.last_log_mean_likelihood = float(top + math.log(np.exp(lw - top).sum()))
        self._set_log_weights(lw)

    def needs_resampling(self) -> bool:
        """Whether the effective sample size is at most ``resample_threshold`` x N."""
        return self.effective_sample_size <= self.params.resample_threshold * self.n_particles

    def resample(self, n: int | None = None) -> np.ndarray:
        """Draw ``n`` particles (default: the current count) by ``params.resampling``.

        The weights become uniform. Returns the chosen indexes of the old particles.
        """
        particles, weights = self._require()
        idx = resample(self.params.resampling, weights, self.rng, n)
        self.set_particles(particles[idx])
        self.n_resamples += 1
        return idx

    def correct(self, scan: np.ndarray) -> bool:
        """Weigh the particles by a scan (metres) and resample if needed; returns whether it did.

        See :class:`~mcl.sensor_model.SensorModel` for the scan's treatment (NaN/inf beams
        dropped, wrong length or negative ranges rejected with ``ValueError``).
        """
        particles, _ = self._require()
        self.update_weights(self.sensor_model.log_evaluate(particles, scan))
        if self.needs_resampling():
            self.resample()
            return True
        return False

    def update(self, twist: np.ndarray, dt: float, scan: np.ndarray | None) -> np.ndarray:
        """``predict``, then ``correct`` when a scan is given, then return ``estimate()``."""
        self.predict(twist, dt)
        if scan is not None:
            self.correct(scan)
        return self.estimate()

    # ------------------------------------------------------------------ outputs
    def estimate(self) -> np.ndarray:
        """(3,) weighted mean pose [x, y, theta]: arithmetic mean of x, y, circular mean of theta."""
        p, w = self._require()
        x, y = w @ p[:, :2]
        return np.array([x, y, circular_mean(p[:, 2], w)])

    def covariance(self) -> np.ndarray:
        """(3, 3) weighted covariance of the particles about :meth:`estimate` (metres, radians).

        Heading deviations are wrapped to [-pi, pi) around the circular mean, so a cloud straddling
        +-pi has a small theta variance. Normalised by sum(w) = 1 (the maximum-likelihood form).
        """
        p, w = self._require()
        mean = self.estimate()
        dev = p - mean
        dev[:, 2] = wrap_angle(dev[:, 2])
        return (dev * w[:, None]).T @ dev
