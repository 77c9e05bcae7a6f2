"""What the four-part beam model misses, measured: residual categories of real (or simulated)
scans against exact casts, how failures cluster along the scan, and how drop-outs depend on range.

Categories of a beam whose expected range z* is a mapped surface (z* < max range):
``hit`` |z - z*| <= 0.15 m, ``short`` z < z* - 0.15 m, ``long`` z > z* + 0.15 m, ``noreturn``
(no finite reading). ``within5`` / ``within15`` are fractions of the *valid* (finite) readings.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

__all__ = [
    "RANGE_BINS",
    "ResidualFractions",
    "ScanFailureStats",
    "failure_stats",
    "residual_fractions",
]

RANGE_BINS = (0.0, 5.0, 7.5, 10.0, 12.5, 15.0, 20.0, 30.0)
"""Metres: edges of the expected-range bins of the drop-out table."""

_TOL = 0.15


@dataclass(frozen=True)
class ResidualFractions:
    """Fractions of beams with a mapped surface (z* < max range): see the module doc."""

    within5: float
    within15: float
    short: float
    long: float
    noreturn: float
    n_beams: int

    def as_dict(self) -> dict[str, float]:
        """The five fractions by name."""
        return {
            "within5": self.within5,
            "within15": self.within15,
            "short": self.short,
            "long": self.long,
            "noreturn": self.noreturn,
        }


def _mapped(z_star: np.ndarray, max_range: float) -> np.ndarray:
    return np.isfinite(z_star) & (z_star < max_range - 1e-6)


def residual_fractions(z: np.ndarray, z_star: np.ndarray, max_range: float) -> ResidualFractions:
    """Residual categories of readings ``z`` (metres, NaN or >= max_range = no-return) against
    expected ranges ``z_star`` (same shape).

    ``short``, ``long`` and ``noreturn`` are fractions of all mapped beams; ``within5`` and
    ``within15`` of the mapped beams with a finite reading.
    """
    z = np.asarray(z, dtype=np.float64)
    z_star = np.asarray(z_star, dtype=np.float64)
    mapped = _mapped(z_star, max_range)
    valid = mapped & np.isfinite(z) & (z < max_range - 1e-6)
    res = z - z_star
    n_valid = max(int(valid.sum()), 1)
    n = max(int(mapped.sum()), 1)
    return ResidualFractions(
        within5=float((valid & (np.abs(res) <= 0.05)).sum() / n_valid),
        within15=float((valid & (np.abs(res) <= _TOL)).sum() / n_valid),
        short=float((valid & (res < -_TOL)).sum() / n),
        long=float((valid & (res > _TOL)).sum() / n),
        noreturn=float((mapped & ~valid).sum() / n),
        n_beams=int(mapped.sum()),
    )


@dataclass(frozen=True)
class ScanFailureStats:
    """Failures along the scan and their shapes.

    Attributes:
        fractions: the residual categories.
        run_length: mean run length (beams) of consecutive short / long / no-return beams.
        next_same: P(the next beam fails the same way | this one does), per kind.
        noreturn_by_range: no-return probability per bin of `RANGE_BINS` (expected range).
        long_excess: metres, mean of (z - z* - 0.15) over long returns (the excess beyond 0.15 m).
        short_ratio: mean z / z* of short returns.
        hit_bias, hit_sigma: metres, mean and standard deviation of |z - z*| <= 0.15 m residuals.
        hit_sigma_by_range: per bin of `RANGE_BINS`, the same standard deviation.
        mixed_at_edges: fraction of beams beside a cast jump (> 0.5 m) reading strictly between
            the neighbouring expected ranges (mixed pixels), and ``edge_fraction`` of such beams.
    """

    fractions: ResidualFractions
    run_length: dict[str, float]
    next_same: dict[str, float]
    noreturn_by_range: tuple[float, ...]
    long_excess: float
    short_ratio: float
    hit_bias: float
    hit_sigma: float
    hit_sigma_by_range: tuple[float, ...]
    mixed_at_edges: float
    edge_fraction: float


def _runs(mask: np.ndarray) -> np.ndarray:
    """Lengths of the runs of True along the last axis of a 2-D mask."""
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    d = np.diff(padded, axis=1)
    starts = np.argwhere(d == 1)
    ends = np.argwhere(d == -1)
    return (ends[:, 1] - starts[:, 1]).astype(np.float64)


def failure_stats(z: np.ndarray, z_star: np.ndarray, max_range: float) -> ScanFailureStats:
    """Failure statistics of scans ``z`` (S, B) against expected ``z_star`` (S, B), metres."""
    z = np.atleast_2d(np.asarray(z, dtype=np.float64))
    z_star = np.atleast_2d(np.asarray(z_star, dtype=np.float64))
    mapped = _mapped(z_star, max_range)
    valid = mapped & np.isfinite(z) & (z < max_range - 1e-6)
    res = np.where(valid, z - z_star, np.nan)
    kinds = {
        "short": valid & (res < -_TOL),
        "long": valid & (res > _TOL),
        "noreturn": mapped & ~valid,
    }
    run_length, next_same = {}, {}
    for name, m in kinds.items():
        runs = _runs(m)
        run_length[name] = float(runs.mean()) if runs.size else 0.0
        prev = m[:, :-1]
        next_same[name] = float((prev & m[:, 1:]).sum() / max(prev.sum(), 1))
    edges = np.asarray(RANGE_BINS)
    nr_bins, sd_bins = [], []
    hit = valid & (np.abs(res) <= _TOL)
    for lo, hi in itertools.pairwise(edges):
        sel = mapped & (z_star >= lo) & (z_star < hi)
        nr_bins.append(float(kinds["noreturn"][sel].mean()) if sel.any() else 0.0)
        sh = hit & sel
        sd_bins.append(float(np.nanstd(res[sh])) if sh.sum() > 10 else float("nan"))
    with np.errstate(invalid="ignore"):  # inf - inf where beams are left out
        jump = np.abs(np.diff(z_star, axis=1)) > 0.5
    edge = np.zeros_like(mapped)
    edge[:, :-1] |= jump
    edge[:, 1:] |= jump
    left = np.concatenate([z_star[:, :1], z_star[:, :-1]], axis=1)
    right = np.concatenate([z_star[:, 1:], z_star[:, -1:]], axis=1)
    lo = np.minimum(np.minimum(z_star, left), right)
    hi = np.maximum(np.maximum(z_star, left), right)
    between = valid & (z > lo + _TOL) & (z < hi - _TOL)
    n_edge = edge & mapped
    long_m, short_m = kinds["long"], kinds["short"]
    return ScanFailureStats(
        fractions=residual_fractions(z, z_star, max_range),
        run_length=run_length,
        next_same=next_same,
        noreturn_by_range=tuple(nr_bins),
        long_excess=float(np.mean(res[long_m] - _TOL)) if long_m.any() else 0.0,
        short_ratio=float(np.mean(z[short_m] / z_star[short_m])) if short_m.any() else 1.0,
        hit_bias=float(np.mean(res[hit])),
        hit_sigma=float(np.std(res[hit])),
        hit_sigma_by_range=tuple(sd_bins),
        mixed_at_edges=float(between[n_edge].mean()) if n_edge.any() else 0.0,
        edge_fraction=float(n_edge.sum() / max(mapped.sum(), 1)),
    )
