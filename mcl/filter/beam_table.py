"""The beam model's table and the kernels that score expected ranges against it.

``beam_table()`` builds the MIT RSS lab's mixture ``table[z_measured_px, d_expected_px]`` (see
[SensorModel][mcl.filter.sensor_model.SensorModel]'s module for its four components); the kernels sum a
particle's log-likelihood over its beams, on one thread or shared by all (blocks of 256
particles). Ranges in metres become pixels as ``round(clip(r * px_per_m, 0, z_max))``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numba as nb
import numpy as np

from racecar_sim.raycast.shared_work import fetch_add

if TYPE_CHECKING:
    from mcl.filter.sensor_params import SensorModelParams

__all__ = [
    "PARALLEL_MIN_LOOKUPS", "beam_table", "score_row", "score_serial", "score_shared", "table_term",
]


@nb.njit(cache=True, inline="always")
def table_term(ranges, z_obs, log_table, px_per_m, z_max, i, b):
    """log_table[z_obs[b], round(clip(ranges[i, b] * px_per_m, 0, z_max))]."""
    d = ranges[i, b] * px_per_m
    if d > z_max:
        d = z_max
    elif d < 0.0:
        d = 0.0
    return log_table[z_obs[b], int(d + 0.5)]


def beam_table(params: SensorModelParams) -> np.ndarray:
    """The (W, W) float64 table ``[z_measured_px, d_expected_px]``; every column sums to 1.

    The four components are described in `mcl.filter.sensor_model`'s module docstring.
    """
    z_max = params.z_max
    z = np.arange(params.table_width, dtype=np.float64)[:, None]  # rows: measured
    d = np.arange(params.table_width, dtype=np.float64)[None, :]  # columns: expected

    hit = np.exp(-0.5 * ((z - d) / params.sigma_hit) ** 2)
    hit /= hit.sum(axis=0, keepdims=True)

    d_safe = np.where(d > 0, d, 1.0)
    short = np.where((d > 0) & (z <= d), (2.0 / d_safe) * (1.0 - z / d_safe), 0.0)
    max_ = (z == z_max).astype(np.float64) * np.ones_like(d)
    rand = np.full_like(hit, 1.0 / z_max)

    table = (
        params.alpha_hit * hit
        + params.alpha_short * short
        + params.alpha_max * max_
        + params.alpha_rand * rand
    )
    return table / table.sum(axis=0, keepdims=True)


@nb.njit(cache=True, inline="always")
def score_row(ranges, z_obs, log_table, px_per_m, z_max, out, i):
    """out[i] = sum_b log_table[z_obs[b], round(clip(ranges[i, b] * px_per_m, 0, z_max))]."""
    acc = 0.0
    for b in range(ranges.shape[1]):
        acc += table_term(ranges, z_obs, log_table, px_per_m, z_max, i, b)
    out[i] = acc


@nb.njit(cache=True, nogil=True)
def score_shared(ranges, z_obs, log_table, px_per_m, z_max, out, counter):
    """Log-likelihood sums for blocks of 256 particles (rows of ``ranges``) taken from
    ``counter``: one of the threads sharing the particles (`racecar_sim.raycast.shared_work`)."""
    n = ranges.shape[0]
    while True:
        i0 = fetch_add(counter, 1) * 256
        if i0 >= n:
            break
        for i in range(i0, min(n, i0 + 256)):
            score_row(ranges, z_obs, log_table, px_per_m, z_max, out, i)


@nb.njit(cache=True)
def score_serial(ranges, z_obs, log_table, px_per_m, z_max, out):
    """Same as `score_shared()` on one thread, all the particles."""
    for i in range(ranges.shape[0]):
        score_row(ranges, z_obs, log_table, px_per_m, z_max, out, i)


PARALLEL_MIN_LOOKUPS = 2_000_000
"""Table look-ups per scoring call (particles x beams) from which the scoring kernel runs on all
numba threads. A look-up costs 1-2 ns, so below this one thread takes a few milliseconds at most,
while a parallel region on a busy 2-core machine (other processes running) was measured to stall for
about 10 ms waiting for a descheduled thread (4 000 x 100: 0.6 ms serial, 12 ms parallel)."""
