"""Lidar failures the four-part beam model leaves out, as measured on the real MIT racecar
(``mcl.calibration``): failures come in runs of neighbouring beams, drop-outs depend on range,
some beams return from *behind* the mapped wall (open doors, glass, changes since the map was
drawn), and the range has a bias.

`ScanEffects` replaces the beam noise of [`Lidar`][racecar_sim.sensors.lidar.Lidar] when a noise
profile asks for it (the lidar then casts noise-free). Along the scan (beam index), a Markov chain
is in one of four states: a *hit* (true range + ``hit_bias`` + an error of standard deviation
``hit_sigma``, correlated ``hit_corr`` with the previous beam's: an AR(1) along the scan), or inside a
run of *short* returns (one surface per run, ``ratio`` of the run's first true range, ratio
uniform in [``short_ratio_min``, 1)), of *long* returns (true range + one excess per run,
0.15 m + exponential of mean ``long_excess``), or of *no-returns* (reported as ``max_range``).
From a hit, a run of each kind starts with a probability chosen so that the kind covers its
fraction of the beams (the chain's stationary fractions: no-returns ``p(r)`` of the beams, short
and long their fractions of the rest); a run goes on with probability ``1 - 1 / run_length`` (geometric lengths).
The no-return fraction depends on the true range through a table (``noreturn_edges``,
``noreturn_probability``); a no-return run ends early where the range falls into a nearer bin. A beam with no surface within ``max_range`` is a no-return.

The car's own body blocks a fixed stretch of beams at the scan's end some of the time
(``body_*``: on the MIT racecar the rear right wheel, read at about 6 cm).

All draws come from the generator passed in: three uniforms and one standard normal per beam,
then one uniform per body beam.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numba as nb
import numpy as np

from racecar_sim.settings.validation import check_number, short

_MAX_BINS = 100  # no-return probability bins by range (a fitted profile has about ten)

__all__ = ["OdometryBias", "ScanEffects"]


@dataclass(frozen=True)
class ScanEffects:
    """Correlated lidar failures and range bias (see the module doc).

    Attributes:
        hit_bias: metres added to every hit.
        hit_sigma: metres, standard deviation of a hit's range noise.
        hit_corr: correlation of neighbouring beams' range errors, in [0, 1) (0 = independent;
            near 1 = an error that varies smoothly along the scan, as a wall a little off the
            map's).
        short_fraction: fraction of the *returning* beams (with a surface in range) in short-return
            runs.
        short_run: mean run length in beams.
        short_ratio_min: shortest run distance as a fraction of the run's first true range.
        long_fraction: fraction of the returning beams in long-return runs.
        long_run: mean run length in beams.
        long_excess: metres, mean excess beyond 0.15 m of a long run's return.
        noreturn_edges: metres, increasing true-range bin edges (first 0).
        noreturn_probability: no-return fraction per bin (one fewer than the edges).
        noreturn_run: mean no-return run length in beams.
        body_first, body_last: the beams the car's own body blocks, as fractions of the scan
            from its first beam (the right end): beams ``[body_first, body_last) x B``.
        body_probability: how often such a beam sees the body (it reads ``body_range``) instead
            of the world (a wheel that steers, a cable that moves).
        body_range: metres, what a beam on the body reads.
    """

    hit_bias: float = 0.0
    hit_sigma: float = 0.01
    hit_corr: float = 0.0
    short_fraction: float = 0.0
    short_run: float = 1.0
    short_ratio_min: float = 0.2
    long_fraction: float = 0.0
    long_run: float = 1.0
    long_excess: float = 0.3
    noreturn_edges: tuple[float, ...] = (0.0, 1e9)
    noreturn_probability: tuple[float, ...] = (0.0,)
    noreturn_run: float = 1.0
    body_first: float = 0.0
    body_last: float = 0.0
    body_probability: float = 0.0
    body_range: float = 0.06
    _tables: tuple = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        name = "ScanEffects"
        # a metre of bias or noise is far beyond any lidar's; runs longer than a scan's beams
        check_number(name, "hit_bias", self.hit_bias, low=-1, high=1)
        check_number(name, "hit_sigma", self.hit_sigma, low=0, high=1)
        check_number(name, "hit_corr", self.hit_corr, low=0, high=1, high_open=True)
        for f in ("short_fraction", "long_fraction"):
            check_number(name, f, getattr(self, f), low=0, high=1)
        for f in ("short_run", "long_run", "noreturn_run"):
            check_number(name, f, getattr(self, f), low=1, high=10_000)
        check_number(name, "short_ratio_min", self.short_ratio_min, low=0, high=1)
        for f in ("body_first", "body_last", "body_probability"):
            check_number(name, f, getattr(self, f), low=0, high=1)
        if self.body_last < self.body_first:
            raise ValueError("ScanEffects.body_last must not be below body_first")
        check_number(name, "body_range", self.body_range, low=0, high=1000)
        check_number(name, "long_excess", self.long_excess, low=0, high=1000, low_open=True)
        try:
            edges = tuple(float(v) for v in self.noreturn_edges)
            probs = tuple(float(v) for v in self.noreturn_probability)
        except (TypeError, ValueError):
            raise ValueError(
                "ScanEffects.noreturn_edges and noreturn_probability must be lists of numbers, "
                f"got {short(self.noreturn_edges)} and {short(self.noreturn_probability)}"
            ) from None
        if len(probs) > _MAX_BINS:
            raise ValueError(f"ScanEffects: at most {_MAX_BINS} no-return range bins, got {len(probs)}")
        if not all(math.isfinite(v) for v in edges):
            raise ValueError("ScanEffects.noreturn_edges must be finite numbers")
        if len(edges) != len(probs) + 1 or len(probs) < 1:
            raise ValueError(
                "ScanEffects.noreturn_edges must have one more entry than noreturn_probability"
            )
        if edges[0] != 0.0 or any(b <= a for a, b in itertools.pairwise(edges)):
            raise ValueError("ScanEffects.noreturn_edges must start at 0 and increase")
        if not all(0.0 <= p < 1.0 for p in probs):
            raise ValueError("ScanEffects.noreturn_probability values must lie in [0, 1)")
        if self.short_fraction + self.long_fraction >= 1:
            raise ValueError("ScanEffects: short_fraction + long_fraction must stay below 1")
        object.__setattr__(self, "noreturn_edges", edges)
        object.__setattr__(self, "noreturn_probability", probs)
        # start probabilities from a hit, per no-return bin: stationary fractions of the chain
        starts = []
        for p_nr in probs:
            back = 1.0 - p_nr  # the beams that return, split into short, long and hits
            p_short, p_long = self.short_fraction * back, self.long_fraction * back
            p_hit = back - p_short - p_long
            starts.append(
                (
                    p_short / (self.short_run * p_hit),
                    p_long / (self.long_run * p_hit),
                    p_nr / (self.noreturn_run * p_hit),
                )
            )
        object.__setattr__(
            self,
            "_tables",
            (np.asarray(edges), np.asarray(starts, dtype=np.float64)),
        )

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any] | ScanEffects) -> ScanEffects:
        """From a mapping of the fields (unknown keys raise ValueError naming them)."""
        if isinstance(data, ScanEffects):
            return data
        known = {f for f in cls.__dataclass_fields__ if not f.startswith("_")}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown scan_effects setting(s) {short(unknown, 200)}; known: {sorted(known)}")
        return cls(**dict(data))

    def apply(self, ranges: np.ndarray, max_range: float, rng: np.random.Generator) -> np.ndarray:
        """(B,) float32 measured ranges from true ``ranges`` (B,) metres of one scan."""
        r = np.ascontiguousarray(ranges, dtype=np.float64)
        u = rng.random((3, r.size))
        z = rng.standard_normal(r.size)
        out = np.empty(r.size, dtype=np.float32)
        edges, starts = self._tables
        _apply(
            r, u, z, float(max_range), self.hit_bias, self.hit_sigma, self.hit_corr, self.short_run,
            self.short_ratio_min, self.long_run, self.long_excess, self.noreturn_run, edges,
            starts, out,
        )  # fmt: skip
        if self.body_probability > 0 and self.body_last > self.body_first:
            lo, hi = round(self.body_first * r.size), round(self.body_last * r.size)
            seen = rng.random(hi - lo) < self.body_probability
            out[lo:hi][seen] = np.float32(min(self.body_range, max_range))
        return out


@nb.njit(cache=True)
def _apply(r, u, z, max_range, bias, sigma, rho, short_run, ratio_min, long_run, excess_mean,
           nr_run, edges, starts, out):  # fmt: skip
    state = 0  # 0 hit, 1 short, 2 long, 3 no-return
    e = 0.0  # the range error, AR(1) along the scan (rho = 0: independent draws)
    keep = math.sqrt(1.0 - rho * rho)
    run_value = 0.0
    n_bins = starts.shape[0]
    run_bin = 0
    for i in range(r.size):
        ri = r[i]
        surface = ri < max_range
        b = 0
        while b + 1 < n_bins and ri >= edges[b + 1]:
            b += 1
        # continue or end the current run (a no-return run also ends where the range falls
        # into a nearer bin of the table: drop-outs belong to the far surface that started it)
        if state == 1:
            if u[0, i] < 1.0 / short_run or run_value >= ri:
                state = 0
        elif state == 2:
            if u[0, i] < 1.0 / long_run:
                state = 0
        elif state == 3:
            if u[0, i] < 1.0 / nr_run or (surface and b < run_bin):
                state = 0
        if state == 0 and surface:
            run_bin = b
            v = u[1, i]
            if v < starts[b, 0]:
                state = 1
                run_value = ri * (ratio_min + (1.0 - ratio_min) * u[2, i])
            elif v < starts[b, 0] + starts[b, 1]:
                state = 2
                run_value = 0.15 - excess_mean * math.log1p(-u[2, i])
            elif v < starts[b, 0] + starts[b, 1] + starts[b, 2]:
                state = 3
        e = rho * e + keep * sigma * z[i]
        if not surface:
            val = max_range
        elif state == 1:
            val = run_value + e
        elif state == 2:
            val = ri + run_value + e
        elif state == 3:
            val = max_range
        else:
            val = ri + bias + e
        out[i] = min(max(val, 0.0), max_range)


@dataclass(frozen=True)
class OdometryBias:
    """Systematic odometry error: reported = true * (1 + scale) + offset, per [vx, vy, omega].

    Attributes:
        scale: relative bias per component (e.g. -0.05: reads 5 % low).
        offset: additive bias per component (m/s, m/s, rad/s).
    """

    scale: tuple[float, float, float] = (0.0, 0.0, 0.0)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name, most in (("scale", 1.0), ("offset", 10.0)):  # a 100 % / 10 m/s bias at most
            given = getattr(self, name)
            try:
                value = tuple(float(v) for v in given)
            except (TypeError, ValueError):
                value = ()
            if len(value) != 3 or not all(math.isfinite(v) and abs(v) <= most for v in value):
                raise ValueError(
                    f"odometry bias {name} must be three numbers in [-{most:g}, {most:g}], "
                    f"got {short(given)}"
                )
            object.__setattr__(self, name, value)

    def apply(self, odom: np.ndarray) -> np.ndarray:
        """Biased (3,) float32 odometry from the noisy ``odom`` (3,)."""
        s = np.asarray(self.scale)
        o = np.asarray(self.offset)
        return (np.asarray(odom, dtype=np.float64) * (1.0 + s) + o).astype(np.float32)

    @property
    def is_zero(self) -> bool:
        """Whether the bias changes nothing (scale and offset all zero)."""
        return not any(self.scale) and not any(self.offset)

    def unbiased(self, reported: np.ndarray) -> np.ndarray:
        """The (3,) float64 twist [vx m/s, vy m/s, omega rad/s] that reads as ``reported`` (3,):
        ``(reported - offset) / (1 + scale)``, the inverse of [apply][racecar_sim.sensors.scan_effects.OdometryBias.apply]
        (a filter given a car's calibrated odometry). Needs every ``1 + scale`` > 0."""
        return (np.asarray(reported, dtype=np.float64) - np.asarray(self.offset)) / (
            1.0 + np.asarray(self.scale)
        )
