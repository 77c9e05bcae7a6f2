"""Odometry motion model: compose each particle with a (noisy) car-frame displacement.

Frames: particles are ``[x, y, theta]`` in the world frame (metres, radians) at the rear axle; the
odometry ``[dx, dy, dtheta]`` is the displacement in the car frame of the *previous* pose (metres,
radians). Composition is the SE(2) product of the pose matrices, vectorised over particles:

    x' = x + cos(theta) dx - sin(theta) dy,   y' = y + sin(theta) dx + cos(theta) dy,
    theta' = theta + dtheta   (wrapped to [-pi, pi)).

Noise is added to each particle's copy of the odometry before composing (the MIT RSS lab's scheme):
``"uniform"`` draws each component from [-c, c], ``"gaussian"`` from N(0, sigma^2), ``"none"`` adds
nothing. The coefficients are per update, not per second. ``"alpha"`` is the odometry model of
Probabilistic Robotics (table 5.6, ROS amcl's ``alpha1..alpha4``): noise on a turn, a translation
and a turn that grows with the motion of the update (`mcl.filter.alpha_motion`), plus the
coefficients as a constant floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from mcl.filter.alpha_motion import alpha_odometry_into
from mcl.filter.angles import wrap_angle
from mcl.filter.bounds import check_filter
from mcl.filter.step_kernels import compose_into, move_noisy, noise_into
from racecar_sim.raycast.rand import seed_from
from racecar_sim.settings.validation import short

__all__ = [
    "SCHEMES",
    "MotionModel",
    "MotionModelParams",
    "carry",
    "compose",
    "gaussian_to_uniform",
    "odometry_to_twist",
    "twist_to_odometry",
    "uniform_to_gaussian",
]

SCHEMES: tuple[str, ...] = ("uniform", "gaussian", "none", "alpha")
"""Noise schemes accepted by `MotionModelParams`."""

_SQRT3 = math.sqrt(3.0)


def uniform_to_gaussian(half_width: float | np.ndarray) -> float | np.ndarray:
    """Standard deviation with the variance of uniform noise on [-c, c]: sigma = c / sqrt(3)."""
    out = np.asarray(half_width, dtype=np.float64) / _SQRT3
    return float(out) if out.ndim == 0 else out


def gaussian_to_uniform(sigma: float | np.ndarray) -> float | np.ndarray:
    """Half-width c of uniform noise with the variance of N(0, sigma^2): c = sigma * sqrt(3)."""
    out = np.asarray(sigma, dtype=np.float64) * _SQRT3
    return float(out) if out.ndim == 0 else out


def _three(name: str, value: float | tuple[float, ...] | list[float]) -> tuple[float, float, float]:
    """One number or three (x, y, theta) as a tuple of three non-negative finite floats."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        values = (float(value),) * 3
    else:
        try:
            values = tuple(float(v) for v in value)  # type: ignore[union-attr]
        except (TypeError, ValueError):
            raise ValueError(
                f"MotionModelParams.{name} must be a number or three numbers, got {short(value)}"
            ) from None
    if len(values) != 3 or not all(math.isfinite(v) and v >= 0 for v in values):
        raise ValueError(
            f"MotionModelParams.{name} must be one or three non-negative finite numbers "
            f"(x, y, theta), got {short(value)}"
        )
    for v in values:  # bounds and their reasons: mcl.filter.bounds
        check_filter("MotionModelParams", name, v, f"motion.{name}")
    return values  # type: ignore[return-value]


