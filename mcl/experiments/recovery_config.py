"""The recovery experiment's settings and per-run judgement: the scenarios, the filter that finds
the car (`recovery_localization()`), `RecoveryConfig` and `RecoveryRun`.

Below [`mcl.experiments.recovery`][mcl.experiments.recovery] (which runs the experiment) and its report and plots, which
all read these classes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from mcl.experiments.convergence import ConvergenceCriteria, RecoveryStats
from mcl.experiments.runs import DRIVERS, RunResult, RunSpec
from mcl.filter.augmented import AugmentedParams
from mcl.filter.kld import KLDParams
from mcl.filter.lost_params import LostParams
from mcl.filter.particle_filter import ParticleFilterParams
from mcl.filter.sensor_model import SensorModelParams
from mcl.wrappers.localization import LocalizationConfig
from racecar_sim.maps import DEFAULT_MAP

__all__ = ["RECOVERY_SCENARIOS", "RecoveryConfig", "RecoveryRun", "recovery_localization"]

RECOVERY_SCENARIOS: dict[str, tuple[float, float]] = {
    "global": (20.0, 10.0),
    "kidnap": (20.0, 15.0),
}
"""Scenario -> (default seconds of driving after the filter loses the car, time limit in s)."""


def recovery_localization(
    global_density: float = 300.0,
    global_particles: int | None = None,
    min_particles: int = 1000,
    max_particles: int = 20_000,
    alpha_slow: float = 0.001,
    alpha_fast: float = 0.1,
    squash_exponent: float = 0.05,
    update_min_distance: float = 0.1,
    update_min_angle: float = 0.2,
) -> LocalizationConfig:
    """Filter settings for finding the car (module docstring); the defaults are the measured ones.

    The lost flag ([LostParams][mcl.filter.lost_params.LostParams]) is reported but triggers no recovery of
    its own here: augmented MCL and KLD-sampling do the searching, as measured.

    Args:
        global_density: particles per m² of free floor at a global start (capped at 300 000).
        global_particles: an explicit count for the global start instead.
        min_particles: KLD-sampling's lower bound on the particle count.
        max_particles: KLD-sampling's upper bound on the particle count.
        alpha_slow: augmented MCL's slow averaging rate per correction.
        alpha_fast: augmented MCL's fast averaging rate per correction.
        squash_exponent: the beam model's tempering exponent (the lab's is 1/2.2).
        update_min_distance: metres of motion between two scans the filter uses.
        update_min_angle: radians of rotation between two scans the filter uses.
    """
    return LocalizationConfig(
        lost=LostParams(recover=False),  # the flag is reported; augmented MCL does the recovery
        sensor=SensorModelParams(squash_exponent=squash_exponent, parallel=False),
        filter=ParticleFilterParams(
            n_particles=min_particles,
            global_particles=global_particles,
            global_density=global_density,
            global_max_particles=300_000,
            update_min_distance=update_min_distance,
            update_min_angle=update_min_angle,
            augmented=AugmentedParams(alpha_slow=alpha_slow, alpha_fast=alpha_fast),
            kld=KLDParams(
                enabled=True, epsilon=0.02, min_particles=min_particles, max_particles=max_particles
            ),
        ),
    )


@dataclass(frozen=True)
class RecoveryConfig:
    """The experiment: which runs to make and how to judge them.

    Attributes:
        map: bundled map name or map YAML path.
        scenario: ``"global"`` or ``"kidnap"``.
        driver: a key of [`mcl.experiments.runs.DRIVERS`][mcl.experiments.runs.DRIVERS].
        seeds: number of seeds (``first_seed``, ``first_seed + 1``, ...): each gives its own start
            pose, sensor noise, filter draws and kidnap pose.
        first_seed: the first seed.
        duration: seconds of simulated time per run; None = the scenario's default after the
            filter loses the car (20 s), plus ``kidnap_time`` for a kidnapping.
        kidnap_time: seconds after reset at which the car is kidnapped (scenario ``kidnap``).
        time_limit: seconds after losing the car within which convergence counts as a success;
            None = 10 s (global) or 15 s (kidnap).
        criteria: what counts as converged.
        localization: the filter's settings (default `recovery_localization()`).
        env: extra RacecarEnv settings as (name, value) pairs.
    """

    map: str = DEFAULT_MAP
    scenario: str = "global"
    driver: str = "wall"
    seeds: int = 20
    first_seed: int = 0
    duration: float | None = None
    kidnap_time: float = 5.0
    time_limit: float | None = None
    criteria: ConvergenceCriteria = field(default_factory=ConvergenceCriteria)
    localization: LocalizationConfig = field(default_factory=recovery_localization)
    env: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        if self.scenario not in RECOVERY_SCENARIOS:
            raise ValueError(
                f"RecoveryConfig.scenario = {self.scenario!r}; choose one of "
                f"{sorted(RECOVERY_SCENARIOS)}"
            )
        if self.driver not in DRIVERS:
            raise ValueError(f"RecoveryConfig.driver = {self.driver!r}; choose one of {DRIVERS}")
        for name, low in (("seeds", 1), ("first_seed", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ValueError(f"RecoveryConfig.{name} = {v!r} must be an integer >= {low}")
        for name in ("duration", "time_limit", "kidnap_time"):
            v = getattr(self, name)
            if v is None and name != "kidnap_time":
                continue
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 <= v < math.inf:
                raise ValueError(f"RecoveryConfig.{name} = {v!r} must be a number of seconds")
        if self.total_duration <= self.lost_at:
            raise ValueError(
                f"RecoveryConfig.duration = {self.duration!r} s ends before the kidnap at "
                f"{self.kidnap_time} s"
            )
        object.__setattr__(self, "env", tuple((str(k), v) for k, v in dict(self.env).items()))

    @property
    def lost_at(self) -> float:
        """Seconds after reset at which the filter loses the car (0, or the kidnap)."""
        return self.kidnap_time if self.scenario == "kidnap" else 0.0

    @property
    def limit(self) -> float:
        """The time limit in seconds after losing the car."""
        return (
            self.time_limit if self.time_limit is not None else RECOVERY_SCENARIOS[self.scenario][1]
        )

    @property
    def total_duration(self) -> float:
        """Seconds of simulated time per run."""
        if self.duration is not None:
            return float(self.duration)
        return self.lost_at + RECOVERY_SCENARIOS[self.scenario][0]

    def runs(self) -> list[RunSpec]:
        """One run per seed."""
        settings = (("kidnap_time", self.kidnap_time),) if self.scenario == "kidnap" else ()
        loc = self.localization
        return [
            RunSpec(
                map=str(self.map),
                driver=self.driver,
                scenario=self.scenario,
                motion=loc.motion,
                seed=seed,
                duration=self.total_duration,
                n_particles=loc.filter.n_particles,
                series=self.scenario,
                env=self.env,
                config=loc,
                scenario_settings=settings,
            )
            for seed in range(self.first_seed, self.first_seed + self.seeds)
        ]


@dataclass(frozen=True)
class RecoveryRun:
    """One run and its judgement.

    Attributes:
        result: how the run went ([`mcl.experiments.runs.RunResult`][mcl.experiments.runs.RunResult]).
        stats: convergence and honesty (None when the run failed).
    """

    result: RunResult
    stats: RecoveryStats | None
