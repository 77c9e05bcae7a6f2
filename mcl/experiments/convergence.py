"""When did the filter find the car? Convergence times and honesty of an error log.

A run has *converged* at the first logged step from which the position error stays below
``position_m`` metres and the absolute heading error below ``heading_rad`` radians for ``hold_s``
seconds (every step of that window). Times are seconds of simulated time from the moment the filter
lost the car (0 for a global start, the kidnap for a kidnapping).

A step is *confidently wrong* when the filter says the pose is not ambiguous while the position
error exceeds ``wrong_m`` metres: the failure an agent cannot see coming.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcl.wrappers.error_log import ErrorLog

__all__ = ["ConvergenceCriteria", "RecoveryStats", "convergence_time", "recovery_stats"]


@dataclass(frozen=True)
class ConvergenceCriteria:
    """What counts as converged (module docstring).

    Attributes:
        position_m: metres of position error.
        heading_rad: radians of absolute heading error.
        hold_s: seconds both must hold.
        wrong_m: metres of position error from which a confident estimate counts as wrong.
    """

    position_m: float = 0.3
    heading_rad: float = math.radians(10.0)
    hold_s: float = 2.0
    wrong_m: float = 1.0

    def __post_init__(self) -> None:
        for name in ("position_m", "heading_rad", "wrong_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < math.inf:
                raise ValueError(f"ConvergenceCriteria.{name} = {v!r} must be a positive number")
        h = self.hold_s
        if isinstance(h, bool) or not isinstance(h, int | float) or not 0 <= h < math.inf:
            raise ValueError(f"ConvergenceCriteria.hold_s = {h!r} must be >= 0 seconds")


def _within(log: ErrorLog, criteria: ConvergenceCriteria) -> np.ndarray:
    return (log.position_error < criteria.position_m) & (
        np.abs(log.heading_error) < criteria.heading_rad
    )


def convergence_time(
    log: ErrorLog, since: float = 0.0, criteria: ConvergenceCriteria | None = None
) -> float:
    """Seconds from ``since`` to the first step (logged at time >= ``since``) that starts a
    ``hold_s`` window inside the tolerances; NaN when none does (or the log ends too early to
    tell).

    The window from step i holds when every step with time in [t_i, t_i + hold_s] is within the
    tolerances and the log reaches t_i + hold_s.
    """
    c = criteria if criteria is not None else ConvergenceCriteria()
    n = len(log)
    if n == 0 or not math.isfinite(since):
        return math.nan
    t = np.asarray(log.time, dtype=np.float64)
    ok = _within(log, c) & (t >= since - 1e-9)
    bad = np.flatnonzero(~ok)
    # For each step, the index of the next step that is not within (n when none).
    next_bad = np.append(bad, n)[np.searchsorted(bad, np.arange(n), side="left")]
    last_ok_time = t[np.maximum(next_bad - 1, 0)]
    eps = 1e-9
    held = ok & (last_ok_time >= t + c.hold_s - eps)
    # A run of good steps that reaches the end of the log but not hold_s: unknown, not converged.
    hits = np.flatnonzero(held)
    return float(t[hits[0]] - since) if hits.size else math.nan


@dataclass(frozen=True)
class RecoveryStats:
    """How one global-localization or kidnapping run went.

    Attributes:
        lost_at: seconds after reset at which the filter lost the car (0 or the kidnap).
        convergence_s: seconds from ``lost_at`` to convergence (NaN: never within the log).
        success: converged within the time limit.
        error_after: mean position error (m) from convergence to the end (NaN if never).
        ambiguous_fraction: fraction of steps after ``lost_at`` flagged ambiguous.
        wrong_fraction: fraction of steps after ``lost_at`` that were confidently wrong.
        wrong_after_fraction: the same, only after the first ``time_limit`` seconds (a filter
            still searching may be wrong early; it should not stay wrong and sure).
        peak_particles, final_particles: largest and last particle count after ``lost_at``.
    """

    lost_at: float
    convergence_s: float
    success: bool
    error_after: float
    ambiguous_fraction: float
    wrong_fraction: float
    wrong_after_fraction: float
    peak_particles: int
    final_particles: int


def recovery_stats(
    log: ErrorLog,
    lost_at: float,
    time_limit: float,
    ambiguous: np.ndarray | None = None,
    n_particles: np.ndarray | None = None,
    criteria: ConvergenceCriteria | None = None,
) -> RecoveryStats:
    """`RecoveryStats` of a run's log.

    Args:
        log: the run's error log (one row per step).
        lost_at: seconds after reset at which the filter lost the car.
        time_limit: seconds after ``lost_at`` within which convergence counts as a success.
        ambiguous: (rows,) per-step ambiguity flags (0/1), aligned with the log (None: unknown,
            NaN fractions).
        n_particles: (rows,) per-step particle counts (None: -1).
        criteria: what counts as converged.
    """
    c = criteria if criteria is not None else ConvergenceCriteria()
    conv = convergence_time(log, lost_at, c)
    t = np.asarray(log.time, dtype=np.float64)
    err = np.asarray(log.position_error, dtype=np.float64)
    after = t > lost_at + 1e-9
    if math.isnan(conv):
        error_after = math.nan
    else:
        settled = t >= lost_at + conv - 1e-9
        error_after = float(err[settled].mean())
    amb_frac = wrong_frac = wrong_late = math.nan
    if ambiguous is not None:
        amb = np.asarray(ambiguous, dtype=bool)[: len(t)]
        m = min(len(amb), len(t))
        sel = after[:m]
        if sel.any():
            wrong = (~amb[:m]) & (err[:m] > c.wrong_m)
            amb_frac = float(amb[:m][sel].mean())
            wrong_frac = float(wrong[sel].mean())
            late = sel & (t[:m] > lost_at + time_limit)
            wrong_late = float(wrong[late].mean()) if late.any() else math.nan
    peak = final = -1
    if n_particles is not None:
        counts = np.asarray(n_particles, dtype=np.int64)[: len(t)]
        sel = after[: len(counts)]
        if sel.any():
            peak, final = int(counts[sel].max()), int(counts[sel][-1])
    return RecoveryStats(
        lost_at=float(lost_at),
        convergence_s=conv,
        success=bool(math.isfinite(conv) and conv <= time_limit + 1e-9),
        error_after=error_after,
        ambiguous_fraction=amb_frac,
        wrong_fraction=wrong_frac,
        wrong_after_fraction=wrong_late,
        peak_particles=peak,
        final_particles=final,
    )
