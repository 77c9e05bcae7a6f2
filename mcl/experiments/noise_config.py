"""The odometry-noise sweep's settings: the source's coefficients and `ExperimentConfig`
(which runs to make).

Below [`mcl.experiments.noise_sweep`][mcl.experiments.noise_sweep] (which runs the sweep) and
[`mcl.experiments.noise_report`][mcl.experiments.noise_report] (which summarises it), which both read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from mcl.experiments.metrics import DIVERGED_M
from mcl.experiments.runs import RunSpec
from mcl.filter.motion_model import MotionModelParams, uniform_to_gaussian
from mcl.filter.params import DEFAULT_PARTICLES
from racecar_sim.maps import DEFAULT_MAP

__all__ = ["GAUSSIAN_SIGMAS", "UNIFORM_COEFFICIENTS", "ExperimentConfig"]

UNIFORM_COEFFICIENTS: tuple[float, ...] = (0.01, 0.1, 0.3, 0.5, 1.0)
"""Half-widths c of the uniform noise in the source's table (per update)."""
GAUSSIAN_SIGMAS: tuple[float, ...] = (0.01, 0.1, 0.3, 0.5, 1.0)
"""Standard deviations sigma of the Gaussian noise in the source's table (per update)."""


@dataclass(frozen=True)
class ExperimentConfig:
    """The sweep: which runs to make.

    Attributes:
        map: bundled map name or map YAML path.
        driver: ``"wall"`` or ``"pursuit"`` (see [`mcl.experiments.runs.DRIVERS`][mcl.experiments.runs.DRIVERS]).
        scenario: a key of [`mcl.experiments.scenarios.SCENARIOS`][mcl.experiments.scenarios.SCENARIOS].
        seeds: number of seeds (``first_seed``, ``first_seed + 1``, ...).
        first_seed: the first seed.
        duration: seconds of simulated time per run.
        n_particles: particles per run.
        uniform: uniform half-widths c (per update); empty skips the series.
        gaussian: Gaussian sigmas (per update); empty skips the series.
        matched: also run Gaussian noise at sigma = c / sqrt(3) for every uniform c.
        diverged_m: metres of position error counted as diverged.
        env: extra RacecarEnv settings as (name, value) pairs (e.g. fewer beams in tests).
        filter_map: the map the filter holds when it differs from the world ``map``; None = same.
    """

    map: str = DEFAULT_MAP
    driver: str = "wall"
    scenario: str = "tracking"
    seeds: int = 3
    first_seed: int = 0
    duration: float = 60.0
    n_particles: int = DEFAULT_PARTICLES
    uniform: tuple[float, ...] = UNIFORM_COEFFICIENTS
    gaussian: tuple[float, ...] = GAUSSIAN_SIGMAS
    matched: bool = True
    diverged_m: float = DIVERGED_M
    env: tuple[tuple[str, Any], ...] = ()
    filter_map: str | None = None

    def __post_init__(self) -> None:
        for name in ("seeds", "first_seed"):
            value = getattr(self, name)
            low = 1 if name == "seeds" else 0
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"ExperimentConfig.{name} = {value!r} must be an integer >= {low}")
        for name in ("uniform", "gaussian"):
            values = tuple(float(v) for v in getattr(self, name))
            if not all(math.isfinite(v) and v > 0 for v in values):
                raise ValueError(
                    f"ExperimentConfig.{name} = {values!r} must hold positive coefficients"
                )
            object.__setattr__(self, name, values)
        if not (math.isfinite(self.diverged_m) and self.diverged_m > 0):
            raise ValueError(f"ExperimentConfig.diverged_m = {self.diverged_m!r} must be > 0 m")
        object.__setattr__(self, "env", tuple((str(k), v) for k, v in dict(self.env).items()))
        if not self.runs():
            raise ValueError("ExperimentConfig: no runs (uniform and gaussian are both empty)")

    def runs(self) -> list[RunSpec]:
        """Every run of the sweep, seed by seed (so early results cover every series)."""
        points: list[tuple[str, str, float, float]] = []  # series, scheme, coefficient, nominal
        points += [("uniform", "uniform", c, c) for c in self.uniform]
        points += [("gaussian", "gaussian", s, s) for s in self.gaussian]
        if self.matched:
            points += [
                ("gaussian_matched", "gaussian", float(uniform_to_gaussian(c)), c)
                for c in self.uniform
            ]
        return [
            RunSpec(
                map=str(self.map),
                driver=self.driver,
                scenario=self.scenario,
                motion=MotionModelParams(scheme=scheme, coefficients=coeff),
                seed=seed,
                duration=self.duration,
                n_particles=self.n_particles,
                series=series,
                nominal=nominal,
                env=self.env,
                filter_map=self.filter_map,
            )
            for seed in range(self.first_seed, self.first_seed + self.seeds)
            for series, scheme, coeff, nominal in points
        ]
