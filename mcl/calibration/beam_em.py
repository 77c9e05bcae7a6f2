"""Expectation-maximisation of the beam model's intrinsic parameters (Probabilistic Robotics,
table 6.2, ``learn_intrinsic_parameters``), from measured ranges z and expected ranges z* (exact
casts at reference poses).

The four parts, as in the book and the simulator: a hit N(z* + bias, sigma_hit²) truncated to
[0, z_max]; a short return, exponential with rate lambda_short truncated to [0, z*]; a max-range
reading (a no-return, a point mass at z_max); a random return uniform on [0, z_max]. The book's
hit is unbiased; ``fit_bias`` also estimates the hit's mean offset (metres), which the real lidar
needs (+1 to +2 cm). A no-return is explained by the max part alone (it has no density at a
finite z), so z_max comes out as the no-return fraction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["BeamModelFit", "fit_beam_model", "part_densities"]


@dataclass(frozen=True)
class BeamModelFit:
    """Fitted beam model: mixing weights (sum 1) and shape parameters.

    Attributes:
        z_hit, z_short, z_max, z_rand: mixing weights.
        sigma_hit: metres, hit standard deviation.
        bias: metres, hit mean offset (0 unless fitted).
        lambda_short: 1/metres, rate of the short-return exponential.
        max_range: metres, the z_max of the uniform part.
        iterations: EM iterations run.
        log_likelihood: mean log-likelihood per beam at the end (no-returns included, via log z_max).
        n_beams: beams used.
    """

    z_hit: float
    z_short: float
    z_max: float
    z_rand: float
    sigma_hit: float
    bias: float
    lambda_short: float
    max_range: float
    iterations: int
    log_likelihood: float
    n_beams: int


def part_densities(
    z: np.ndarray, z_star: np.ndarray, sigma: float, bias: float, lam: float, max_range: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p_hit, p_short, p_rand) densities (1/metres) of finite readings z given z* (same shape)."""
    mu = z_star + bias
    norm = _trunc_norm(mu, sigma, max_range)
    p_hit = np.exp(-0.5 * ((z - mu) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi)) / norm
    p_hit = np.where((z >= 0) & (z <= max_range), p_hit, 0.0)
    denom = -np.expm1(-lam * z_star)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_short = np.where(
            (z <= z_star) & (denom > 0),
            lam * np.exp(-lam * z) / np.where(denom > 0, denom, 1.0),
            0.0,
        )
    p_rand = np.full(z.shape, 1.0 / max_range)
    return p_hit, p_short, p_rand


def _trunc_norm(mu: np.ndarray, sigma: float, max_range: float) -> np.ndarray:
    """Mass of N(mu, sigma²) inside [0, max_range] (the hit's normaliser)."""
    s = sigma * math.sqrt(2.0)
    hi = _erf((max_range - mu) / s)
    lo = _erf((0.0 - mu) / s)
    return np.maximum(0.5 * (hi - lo), 1e-12)


def _erf(x: np.ndarray) -> np.ndarray:
    """Vectorised error function (Abramowitz-Stegun 7.1.26, |error| < 1.5e-7)."""
    x = np.asarray(x, dtype=np.float64)
    sign = np.sign(x)
    a = np.abs(x)
    t = 1.0 / (1.0 + 0.3275911 * a)
    poly = t * (
        0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429)))
    )
    return sign * (1.0 - poly * np.exp(-a * a))


def fit_beam_model(
    z: np.ndarray,
    z_star: np.ndarray,
    max_range: float,
    *,
    fit_bias: bool = True,
    init: tuple[float, float, float, float, float, float] = (0.7, 0.1, 0.05, 0.15, 0.05, 1.0),
    max_iterations: int = 200,
    tol: float = 1e-7,
) -> BeamModelFit:
    """Fit the beam model to readings ``z`` (metres, NaN = no-return) with expected ranges ``z_star``.

    Beams whose expected range is ``max_range`` or beyond (nothing mapped within range) are left
    out: the model conditions on a mapped surface. ``init`` = (z_hit, z_short, z_max, z_rand,
    sigma_hit, lambda_short).

    Raises:
        ValueError: shapes differ, or fewer than 100 usable beams.
    """
    z = np.asarray(z, dtype=np.float64).ravel()
    z_star = np.asarray(z_star, dtype=np.float64).ravel()
    if z.shape != z_star.shape:
        raise ValueError(f"z and z_star must have the same shape, got {z.shape} and {z_star.shape}")
    use = np.isfinite(z_star) & (z_star < max_range)
    z, z_star = z[use], z_star[use]
    if z.size < 100:
        raise ValueError(f"need at least 100 beams with a mapped surface, got {z.size}")
    nret = ~np.isfinite(z) | (z >= max_range)
    zf, zs = z[~nret], z_star[~nret]
    w = np.array(init[:4], dtype=np.float64)
    w /= w.sum()
    sigma, lam, bias = float(init[4]), float(init[5]), 0.0
    prev = -math.inf
    ll = -math.inf
    it = 0
    for it in range(1, max_iterations + 1):  # noqa: B007
        p_hit, p_short, p_rand = part_densities(zf, zs, sigma, bias, lam, max_range)
        a_hit, a_short, a_rand = w[0] * p_hit, w[1] * p_short, w[3] * p_rand
        total = a_hit + a_short + a_rand
        total = np.maximum(total, 1e-300)
        e_hit, e_short, e_rand = a_hit / total, a_short / total, a_rand / total
        n = z.size
        n_max = float(nret.sum())
        ll = (np.log(total).sum() + n_max * math.log(max(w[2], 1e-300))) / n
        w = np.array([e_hit.sum(), e_short.sum(), n_max, e_rand.sum()]) / n
        s_hit = e_hit.sum()
        if fit_bias:
            bias = float((e_hit * (zf - zs)).sum() / s_hit)
        sigma = float(math.sqrt((e_hit * (zf - zs - bias) ** 2).sum() / s_hit))
        s_short = e_short.sum()
        if s_short > 0:
            lam = float(s_short / max((e_short * zf).sum(), 1e-12))
        if abs(ll - prev) < tol:
            break
        prev = ll
    return BeamModelFit(
        z_hit=float(w[0]), z_short=float(w[1]), z_max=float(w[2]), z_rand=float(w[3]),
        sigma_hit=sigma, bias=bias, lambda_short=lam, max_range=float(max_range),
        iterations=it, log_likelihood=float(ll), n_beams=int(z.size),
    )  # fmt: skip
