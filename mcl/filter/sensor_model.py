"""Beam sensor model: a lidar scan -> one likelihood per particle (the MIT RSS lab's table model).

Units: ranges in metres outside, in *pixels* inside the table: a range r becomes
``round(clip(r / cell, 0, z_max))`` with ``z_max = table_width - 1`` and ``cell`` the table's cell in
metres: ``resolution * lidar_scale_to_map_scale`` (the lab's), or ``max_range / z_max`` when
``SensorModelParams.max_range`` is given.

Frames: particles are world ``[x, y, theta]`` of the rear axle; rays are cast from the lidar, mounted
``mount_offset`` metres ahead of the rear axle along the car's x axis; beam angles are in the car
frame (radians, 0 = straight ahead, positive to the left).

The table ``table[z_measured_px, d_expected_px]`` (Probabilistic Robotics, 6.3) mixes:

- ``p_hit``: the Gaussian N(z; d, sigma_hit^2), normalised over z within each column d;
- ``p_short``: ``(2 / d) (1 - z / d)`` for 0 <= z <= d and d != 0, else 0;
- ``p_max``: 1 at z = z_max, else 0;
- ``p_rand``: ``1 / z_max`` for 0 <= z <= z_max;

weighted by the alphas, then every column is normalised to sum to 1. A particle's likelihood is the
product over beams of ``table[z, d]``, raised to ``squash_exponent`` to soften the peak; it is computed
as a sum of logs (a numba kernel over particles, threaded for large batches), so products far below
1e-300 keep their order.

Scan treatment: the scan is down-sampled to ``num_beams_per_particle`` evenly spaced beams (all beams
when it has fewer); beams of the down-sampled set that are NaN or +-inf are *dropped* (they carry no
information about the pose); a negative range, a scan that is not 1-D, or a scan whose length differs
from ``beam_angles`` raises ``ValueError``. With every beam dropped, all particles score log 0 = 0.
"""

from __future__ import annotations

from dataclasses import replace

import numba as nb
import numpy as np

from mcl.filter.beam_bound import bounded_scores
from mcl.filter.beam_skip import BeamSkip, beam_skip_mask, cloud_converged
from mcl.filter.beam_table import PARALLEL_MIN_LOOKUPS, beam_table, score_serial, score_shared
from mcl.filter.likelihood_field import likelihood_table, score_endpoints
from mcl.filter.sensor_params import MODELS, SensorModelParams
from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import LutParams, RayCaster
from racecar_sim.raycast.shared_work import run_shared

__all__ = ["MODELS", "PARALLEL_MIN_LOOKUPS", "SensorModel", "SensorModelParams", "beam_table"]




