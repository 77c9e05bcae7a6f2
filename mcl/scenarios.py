"""Localization scenarios: how a run starts the filter and what happens to the car on the way.

A scenario is a small object with a ``name``, the reset options it gives
:class:`~mcl.wrapper.LocalizationWrapper` (how the filter starts), and a ``before_step`` hook called
before every step (a kidnapping scenario teleports the car there with
``env.unwrapped.teleport(pose)``). New scenarios register a factory in :data:`SCENARIOS`; the
experiment's ``--scenario`` choices are its keys.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

__all__ = ["SCENARIOS", "Scenario", "TrackingScenario", "make_scenario"]


class Scenario(Protocol):
    """What a run asks of a scenario (see the module docstring)."""

    name: str

    def reset_options(self) -> dict[str, Any]:
        """Options for ``LocalizationWrapper.reset`` (e.g. ``{"init": "global"}``)."""
        ...

    def before_step(self, env: Any, step: int, time: float, rng: np.random.Generator) -> None:
        """Called before step number ``step`` (1-based) at ``time`` seconds since reset.

        ``env`` is the wrapper; ``rng`` is the scenario's own Generator (derived from the run's
        seed, separate from the env's and the filter's).
        """
        ...


@dataclass(frozen=True)
class TrackingScenario:
    """Position tracking: the filter starts around the true start pose and is never disturbed.

    Attributes:
        init_spread: standard deviations (x m, y m, theta rad) of the initial particle cloud
            around the true start pose.
    """

    init_spread: tuple[float, float, float] = (0.25, 0.25, 0.1)
    name: str = "tracking"

    def __post_init__(self) -> None:
        spread = tuple(float(v) for v in self.init_spread)
        if len(spread) != 3 or not all(math.isfinite(v) and v >= 0 for v in spread):
            raise ValueError(
                f"TrackingScenario.init_spread must be three non-negative numbers, got "
                f"{self.init_spread!r}"
            )
        object.__setattr__(self, "init_spread", spread)

    def reset_options(self) -> dict[str, Any]:
        """Start around the truth with ``init_spread``."""
        return {"init": "pose", "init_spread": self.init_spread}

    def before_step(self, env: Any, step: int, time: float, rng: np.random.Generator) -> None:
        """Nothing happens."""


SCENARIOS: dict[str, Callable[..., Scenario]] = {"tracking": TrackingScenario}
"""Scenario factories by name (keyword arguments are the scenario's settings)."""


def make_scenario(name: str, **settings: Any) -> Scenario:
    """The scenario registered as ``name``, built with ``settings``.

    Raises:
        ValueError: ``name`` is not registered (the known names are listed).
    """
    try:
        factory = SCENARIOS[name]
    except KeyError:
        raise ValueError(f"unknown scenario {name!r}; choose one of {sorted(SCENARIOS)}") from None
    return factory(**settings)