@dataclass(frozen=True)
class MotionModelParams:
    """Noise of the odometry motion model.

    Attributes:
        scheme: ``"uniform"``, ``"gaussian"``, ``"none"`` or ``"alpha"``.
        coefficients: per-update noise of the car-frame odometry (dx metres, dy metres, dtheta
            radians): the half-width c for ``"uniform"``, the standard deviation for ``"gaussian"``
            and for the constant floor of ``"alpha"``, ignored for ``"none"``. One number applies
            to all three components. The forward 0.005 m is tight on purpose: the scan must not drag
            the cloud along a corridor whose map is out of date (docs/localization_changing_world.md).
        search_coefficients: the coefficients while the filter searches (its cloud spread, random
            particles just joined: [is_searching][mcl.filter.particle_filter.ParticleFilter.is_searching]),
            so that a spread cloud keeps exploring even while the car stands; None: ``coefficients``.
        alphas: ``"alpha"`` only: a1 (rad² of rotation noise variance per rad² of rotation), a2
            (rad² per m² of translation), a3 (m² of translation variance per m²), a4 (m² per rad²);
            amcl's ``odom_alpha1..4`` (`mcl.filter.alpha_motion`).
    """

    scheme: str = "gaussian"
    coefficients: float | tuple[float, float, float] = (0.005, 0.01, 0.02)
    search_coefficients: float | tuple[float, float, float] | None = (0.02, 0.01, 0.02)
    alphas: tuple[float, float, float, float] = (0.2, 0.08, 0.16, 0.02)

    def __post_init__(self) -> None:
        if self.scheme not in SCHEMES:
            raise ValueError(
                f"MotionModelParams.scheme = {short(self.scheme)}; choose one of {list(SCHEMES)}"
            )
        object.__setattr__(self, "coefficients", _three("coefficients", self.coefficients))
        if self.search_coefficients is not None:
            object.__setattr__(
                self, "search_coefficients", _three("search_coefficients", self.search_coefficients)
            )
        try:
            alphas = tuple(float(a) for a in self.alphas)
        except (TypeError, ValueError):
            alphas = ()
        if len(alphas) != 4 or not all(math.isfinite(a) and a >= 0 for a in alphas):
            raise ValueError(
                f"MotionModelParams.alphas must be four non-negative numbers (a1..a4), "
                f"got {short(self.alphas)}"
            )
        for a in alphas:  # bounds and their reasons: mcl.filter.bounds
            check_filter("MotionModelParams", "alphas", a, "motion.alphas")
        object.__setattr__(self, "alphas", alphas)

    def with_scheme(self, scheme: str) -> MotionModelParams:
        """The same noise variance under another scheme (uniform c <-> Gaussian sigma = c/sqrt(3)).

        Converting to or from ``"none"`` keeps the coefficients unchanged.
        """
        coeffs = np.asarray(self.coefficients, dtype=np.float64)
        if self.scheme == "uniform" and scheme == "gaussian":
            coeffs = coeffs / _SQRT3
        elif self.scheme == "gaussian" and scheme == "uniform":
            coeffs = coeffs * _SQRT3
        return replace(self, scheme=scheme, coefficients=tuple(float(c) for c in coeffs))


def compose(particles: np.ndarray, odometry: np.ndarray) -> np.ndarray:
    """Poses (N, 3) world frame moved by car-frame displacements (3,) or (N, 3); new array.

    Theta of the result is wrapped to [-pi, pi). One numba pass (`mcl.filter.step_kernels.compose_into()`).
    """
    particles = np.asarray(particles, dtype=np.float64)
    odo = np.asarray(odometry, dtype=np.float64)
    if odo.ndim == 1 or odo.shape[0] == 1:
        odo = np.ascontiguousarray(odo.reshape(1, 3))
    else:
        odo = np.ascontiguousarray(np.broadcast_to(odo, particles.shape))
    out = np.empty(particles.shape, dtype=np.float64)
    compose_into(particles, odo, out)
    return out


