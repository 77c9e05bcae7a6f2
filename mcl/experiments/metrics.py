"""Summary statistics of a localization error log (metres, radians, fractions of time)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from mcl.wrappers.error_log import ErrorLog

__all__ = ["DIVERGED_M", "ErrorStats", "error_stats"]

DIVERGED_M = 1.0
"""Metres of position error beyond which the filter counts as diverged."""


@dataclass(frozen=True)
class ErrorStats:
    """Error statistics of one run, over all its logged steps.

    Attributes:
        n_steps: logged steps.
        duration: seconds of simulated time covered (time of the last row).
        mean_error, median_error, p95_error, max_error: position error, metres.
        mean_heading_error: mean absolute heading error, radians.
        diverged_fraction: fraction of steps whose position error exceeds the threshold.
        mean_update_s: mean wall time of a filter update, seconds.
    """

    n_steps: int
    duration: float
    mean_error: float
    median_error: float
    p95_error: float
    max_error: float
    mean_heading_error: float
    diverged_fraction: float
    mean_update_s: float

    def as_dict(self) -> dict[str, float]:
        """The fields as a plain dict (for CSV rows)."""
        return asdict(self)


def error_stats(log: ErrorLog, diverged_m: float = DIVERGED_M) -> ErrorStats:
    """Statistics of a log (see `ErrorStats`); NaN values everywhere for an empty log.

    Args:
        log: the run's error log.
        diverged_m: metres of position error beyond which a step counts as diverged.
    """
    if not (math.isfinite(diverged_m) and diverged_m > 0):
        raise ValueError(f"diverged_m must be a positive number of metres, got {diverged_m!r}")
    n = len(log)
    if n == 0:
        nan = math.nan
        return ErrorStats(0, 0.0, nan, nan, nan, nan, nan, nan, nan)
    err = log.position_error
    return ErrorStats(
        n_steps=n,
        duration=float(log.time[-1]),
        mean_error=float(np.mean(err)),
        median_error=float(np.median(err)),
        p95_error=float(np.percentile(err, 95)),
        max_error=float(np.max(err)),
        mean_heading_error=float(np.mean(np.abs(log.heading_error))),
        diverged_fraction=float(np.mean(err > diverged_m)),
        mean_update_s=float(np.mean(log.update_s)),
    )
