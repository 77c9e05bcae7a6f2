"""Convergence time and honesty statistics of an error log (synthetic logs, no simulation)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.experiments.convergence import ConvergenceCriteria, convergence_time, recovery_stats
from mcl.wrappers.error_log import ErrorLog

DT = 0.025


def _log(position_error, heading_error=None) -> ErrorLog:
    e = np.asarray(position_error, dtype=np.float64)
    n = e.size
    h = np.zeros(n) if heading_error is None else np.asarray(heading_error, dtype=np.float64)
    z = np.zeros(n)
    return ErrorLog(
        step=np.arange(1, n + 1), time=np.arange(1, n + 1) * DT, x_true=z, y_true=z,
        theta_true=z, x_est=e, y_est=z, theta_est=h, position_error=e, heading_error=h,
        n_eff=np.ones(n), update_s=z,
    )  # fmt: skip


def _brute_force(err: np.ndarray, since: float, c: ConvergenceCriteria) -> float:
    t = np.arange(1, err.size + 1) * DT
    for i in range(err.size):
        if t[i] < since - 1e-9 or not err[i] < c.position_m:
            continue
        window = (t >= t[i] - 1e-9) & (t <= t[i] + c.hold_s + 1e-9)
        if t[-1] >= t[i] + c.hold_s - 1e-9 and np.all(err[window] < c.position_m):
            return float(t[i] - since)
    return math.nan


def test_converges_at_the_start_of_the_first_long_enough_good_stretch() -> None:
    err = np.full(800, 5.0)
    err[40:60] = 0.1  # 0.5 s good: too short
    err[200:] = 0.1  # good from step 201 on (t = 5.025 s)
    t = convergence_time(_log(err))
    assert t == pytest.approx(201 * DT)
    assert convergence_time(_log(err), since=2.0) == pytest.approx(201 * DT - 2.0)


def test_heading_counts_and_a_stretch_cut_by_the_log_end_is_not_converged() -> None:
    err = np.full(400, 0.05)
    heading = np.full(400, math.radians(20.0))
    assert math.isnan(convergence_time(_log(err, heading)))
    heading[:] = 0.0
    err[:330] = 2.0  # good only for the last 70 steps (1.75 s < 2 s)
    assert math.isnan(convergence_time(_log(err, heading)))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.booleans(), min_size=1, max_size=30),
    st.integers(1, 40),
    st.floats(0.0, 5.0),
)
def test_matches_a_brute_force_search(blocks, block_len, since) -> None:
    err = np.repeat(np.where(blocks, 0.1, 1.0), block_len)
    c = ConvergenceCriteria(hold_s=0.5)
    got = convergence_time(_log(err), since, c)
    want = _brute_force(err, since, c)
    assert (math.isnan(got) and math.isnan(want)) or got == pytest.approx(want)


def test_recovery_stats_success_honesty_and_particles() -> None:
    n = 800  # 20 s
    err = np.full(n, 4.0)
    err[400:] = 0.05  # converged 10 s after losing the car at 0 s
    ambiguous = np.zeros(n, dtype=int)
    ambiguous[:200] = 1  # honest for 5 s, then confidently wrong for 5 s
    counts = np.r_[np.full(100, 20000), np.full(n - 100, 1000)]
    s = recovery_stats(_log(err), 0.0, 10.0, ambiguous, counts)
    assert s.convergence_s == pytest.approx(401 * DT)
    assert not s.success  # 10.025 s > 10 s
    assert recovery_stats(_log(err), 0.0, 10.5, ambiguous, counts).success
    assert s.ambiguous_fraction == pytest.approx(200 / n)
    assert s.wrong_fraction == pytest.approx(200 / n)
    assert s.wrong_after_fraction == 0.0
    assert s.error_after == pytest.approx(0.05)
    assert (s.peak_particles, s.final_particles) == (20000, 1000)


def test_bad_criteria_are_named() -> None:
    with pytest.raises(ValueError, match="position_m"):
        ConvergenceCriteria(position_m=0.0)
    with pytest.raises(ValueError, match="hold_s"):
        ConvergenceCriteria(hold_s=-1.0)