def carry(particles: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Poses (N, 3) world frame moved rigidly with the world-frame motion that takes the pose
    ``start`` to the pose ``end`` (each [x m, y m, theta rad]): every pose keeps where it lies
    relative to ``start``, now relative to ``end``; new array, theta wrapped to [-pi, pi)."""
    p = np.asarray(particles, dtype=np.float64)
    turn = float(end[2]) - float(start[2])
    c, s = math.cos(turn), math.sin(turn)
    dx, dy = p[:, 0] - float(start[0]), p[:, 1] - float(start[1])
    out = np.empty_like(p)
    out[:, 0] = float(end[0]) + c * dx - s * dy
    out[:, 1] = float(end[1]) + s * dx + c * dy
    out[:, 2] = wrap_angle(p[:, 2] + turn)
    return out


def twist_to_odometry(twist: np.ndarray, dt: float) -> np.ndarray:
    """Car-frame displacement [dx, dy, dtheta] after holding a twist for ``dt`` seconds.

    The twist ``[vx, vy, omega]`` (m/s, m/s, rad/s) is in the car frame. Integrated exactly as a
    constant twist (an arc of the SE(2) exponential map), which reduces to ``twist * dt`` when
    omega * dt is small.
    """
    vx, vy, om = (float(v) for v in twist)
    dth = om * dt
    a, b = _arc_factors(dth)
    return np.array([(a * vx - b * vy) * dt, (b * vx + a * vy) * dt, dth])


def _arc_factors(dth: float) -> tuple[float, float]:
    """sin(dth)/dth and (1 - cos(dth))/dth: what a constant twist's turn ``dth`` (radians) does to
    its straight-line displacement (second-order series near 0)."""
    if abs(dth) < 1e-6:
        return 1.0 - dth * dth / 6.0, dth / 2.0
    return math.sin(dth) / dth, (1.0 - math.cos(dth)) / dth


def odometry_to_twist(odometry: np.ndarray, dt: float) -> np.ndarray:
    """The constant car-frame twist [vx m/s, vy m/s, omega rad/s] that moves the car by the
    car-frame displacement ``odometry`` [dx m, dy m, dtheta rad] in ``dt`` seconds (> 0): the
    exact inverse of `twist_to_odometry`.

    Raises:
        ValueError: ``dt`` is not a positive number of seconds.
    """
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    dx, dy, dth = (float(v) for v in odometry)
    a, b = _arc_factors(dth)
    norm = (a * a + b * b) * dt
    return np.array([(a * dx + b * dy) / norm, (a * dy - b * dx) / norm, dth / dt])


class MotionModel:
    """Samples particle motion from odometry (see the module docstring for frames and schemes).

    Args:
        params: noise scheme and coefficients; defaults to `MotionModelParams`.
    """

    def __init__(self, params: MotionModelParams | None = None) -> None:
        self.params = params if params is not None else MotionModelParams()
        self._coefficients_of: tuple[MotionModelParams | None, np.ndarray, np.ndarray] = (
            None, np.zeros(3), np.zeros(4)
        )  # fmt: skip
        self._searching: MotionModel | None = None

    def while_searching(self) -> MotionModel:
        """The model a searching filter moves its particles with: this one with
        ``params.search_coefficients`` (made once per coefficients), or this one itself when
        there are none or the scheme adds no noise."""
        p = self.params
        if p.search_coefficients is None or p.scheme == "none":
            return self
        if self._searching is None or self._searching.params.coefficients != p.search_coefficients:
            self._searching = MotionModel(replace(p, coefficients=p.search_coefficients))
        return self._searching

    def _arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``params.coefficients`` (3,) and ``params.alphas`` (4,) as arrays, made once per
        ``params`` object."""
        params, coefficients, alphas = self._coefficients_of
        if params is not self.params:
            coefficients = np.asarray(self.params.coefficients, dtype=np.float64).reshape(3)
            alphas = np.asarray(self.params.alphas, dtype=np.float64).reshape(4)
            self._coefficients_of = (self.params, coefficients, alphas)
        return coefficients, alphas

    def _coefficients(self) -> np.ndarray:
        return self._arrays()[0]

    def noisy_odometry(self, n: int, odometry: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) noisy car-frame displacements (metres, metres, radians) of ``odometry`` (3,), one
        per particle, as `evaluate()` composes them (every scheme; one raw draw of ``rng``)."""
        odo = np.asarray(odometry, dtype=np.float64).reshape(3)
        if self.params.scheme != "alpha":
            return odo + self.sample_noise(n, rng)
        out = np.empty((n, 3))
        floor, alphas = self._arrays()
        alpha_odometry_into(odo, alphas, floor, seed_from(rng), out)
        return out

    def sample_noise(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) car-frame odometry perturbations (metres, metres, radians) for ``n`` particles.

        Drawn inside numba from a `racecar_sim.raycast.rand` stream seeded by one raw draw of
        ``rng`` (three times faster than ``rng.standard_normal`` at 4000 particles): the same
        ``rng`` state gives the same noise, and `evaluate()` adds exactly these draws.
        """
        if self.params.scheme == "alpha":
            raise ValueError(
                "the alpha scheme's noise depends on the odometry: use noisy_odometry(n, odometry, rng)"
            )
        out = np.zeros((n, 3))
        if self.params.scheme != "none":
            noise_into(self._coefficients(), self.params.scheme == "gaussian", seed_from(rng), out)
        return out

    def evaluate(
        self, particles: np.ndarray, odometry: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """Particles (N, 3) moved by ``odometry`` [dx, dy, dtheta] with per-particle noise.

        Args:
            particles: (N, 3) world [x, y, theta] (metres, radians).
            odometry: (3,) car-frame displacement of the previous pose (metres, radians).
            rng: source of the noise (not used by ``"none"``).

        Returns:
            A new (N, 3) array; theta wrapped to [-pi, pi).

        Raises:
            ValueError: particles are not (N, 3) or odometry is not three finite numbers.
        """
        particles = np.asarray(particles, dtype=np.float64)
        if particles.ndim != 2 or particles.shape[1] != 3:
            raise ValueError(f"particles must have shape (N, 3), got {particles.shape}")
        odo = np.asarray(odometry, dtype=np.float64)
        if odo.shape != (3,) or not all(map(math.isfinite, odo.tolist())):
            raise ValueError(f"odometry must be three finite numbers [dx, dy, dtheta], got {odo}")
        if self.params.scheme == "none":
            return compose(particles, odo)
        if self.params.scheme == "alpha":
            out = np.empty(particles.shape)
            compose_into(particles, self.noisy_odometry(len(particles), odo, rng), out)
            return out
        return move_noisy(
            np.ascontiguousarray(particles), odo, self._coefficients(),
            self.params.scheme == "gaussian", seed_from(rng),
        )  # fmt: skip
