"""Beam skipping: once the cloud has converged, leave out the beams most particles cannot explain.

An unmapped obstacle (an opponent a few metres ahead, a person) returns short ranges on a whole
sector of the scan. Every particle near the true pose expects the wall behind it there, so those
beams say nothing about which particle is right; they only add the beam model's short/random
floor, unevenly (its short-return density ``2 / d`` favours particles that expect the wall
nearer). This is ROS amcl's ``do_beamskip`` (its likelihood-field model; the parameters'
meanings and defaults as Nav2's AMCL configuration guide gives them: ``beam_skip_distance``
0.5 m, ``beam_skip_threshold`` 0.3, ``beam_skip_error_threshold`` 0.9, off by default), here
in the beam model:

- a particle *explains* beam ``b`` when its expected range lies within ``beam_skip_distance``
  metres of the measured one: ``|z_b - d_ib| < distance`` (in table pixels, ``d`` clipped to the
  table as the scoring clips it);
- beam ``b`` is used when more than ``beam_skip_threshold`` of the particles explain it, and
  skipped otherwise;
- when ``beam_skip_error_threshold`` of the beams or more would be skipped, the cloud has
  probably converged to a wrong pose and every beam is used (amcl's "integrating all
  observations");
- with ``beam_skip_short_only`` (this project's variant), a particle also explains a beam that
  returns beyond its expected range, so only short returns, the ones an occluder makes, can be
  skipped; long returns (drop-outs, a gap in a wall the map shows) stay with the beam model;
- nothing is skipped unless the cloud has converged: every particle within
  ``beam_skip_converged_distance`` metres of the particles' unweighted mean in x and in y (amcl's
  ``pf_update_converged`` with its ``dist_threshold``, 0.5 m).

A skipped beam's log-likelihood row is set to 0 for every particle, so it is left out of the sum
exactly (adding 0.0 changes no float); with no beam skipped the scores are those of
[`mcl.filter.sensor_model.SensorModel.score()`][mcl.filter.sensor_model.SensorModel.score] bit for bit.

Frames and units: particles world [x, y, theta] (metres, radians); ranges in table pixels.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["BeamSkip", "beam_skip_mask", "cloud_converged"]


@nb.njit(cache=True)
def cloud_converged(particles: np.ndarray, distance: float) -> bool:
    """Whether every particle lies within ``distance`` metres of the unweighted mean in x and y."""
    n = particles.shape[0]
    if n == 0:
        return False
    mx = 0.0
    my = 0.0
    for i in range(n):
        mx += particles[i, 0]
        my += particles[i, 1]
    mx /= n
    my /= n
    for i in range(n):
        if abs(particles[i, 0] - mx) > distance or abs(particles[i, 1] - my) > distance:
            return False
    return True


@nb.njit(cache=True)
def beam_skip_mask(
    expected, z_px, px_per_m, z_max, distance_px, threshold, error_threshold, keep, short_only=False
):
    """Fill ``keep`` (K,) bool with the beams to use; return how many beams nobody explains
    (when that is ``error_threshold`` of them or more, ``keep`` is all True).

    Args:
        expected: (N, K) expected ranges, metres.
        z_px: (K,) measured ranges, table pixels.
        px_per_m: table pixels per metre.
        z_max: the table's last pixel (expected ranges are clipped to [0, z_max]).
        distance_px: ``beam_skip_distance`` in table pixels.
        threshold: fraction of particles that must explain a beam for it to be used.
        error_threshold: fraction of skipped beams at or beyond which every beam is used.
        short_only: a particle also explains a beam measured beyond its expected range (only
            short returns, what an occluder makes, can be skipped).
    """
    n, k = expected.shape
    counts = np.zeros(k, dtype=np.int64)
    for i in range(n):
        for b in range(k):
            d = expected[i, b] * px_per_m
            if d > z_max:
                d = z_max
            elif d < 0.0:
                d = 0.0
            if abs(z_px[b] - d) < distance_px or (short_only and z_px[b] > d):
                counts[b] += 1
    skipped = 0
    for b in range(k):
        keep[b] = counts[b] > threshold * n
        if not keep[b]:
            skipped += 1
    if k > 0 and skipped >= error_threshold * k:
        keep[:] = True
    return skipped


class BeamSkip:
    """What the last beam-skipping call decided (diagnostics; the sensor model keeps one).

    Attributes:
        converged: whether the cloud counted as converged.
        skipped: beams left out (0 when not converged or when forced back in).
        forced: whether the error threshold forced every beam back in.
        n_beams: beams of the scan that were scored.
    """

    __slots__ = ("converged", "forced", "n_beams", "skipped")

    def __init__(self) -> None:
        self.converged = False
        self.skipped = 0
        self.forced = False
        self.n_beams = 0

    def __repr__(self) -> str:
        return (
            f"BeamSkip(converged={self.converged}, skipped={self.skipped}, "
            f"forced={self.forced}, n_beams={self.n_beams})"
        )