class SensorModel:
    """Weights particles by how well a lidar scan matches the map from their poses.

    Args:
        occupancy_map: the map the expected ranges are cast on.
        params: `SensorModelParams` (defaults: the MIT RSS lab).
        beam_angles: (L,) car-frame angles (radians) of the scan's beams; None spreads any scan's
            beams evenly over ``params.fov`` (first beam at -fov/2, last at +fov/2).

    Attributes:
        table: the (W, W) beam-model table (see `beam_table()`), read-only.
        last_beam_skip: what beam skipping decided on the last scored scan
            (`mcl.filter.beam_skip.BeamSkip`; at its defaults while beam skipping is off).
        caster: the [`RayCaster`][racecar_sim.raycast.RayCaster] for the expected ranges (None for
            the likelihood field, which casts nothing).
        max_range: metres, z_max pixels x resolution x lidar_scale_to_map_scale for the beam
            model; ``likelihood_max_range`` for the likelihood field (a beam there is skipped).
    """

    def __init__(
        self,
        occupancy_map: OccupancyMap,
        params: SensorModelParams | None = None,
        beam_angles: np.ndarray | None = None,
    ) -> None:
        self.params = params if params is not None else SensorModelParams()
        self.map = occupancy_map
        p = self.params
        self.z_max = p.z_max
        if p.max_range is None:
            self.m_per_px = occupancy_map.resolution * p.lidar_scale_to_map_scale
        else:
            self.m_per_px = float(p.max_range) / self.z_max
        self.max_range = self.z_max * self.m_per_px
        self.table = beam_table(p)
        self.table.setflags(write=False)
        with np.errstate(divide="ignore"):
            log_table = p.squash_exponent * np.log(self.table)
        self._log_table = np.ascontiguousarray(log_table)
        self._search_log_table = self._log_table
        self.has_search_hit = False
        if p.search_sigma_hit is not None and p.search_sigma_hit != p.sigma_hit:
            wide = beam_table(replace(p, sigma_hit=float(p.search_sigma_hit)))
            with np.errstate(divide="ignore"):
                self._search_log_table = np.ascontiguousarray(p.squash_exponent * np.log(wide))
            self.has_search_hit = True
        if beam_angles is not None:
            beam_angles = np.asarray(beam_angles, dtype=np.float64)
            if beam_angles.ndim != 1 or beam_angles.size == 0:
                raise ValueError(
                    f"beam_angles must be a non-empty 1-D array, got {beam_angles.shape}"
                )
            if not np.isfinite(beam_angles).all():
                raise ValueError("beam_angles must be finite")
        self.beam_angles = beam_angles
        self.caster: RayCaster | None = None
        if p.model == "likelihood_field":
            self.max_range = float(p.likelihood_max_range)
            self._field_table = likelihood_table(
                occupancy_map,
                p.likelihood_sigma,
                p.likelihood_z_hit,
                p.likelihood_z_rand,
                p.likelihood_max_distance,
                p.likelihood_max_range,
            )
        else:
            self.caster = RayCaster(
                occupancy_map,
                self.max_range,
                method=p.raycast_method,
                parallel=p.parallel,
                lut=LutParams(sort_extent=float(p.lut_sort_extent)),
            )
        self._subsample_cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.last_beam_skip = BeamSkip()

    # ------------------------------------------------------------------ stages
    def beams_used(self, n_ranges: int) -> tuple[np.ndarray, np.ndarray]:
        """The beams of a scan of ``n_ranges`` that the model scores: (indexes (K,), their car-frame
        angles (K,), radians), ``num_beams_per_particle`` of them spread evenly (read-only)."""
        cached = self._subsample_cache.get(n_ranges)
        if cached is not None:
            return cached
        k = min(self.params.num_beams_per_particle, n_ranges)
        idx = np.unique(np.floor(np.linspace(0, n_ranges - 1, k) + 0.5).astype(np.int64))
        if self.beam_angles is not None:
            angles = self.beam_angles
        elif n_ranges == 1:
            angles = np.zeros(1)
        else:
            angles = np.linspace(-self.params.fov / 2, self.params.fov / 2, n_ranges)
        out = (idx, np.ascontiguousarray(angles[idx]))
        self._subsample_cache[n_ranges] = out
        return out

    def _validated(self, scan: np.ndarray) -> np.ndarray:
        """``scan`` as float64 after the checks `observe()` documents."""
        scan = np.asarray(scan, dtype=np.float64)
        if scan.ndim != 1 or scan.size == 0:
            raise ValueError(
                f"scan must be a non-empty 1-D array of ranges, got shape {scan.shape}"
            )
        if self.beam_angles is not None and scan.size != self.beam_angles.size:
            raise ValueError(
                f"scan has {scan.size} ranges but the sensor model has {self.beam_angles.size} "
                "beam angles"
            )
        if (scan < 0).any():  # NaN compares False, so only real negative numbers land here
            raise ValueError(f"scan has negative ranges (min {np.nanmin(scan)} m)")
        return scan

    def observe(self, scan: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The beams of ``scan`` that are used: (car-frame angles (K,) radians, ranges (K,) pixels).

        Raises:
            ValueError: the scan is not 1-D and non-empty, its length differs from ``beam_angles``,
                or a range is negative.
        """
        scan = self._validated(scan)
        idx, angles = self.beams_used(scan.size)
        ranges = scan[idx]
        keep = np.isfinite(ranges)
        if not keep.all():
            angles, ranges = angles[keep], ranges[keep]
        z = np.floor(np.clip(ranges / self.m_per_px, 0.0, self.z_max) + 0.5).astype(np.int64)
        return np.ascontiguousarray(angles), z

    def lidar_poses(self, particles: np.ndarray) -> np.ndarray:
        """(N, 3) world poses of each particle's lidar (``mount_offset`` ahead of the rear axle)."""
        particles = np.asarray(particles, dtype=np.float64)
        if particles.ndim != 2 or particles.shape[1] != 3:
            raise ValueError(f"particles must have shape (N, 3), got {particles.shape}")
        off = self.params.mount_offset
        if off == 0.0:
            return particles
        th = particles[:, 2]
        lidar = np.empty_like(particles)
        lidar[:, 0] = particles[:, 0] + off * np.cos(th)
        lidar[:, 1] = particles[:, 1] + off * np.sin(th)
        lidar[:, 2] = th
        return lidar

    def expected_ranges(self, particles: np.ndarray, angles: np.ndarray) -> np.ndarray:
        """(N, K) ranges in metres the map predicts for each particle's lidar at car-frame angles."""
        if self.caster is None:
            raise ValueError("the likelihood-field model casts no rays (model='likelihood_field')")
        return self.caster.cast(self.lidar_poses(particles), angles)

    def score(self, expected: np.ndarray, z_px: np.ndarray) -> np.ndarray:
        """(N,) log-likelihoods: squash x sum over beams of log table[z_px, expected in pixels].

        Args:
            expected: (N, K) expected ranges in metres.
            z_px: (K,) measured ranges in pixels (integers in [0, z_max]).
        """
        expected = np.ascontiguousarray(expected, dtype=np.float64)
        z_px = np.ascontiguousarray(z_px, dtype=np.int64)
        if expected.ndim != 2 or expected.shape[1] != z_px.shape[0]:
            raise ValueError(
                f"expected ranges {expected.shape} do not match {z_px.shape[0]} measured beams"
            )
        out = np.empty(expected.shape[0], dtype=np.float64)
        if z_px.size == 0:
            out[:] = 0.0
            return out
        if z_px.min() < 0 or z_px.max() > self.z_max:
            raise ValueError(f"measured pixels must lie in [0, {self.z_max}]")
        return self._score_into(expected, z_px, self._log_table, out)

    def _score_into(
        self, expected: np.ndarray, rows: np.ndarray, table: np.ndarray, out: np.ndarray
    ) -> np.ndarray:
        """out[i] = sum_b table[rows[b], expected_ib in pixels] (the scoring kernels)."""
        parallel = self.params.parallel
        if parallel is None:
            parallel = expected.size >= PARALLEL_MIN_LOOKUPS
        args = (expected, rows, table, 1.0 / self.m_per_px, float(self.z_max), out)
        if parallel:
            run_shared(score_shared, args, nb.get_num_threads())
        else:
            score_serial(*args)
        return out

    def _score_skipping(self, particles: np.ndarray, angles: np.ndarray, z_px: np.ndarray):
        """The log-likelihoods with beam skipping (`mcl.filter.beam_skip`), or None when the
        cloud has not converged (then the plain model scores every beam)."""
        p = self.params
        skip = BeamSkip()
        skip.n_beams = int(z_px.size)
        self.last_beam_skip = skip
        skip.converged = bool(cloud_converged(particles, float(p.beam_skip_converged_distance)))
        if not skip.converged:
            return None
        expected = np.ascontiguousarray(self.expected_ranges(particles, angles), dtype=np.float64)
        keep = np.empty(z_px.size, dtype=np.bool_)
        unexplained = int(
            beam_skip_mask(
                expected,
                z_px,
                1.0 / self.m_per_px,
                float(self.z_max),
                float(p.beam_skip_distance) / self.m_per_px,
                float(p.beam_skip_threshold),
                float(p.beam_skip_error_threshold),
                keep,
                bool(p.beam_skip_short_only),
            )
        )
        skip.forced = bool(keep.all()) and unexplained > 0
        skip.skipped = 0 if skip.forced else unexplained
        table = self._log_table[z_px]  # a copy: one row per beam
        table[~keep] = 0.0
        rows = np.arange(z_px.size, dtype=np.int64)
        return self._score_into(expected, rows, table, np.empty(expected.shape[0]))

    # ------------------------------------------------------------------ API
    def log_evaluate(
        self, particles: np.ndarray, scan: np.ndarray, searching: bool = False
    ) -> np.ndarray:
        """(N,) natural-log likelihoods of ``scan`` (metres) from each particle (see module doc);
        ``searching`` scores with the wide hit of ``params.search_sigma_hit``."""
        log_table = self._search_log_table if searching else self._log_table
        if self.caster is None:
            return self._log_evaluate_field(particles, scan)
        angles, z_px = self.observe(scan)
        if z_px.size == 0:
            return np.zeros(np.asarray(particles).shape[0])
        if self.params.beam_skip:
            particles = np.ascontiguousarray(particles, dtype=np.float64)
            if particles.ndim != 2 or particles.shape[1] != 3:
                raise ValueError(f"particles must have shape (N, 3), got {particles.shape}")
            skipping = self._score_skipping(particles, angles, z_px)
            if skipping is not None:
                return skipping
        if self.caster.method == "lut":
            # Cast and score in one pass from the lidars (same numbers as
            # score(expected_ranges(...)) but for rounding of the lidar positions).
            particles = np.asarray(particles, dtype=np.float64)
            if particles.ndim != 2 or particles.shape[1] != 3:
                raise ValueError(f"particles must have shape (N, 3), got {particles.shape}")
            return self.caster.cast_score(
                particles,
                angles,
                log_table[z_px],
                1.0 / self.m_per_px,
                offset=float(self.params.mount_offset),
            )
        expected = np.ascontiguousarray(self.expected_ranges(particles, angles), dtype=np.float64)
        out = np.empty(expected.shape[0], dtype=np.float64)
        return self._score_into(
            expected, np.ascontiguousarray(z_px, dtype=np.int64), log_table, out
        )

    @property
    def bounds_beams(self) -> bool:
        """Whether `log_evaluate_tracking()` bounds each beam's say (``params.beam_bound`` set,
        the beam model)."""
        return self.params.beam_bound is not None and self.caster is not None

    def log_evaluate_tracking(
        self, particles: np.ndarray, scan: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(plain, bounded): the (N,) log-likelihoods of `log_evaluate()` and the same with each
        beam's term at most ``params.beam_bound`` under the cloud's best for that beam
        ([bounded_scores][mcl.filter.beam_bound.bounded_scores]); the two are the same array
        when the bound is off. For weighing a tracking cloud: the bound is relative to the
        particles given."""
        if not self.bounds_beams:
            plain = self.log_evaluate(particles, scan)
            return plain, plain
        particles = np.ascontiguousarray(particles, dtype=np.float64)
        if particles.ndim != 2 or particles.shape[1] != 3:
            raise ValueError(f"particles must have shape (N, 3), got {particles.shape}")
        angles, z_px = self.observe(scan)
        if z_px.size == 0:
            plain = np.zeros(particles.shape[0])
            return plain, plain
        terms = np.empty((particles.shape[0], z_px.size))
        plain = self.caster.cast_score(
            particles, angles, self._log_table[z_px], 1.0 / self.m_per_px,
            offset=float(self.params.mount_offset), terms=terms,
        )  # fmt: skip
        bounded = np.empty_like(plain)
        bounded_scores(terms, float(self.params.beam_bound), bounded)
        return plain, bounded

    def weigh(
        self, particles: np.ndarray, scan: np.ndarray, searching: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """(own, weighing): the (N,) log-likelihoods of `log_evaluate()` (the narrow hit, no
        bound: what likelihood averages follow) and those a filter weighs its cloud by: the wide
        search hit while ``searching``, the bounded ones (`log_evaluate_tracking()`) while not.
        The two are the same array when they do not differ."""
        if searching and self.has_search_hit:
            return self.log_evaluate(particles, scan), self.log_evaluate(particles, scan, True)
        if not searching:
            return self.log_evaluate_tracking(particles, scan)
        own = self.log_evaluate(particles, scan)
        return own, own

    def _log_evaluate_field(self, particles: np.ndarray, scan: np.ndarray) -> np.ndarray:
        """The likelihood-field model's log-likelihoods (see [`mcl.filter.likelihood_field`][mcl.filter.likelihood_field])."""
        scan = self._validated(scan)
        idx, all_angles = self.beams_used(scan.size)
        ranges = scan[idx]
        keep = np.isfinite(ranges) & (ranges < self.max_range)
        lidar = self.lidar_poses(particles)
        if not keep.any():
            return np.zeros(lidar.shape[0])
        return score_endpoints(
            self.map,
            self._field_table,
            lidar,
            np.ascontiguousarray(all_angles[keep]),
            np.ascontiguousarray(ranges[keep]),
            self.params.squash_exponent,
            self.params.parallel,
        )

    def evaluate(self, particles: np.ndarray, scan: np.ndarray) -> np.ndarray:
        """(N,) unnormalised likelihoods ``prod_b table[z_b, d_b] ** squash`` (may underflow to 0;
        use `log_evaluate()` to compare very unlikely particles)."""
        return np.exp(self.log_evaluate(particles, scan))
