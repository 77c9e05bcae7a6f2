"""Localization scenarios: how a run starts the filter and what happens to the car on the way.

A scenario is a small object with a ``name``, the reset options it gives
[`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] (how the filter starts), and a ``before_step`` hook called
before every step (a kidnapping scenario teleports the car there with
``env.unwrapped.teleport(pose)``). New scenarios register a factory in `SCENARIOS`; the
experiment's ``--scenario`` choices are its keys.

Two optional methods: ``after_step(env, step, info)`` sees every step's info (the run calls it
when the scenario has it), and ``outcome()`` returns a dict of what happened (JSON-friendly values),
which the run hands back in `mcl.experiments.runs.RunResult.outcome`.

Scenarios: ``tracking`` (start around the truth), ``global`` (start uniform over free space: the
filter must find the car) and ``kidnap`` (start around the truth, then the car is teleported to a
random free pose without telling the filter), ``opponents`` (tracking with car-sized boxes
driving close ahead, `mcl.experiments.opponents`). ``global`` and ``kidnap`` record, per step, the particle count and
the ambiguity flag of ``info["localization"]``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from mcl.wrappers.localization import TRACKING_INIT_SPREAD

__all__ = [
    "SCENARIOS",
    "GlobalScenario",
    "KidnapScenario",
    "Scenario",
    "TrackingScenario",
    "make_scenario",
]


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
        start: the car's start pose (world x m, y m, theta rad); None = the env's random start.
    """

    init_spread: tuple[float, float, float] = TRACKING_INIT_SPREAD
    name: str = "tracking"
    start: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        spread = tuple(float(v) for v in self.init_spread)
        if len(spread) != 3 or not all(math.isfinite(v) and v >= 0 for v in spread):
            raise ValueError(
                f"TrackingScenario.init_spread must be three non-negative numbers, got "
                f"{self.init_spread!r}"
            )
        object.__setattr__(self, "init_spread", spread)
        if self.start is not None:
            start = tuple(float(v) for v in self.start)
            if len(start) != 3 or not all(math.isfinite(v) for v in start):
                raise ValueError(
                    f"TrackingScenario.start must be None or [x, y, theta], got {self.start!r}"
                )
            object.__setattr__(self, "start", start)

    def reset_options(self) -> dict[str, Any]:
        """Start around the truth with ``init_spread`` (at ``start`` when given)."""
        options: dict[str, Any] = {"init": "pose", "init_spread": self.init_spread}
        if self.start is not None:
            options["pose"] = list(self.start)
        return options

    def before_step(self, env: Any, step: int, time: float, rng: np.random.Generator) -> None:
        """Nothing happens."""


class _Recorder:
    """Per-step particle counts and ambiguity flags from ``info["localization"]``."""

    def __init__(self) -> None:
        self.n_particles: list[int] = []
        self.ambiguous: list[int] = []

    def after_step(self, env: Any, step: int, info: dict[str, Any]) -> None:
        """Record the step's particle count and ambiguity flag (0/1)."""
        loc = info.get("localization", {})
        self.n_particles.append(int(loc.get("n_particles", -1)))
        self.ambiguous.append(int(bool(loc.get("ambiguous", False))))

    def recorded(self) -> dict[str, Any]:
        return {"n_particles": list(self.n_particles), "ambiguous": list(self.ambiguous)}


class GlobalScenario(_Recorder):
    """Global localization: the filter starts uniform over the map's free space, the car anywhere.

    ``outcome()``: ``lost_at`` (0.0 s, when the filter starts without knowing the pose), and the
    per-step ``n_particles`` and ``ambiguous`` (0/1) lists.
    """

    name = "global"

    def reset_options(self) -> dict[str, Any]:
        """Start uniform over free space."""
        return {"init": "global"}

    def before_step(self, env: Any, step: int, time: float, rng: np.random.Generator) -> None:
        """Nothing happens."""

    def outcome(self) -> dict[str, Any]:
        """See the class docstring."""
        return {"lost_at": 0.0, **self.recorded()}


