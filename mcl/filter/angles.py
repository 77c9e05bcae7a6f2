"""Angle helpers: wrapping to [-pi, pi) and the circular (weighted) mean. Radians throughout."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["circular_mean", "wrap_angle"]

_TWO_PI = 2.0 * math.pi


def wrap_angle(angle: np.ndarray | float) -> np.ndarray:
    """Angles (radians, any shape) wrapped to the half-open interval [-pi, pi).

    Exact at the boundary: pi maps to -pi, and rounding never leaves a result equal to pi.
    """
    a = np.asarray(angle, dtype=np.float64)
    out = np.mod(a + math.pi, _TWO_PI) - math.pi
    # np.mod of a tiny negative number can round up to 2*pi, giving +pi: fold it back.
    return np.where(out >= math.pi, out - _TWO_PI, out)


def circular_mean(angles: np.ndarray, weights: np.ndarray | None = None) -> float:
    """Weighted circular mean of ``angles`` (radians) in [-pi, pi).

    The direction of the (weighted) sum of unit vectors, so angles either side of +-pi average to
    about pi instead of 0. Returns 0 when the unit vectors cancel exactly.

    Args:
        angles: (N,) radians.
        weights: (N,) non-negative weights, or None for equal weights.
    """
    a = np.asarray(angles, dtype=np.float64).reshape(-1)
    if weights is None:
        s, c = np.sin(a).sum(), np.cos(a).sum()
    else:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape != a.shape:
            raise ValueError(f"weights shape {w.shape} does not match angles shape {a.shape}")
        s, c = float(w @ np.sin(a)), float(w @ np.cos(a))
    return float(wrap_angle(math.atan2(s, c)))