_TELEPORT_TRIES = 200  # random poses tried before a kidnap gives up


class KidnapScenario(_Recorder):
    """The kidnapped robot: tracking from the true start, then, at ``kidnap_time`` seconds, the car
    is teleported (``env.unwrapped.teleport``) to a random free pose without telling the filter.

    Args:
        kidnap_time: seconds after reset at which the car is moved.
        min_distance: metres the new position lies at least from the old one.
        clearance: metres of free space (distance field) around the new position; the car's
            footprint must fit there at the drawn heading, else another pose is drawn.
        init_spread: standard deviations (x m, y m, theta rad) of the initial cloud around the
            true start pose.

    ``outcome()``: ``lost_at`` (the time of the kidnap, s), ``kidnap_from`` / ``kidnap_to``
    (world poses), and the per-step ``n_particles`` and ``ambiguous`` (0/1) lists.

    Raises:
        RuntimeError: no pose far and free enough was found (from ``before_step``).
    """

    name = "kidnap"

    def __init__(
        self,
        kidnap_time: float = 5.0,
        min_distance: float = 2.0,
        clearance: float = 0.45,
        init_spread: tuple[float, float, float] = TRACKING_INIT_SPREAD,
    ) -> None:
        super().__init__()
        for label, value in (
            ("kidnap_time", kidnap_time),
            ("min_distance", min_distance),
            ("clearance", clearance),
        ):
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"KidnapScenario.{label} = {value!r} must be a number")
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"KidnapScenario.{label} = {value!r} must be >= 0")
        self.kidnap_time = float(kidnap_time)
        self.min_distance = float(min_distance)
        self.clearance = float(clearance)
        self.init_spread = TrackingScenario(init_spread).init_spread
        self.kidnap_from: list[float] | None = None
        self.kidnap_to: list[float] | None = None

    def reset_options(self) -> dict[str, Any]:
        """Start around the truth with ``init_spread``."""
        return {"init": "pose", "init_spread": self.init_spread}

    def before_step(self, env: Any, step: int, time: float, rng: np.random.Generator) -> None:
        """Teleport the car once ``time`` reaches ``kidnap_time``."""
        if self.kidnap_to is not None or time + 1e-9 < self.kidnap_time:
            return
        inner = env.unwrapped
        here = np.asarray(inner.pose, dtype=np.float64)
        for _ in range(_TELEPORT_TRIES):
            pose = inner.map.sample_free_poses(rng, 1, clearance=self.clearance)[0]
            if math.dist(pose[:2], here[:2]) < self.min_distance:
                continue
            try:
                inner.teleport(pose)
            except ValueError:  # the footprint touches a wall at this heading
                continue
            self.kidnap_from = [float(v) for v in here]
            self.kidnap_to = [float(v) for v in pose]
            self.kidnap_time = float(time)
            return
        raise RuntimeError(
            f"kidnap: no free pose with {self.clearance} m clearance at least "
            f"{self.min_distance} m away in {_TELEPORT_TRIES} tries"
        )

    def outcome(self) -> dict[str, Any]:
        """See the class docstring."""
        return {
            "lost_at": self.kidnap_time if self.kidnap_to is not None else math.nan,
            "kidnap_from": self.kidnap_from,
            "kidnap_to": self.kidnap_to,
            **self.recorded(),
        }


def _opponents(**settings: Any) -> Scenario:
    """[`mcl.experiments.opponents.OpponentsScenario`][mcl.experiments.opponents.OpponentsScenario] (imported when first asked for)."""
    from mcl.experiments.opponents import OpponentsScenario

    return OpponentsScenario(**settings)


SCENARIOS: dict[str, Callable[..., Scenario]] = {
    "tracking": TrackingScenario,
    "global": GlobalScenario,
    "kidnap": KidnapScenario,
    "opponents": _opponents,
}
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
